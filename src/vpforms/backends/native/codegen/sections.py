"""The kernel entry ``vp_sections``: the steps of ``vp_run`` (no saves), recording section crossings.

After every step a live lane takes, the kernel evaluates the section function of the surface at
the new state and compares it with the one before the step (the surfaces of
:mod:`vpforms.diagnostics._surfaces`, as data: ``kind``, ``axis``, ``value``, ``period``):

* kind 0, the plane x_axis = value: the side, [x_axis − value ≥ 0];
* kind 1, the planes x_axis = value + kP (also φ = φ₀ mod 2π/nfp of the toroidal coordinates
  (u, φ, Z), where φ is x₂): the level index floor((x_axis − value)/P);
* kind 2, the half-planes φ = value + kP of Cartesian points: the level index of the angle lifted
  across the step, φ₁ = φ₀ + wrap(atan2(X₂, X₁) − φ₀) with φ₀ = atan2(x₂, x₁).

Where the level changes in the requested ``direction`` (+1 up, −1 down, 0 either), the lane appends
an event: its line index, the step index n (the step n → n+1) and the states before and after the
step (6 doubles). Events go to the buffers at an atomic counter, in no particular order; the
function returns how many there were. More than ``cap`` means the buffers overflowed (the events
past ``cap`` are not written): the caller must run the call again, from the same states, with a
larger buffer — the return value is the capacity that suffices.

``vp_locate`` locates recorded crossings on the step family θ ↦ Ψ_{θh}(x) natively: the Illinois
regula falsi of :func:`vpforms.diagnostics._locate.illinois` (same updates, same stopping rules),
from the bracket [0, 1] with the step the trace took as Ψ_h(x), each evaluation the exact step
``vp_step_exact`` at θh, then the point put on the plane (planes).
A crossing where any evaluation fails (status or non-finite) is flagged ``undecided``: the caller
locates it with the JAX locator, which owns the fallback rules.
"""

from __future__ import annotations

__all__ = ["KINDS", "SECTIONS_CDEF", "sections_entry"]

SECTIONS_CDEF = ("int64_t vp_sections(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, "
                 "double h, int32_t kind, int32_t axis, double value, double period, int32_t direction, "
                 "int64_t cap, int64_t *ev_line, int64_t *ev_step, double *ev_x);\n"
                 "void vp_locate(int64_t M, double *x, double *X, double *lvl, double h, int32_t kind, int32_t axis, "
                 "double *Y, double *theta, int32_t *undecided);")

#: the surface kinds of ``vp_sections``
KINDS = {"side": 0, "levels": 1, "angle": 2}

_C = """
/* Section events (vpforms.backends.native.codegen.sections). vp_sec_q: what a lane carries between
   steps — the level index (kinds 0, 1) or the angle atan2(x2, x1) (kind 2). */
#define VP_PI 3.141592653589793
static inline double vp_sec_q(int32_t kind, int32_t axis, double value, double period,
                              double a1, double a2, double a3) {
    if (kind == 2) return atan2(a2, a1);
    double s = (axis == 0 ? a1 : axis == 1 ? a2 : a3) - value;
    return kind == 0 ? (s >= 0 ? 1.0 : 0.0) : floor(s / period);
}
/* the change of level index over a step from q to qn; kind 2 lifts the angle by its wrapped
   increment wrap(a) = a − 2π ceil((a − π)/2π) in (−π, π] (vpforms.diagnostics._surfaces) */
static inline double vp_sec_dlevel(int32_t kind, double value, double period, double q, double qn) {
    if (kind != 2) return qn - q;
    double d = qn - q;
    double phi1 = q + (d - 2.0 * VP_PI * ceil((d - VP_PI) / (2.0 * VP_PI)));
    return floor((phi1 - value) / period) - floor((q - value) / period);
}
int64_t vp_sections(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h,
                    int32_t kind, int32_t axis, double value, double period, int32_t direction,
                    int64_t cap, int64_t *ev_line, int64_t *ev_step, double *ev_x) {
    int64_t count = 0;
    int64_t nb = (N + B - 1) / B;
    #pragma omp parallel for schedule(dynamic, 1)
    for (int64_t b = 0; b < nb; b++) {
@LOAD@        double q[B], p1[B], p2[B], p3[B];
        int64_t n0[B];
        for (int i = 0; i < B; i++) q[i] = vp_sec_q(kind, axis, value, period, a1[i], a2[i], a3[i]);
        for (int64_t k = nmin; k < n_target; k++) {
            for (int i = 0; i < B; i++) { p1[i] = a1[i]; p2[i] = a2[i]; p3[i] = a3[i]; n0[i] = nn[i]; }
@STEP@            for (int i = 0; i < m; i++) {
                if (nn[i] == n0[i]) continue;  /* no step taken: done, frozen, or failed just now */
                double qn = vp_sec_q(kind, axis, value, period, a1[i], a2[i], a3[i]);
                double d = vp_sec_dlevel(kind, value, period, q[i], qn);
                q[i] = qn;
                if (!(direction > 0 ? d > 0 : direction < 0 ? d < 0 : d != 0)) continue;
                int64_t e;
                #pragma omp atomic capture
                e = count++;
                if (e >= cap) continue;  /* overflow: counted, not written (the caller re-runs) */
                ev_line[e] = lo + i; ev_step[e] = n0[i];
                double *o = ev_x + 6 * e;
                o[0] = p1[i]; o[1] = p2[i]; o[2] = p3[i]; o[3] = a1[i]; o[4] = a2[i]; o[5] = a3[i];
            }
        }
@STORE@    }
    return count;
}
/* the gap of vpforms.diagnostics._surfaces: Y_axis − level (planes), wrap(atan2(Y2, Y1) − level) */
static inline double vp_sec_gap(int32_t kind, int32_t axis, double l, double y1, double y2, double y3) {
    if (kind == 2) { double a = atan2(y2, y1) - l; return a - 2.0 * VP_PI * ceil((a - VP_PI) / (2.0 * VP_PI)); }
    return (axis == 0 ? y1 : axis == 1 ? y2 : y3) - l;
}
static inline double vp_sign(double v) { return v > 0 ? 1.0 : v < 0 ? -1.0 : v == 0 ? 0.0 : v; }
void vp_locate(int64_t M, double *x, double *X, double *lvl, double h, int32_t kind, int32_t axis,
               double *Y, double *theta, int32_t *undecided) {
    #pragma omp parallel for schedule(dynamic, 64)
    for (int64_t e = 0; e < M; e++) {
        double x1 = x[3 * e], x2 = x[3 * e + 1], x3 = x[3 * e + 2], l = lvl[e];
        double tol = 1e-15 * (1.0 + fabs(l));
        /* a, b: the bracket; fa: Illinois-scaled g(a), ga: g(a) itself; (a1, a2, a3), (b1, b2, b3):
           the payloads Ψ_{ah}(x), Ψ_{bh}(x) — at b = 1 the step the trace took (X) */
        double g0 = vp_sec_gap(kind, axis, l, x1, x2, x3);
        double a = 0.0, fa = g0, ga = g0, a1 = x1, a2 = x2, a3 = x3;
        double b = 1.0, b1 = X[3 * e], b2 = X[3 * e + 1], b3 = X[3 * e + 2];
        double fb = vp_sec_gap(kind, axis, l, b1, b2, b3);
        int bad = 0, done = fabs(g0) <= tol || fabs(fb) <= tol;
        for (int it = 0; it < 100 && !done && !bad; it++) {
            double den = fb - fa;
            double th = den != 0 ? (a * fb - b * fa) / den : 0.5 * (a + b);
            double lo = a < b ? a : b, hi = a < b ? b : a;
            th = th < lo ? lo : th > hi ? hi : th;
            double t1, t2, t3;  /* the one call site of the (inlined) step */
            bad = vp_step_exact(x1, x2, x3, th * h, &t1, &t2, &t3) != 0 || !_VP_FINITE(t1, t2, t3);
            double ft = vp_sec_gap(kind, axis, l, t1, t2, t3);
            /* Illinois: halve the retained end's value when the same end is kept twice */
            if (vp_sign(ft) == vp_sign(fb)) fa = fa * 0.5;
            else { a = b; fa = fb; ga = fb; a1 = b1; a2 = b2; a3 = b3; }
            done = fabs(ft) <= tol || fabs(th - a) <= 1e-15;
            b = th; fb = ft; b1 = t1; b2 = t2; b3 = t3;
        }
        int first = fabs(ga) < fabs(fb);
        double y1 = first ? a1 : b1, y2 = first ? a2 : b2, y3 = first ? a3 : b3;
        if (kind != 2) { if (axis == 0) y1 = l; else if (axis == 1) y2 = l; else y3 = l; }  /* snap */
        Y[3 * e] = y1; Y[3 * e + 1] = y2; Y[3 * e + 2] = y3;
        theta[e] = first ? a : b;
        undecided[e] = bad;
    }
}
"""


def sections_entry(lanes: dict[str, str]) -> str:
    """The C of ``vp_sections`` around the shared lane code ``lanes`` (load, step, store) of
    :func:`.emit.kernel_source`."""
    return _C.replace("@LOAD@", lanes["load"]).replace("@STEP@", lanes["step"]).replace("@STORE@", lanes["store"])

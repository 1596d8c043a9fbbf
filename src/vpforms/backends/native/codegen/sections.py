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
from the bracket [0, 1] with the step the trace took as Ψ_h(x), each evaluation the kernel's step
at θh (the vectorised pass over a block of crossings iterated in lockstep, the exact one where it
does not decide), then the point put on the plane (planes).
A crossing where any evaluation fails (status or non-finite) is flagged ``undecided``: the caller
locates it with the JAX locator, which owns the fallback rules.
"""

from __future__ import annotations

__all__ = ["KINDS", "SECTIONS_CDEF", "sections_entry"]

SECTIONS_CDEF = ("int64_t vp_sections(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, "
                 "double h, int32_t kind, int32_t axis, double value, double period, int32_t direction, "
                 "int64_t cap, int64_t *ev_line, int64_t *ev_step, double *ev_x, const double *fd);\n"
                 "void vp_locate(int64_t M, double *x, double *X, double *lvl, double h, int32_t kind, int32_t axis, "
                 "double *Y, double *theta, int32_t *undecided, const double *fd);")

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
                    int64_t cap, int64_t *ev_line, int64_t *ev_step, double *ev_x, const double *fd) {
    int64_t count = 0;
    int64_t Bn = vp_block(N), nb = (N + Bn - 1) / Bn;
    #pragma omp parallel for schedule(dynamic, 1) if (nb > 1)
    for (int64_t b = 0; b < nb; b++) {
@LOAD@        double q[B], p1[B], p2[B], p3[B];
        int64_t n0[B];
        int cr[B];
        for (int i = 0; i < B; i++) q[i] = vp_sec_q(kind, axis, value, period, a1[i], a2[i], a3[i]);
        for (int64_t k = nmin; k < n_target; k++) {
            #pragma omp simd
            for (int i = 0; i < B; i++) { p1[i] = a1[i]; p2[i] = a2[i]; p3[i] = a3[i]; n0[i] = nn[i]; }
@STEP@            /* the section function after the step and its change; a lane that took no step (done,
               frozen, failed just now) crosses nothing. Vectorised for the planes; atan2 lane by lane */
            int any_cross = 0;
            if (kind == 2) for (int i = 0; i < B; i++) {
                double qn = atan2(a2[i], a1[i]), d = vp_sec_dlevel(kind, value, period, q[i], qn);
                int adv = nn[i] != n0[i];
                cr[i] = adv & (direction > 0 ? d > 0 : direction < 0 ? d < 0 : d != 0);
                any_cross |= cr[i];
                q[i] = adv ? qn : q[i];
            } else {
                const double *c = axis == 0 ? a1 : axis == 1 ? a2 : a3;
                #pragma omp simd reduction(|:any_cross)
                for (int i = 0; i < B; i++) {
                    double s = c[i] - value;
                    double qn = kind == 0 ? (s >= 0 ? 1.0 : 0.0) : floor(s / period), d = qn - q[i];
                    int adv = nn[i] != n0[i];
                    cr[i] = adv & (direction > 0 ? d > 0 : direction < 0 ? d < 0 : d != 0);
                    any_cross |= cr[i];
                    q[i] = adv ? qn : q[i];
                }
            }
            if (any_cross) for (int i = 0; i < m; i++) {
                if (!cr[i]) continue;
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
               double *Y, double *theta, int32_t *undecided, const double *fd) {
    int64_t nb = (M + B - 1) / B;
    #pragma omp parallel for schedule(dynamic, 1) if (nb > 1)
    for (int64_t blk = 0; blk < nb; blk++) {  /* B crossings a block, iterated in lockstep */
        int64_t lo = blk * B;
        int m = (int)(M - lo < B ? M - lo : B);
        /* a, b: the bracket; fa: Illinois-scaled g(a), ga: g(a) itself; (a1, a2, a3), (b1, b2, b3):
           the payloads Ψ_{ah}(x), Ψ_{bh}(x) — at b = 1 the step the trace took (X) */
        double x1[B], x2[B], x3[B], l[B], tol[B], a[B], fa[B], ga[B], a1[B], a2[B], a3[B];
        double b[B], fb[B], b1[B], b2[B], b3[B], th[B], t1[B], t2[B], t3[B];
        int live[B], bad[B], redo[B];
        for (int i = 0; i < B; i++) {
            int64_t e = lo + (i < m ? i : 0);  /* padding lanes: a copy of the first, never live */
            x1[i] = x[3 * e]; x2[i] = x[3 * e + 1]; x3[i] = x[3 * e + 2]; l[i] = lvl[e];
            tol[i] = 1e-15 * (1.0 + fabs(l[i]));
            double g0 = vp_sec_gap(kind, axis, l[i], x1[i], x2[i], x3[i]);
            a[i] = 0.0; fa[i] = g0; ga[i] = g0; a1[i] = x1[i]; a2[i] = x2[i]; a3[i] = x3[i];
            b[i] = 1.0; b1[i] = X[3 * e]; b2[i] = X[3 * e + 1]; b3[i] = X[3 * e + 2];
            fb[i] = vp_sec_gap(kind, axis, l[i], b1[i], b2[i], b3[i]);
            bad[i] = 0;
            live[i] = (i < m) && !(fabs(g0) <= tol[i] || fabs(fb[i]) <= tol[i]);
        }
        for (int it = 0; it < 100; it++) {
            int any = 0;
            for (int i = 0; i < B; i++) any |= live[i];
            if (!any) break;
            for (int i = 0; i < B; i++) {  /* the regula falsi iterate, clipped to the bracket */
                double den = fb[i] - fa[i];
                double t = den != 0 ? (a[i] * fb[i] - b[i] * fa[i]) / den : 0.5 * (a[i] + b[i]);
                double lo_ = a[i] < b[i] ? a[i] : b[i], hi_ = a[i] < b[i] ? b[i] : a[i];
                th[i] = t < lo_ ? lo_ : t > hi_ ? hi_ : t;
            }
            #pragma omp simd
            for (int i = 0; i < B; i++) {  /* Ψ_{θh}(x): the kernel's step, as vp_run takes it */
                double T1, T2, T3;
                double good = vp_step_fast(x1[i], x2[i], x3[i], th[i] * h, &T1, &T2, &T3, fd);
                t1[i] = T1; t2[i] = T2; t3[i] = T3;
                redo[i] = live[i] & !(good > 0.5);
            }
            int anyr = 0;
            for (int i = 0; i < B; i++) anyr |= redo[i];
            if (anyr) for (int i = 0; i < B; i++) {
                if (!redo[i]) continue;
                double T1, T2, T3;
                int code = vp_step_exact(x1[i], x2[i], x3[i], th[i] * h, &T1, &T2, &T3, fd);
                t1[i] = T1; t2[i] = T2; t3[i] = T3;
                if (code != 0 || !_VP_FINITE(T1, T2, T3)) { bad[i] = 1; live[i] = 0; }  /* for JAX */
            }
            for (int i = 0; i < B; i++) {
                if (!live[i]) continue;
                double ft = vp_sec_gap(kind, axis, l[i], t1[i], t2[i], t3[i]);
                /* Illinois: halve the retained end's value when the same end is kept twice */
                if (vp_sign(ft) == vp_sign(fb[i])) fa[i] = fa[i] * 0.5;
                else { a[i] = b[i]; fa[i] = fb[i]; ga[i] = fb[i]; a1[i] = b1[i]; a2[i] = b2[i]; a3[i] = b3[i]; }
                live[i] = !(fabs(ft) <= tol[i] || fabs(th[i] - a[i]) <= 1e-15);
                b[i] = th[i]; fb[i] = ft; b1[i] = t1[i]; b2[i] = t2[i]; b3[i] = t3[i];
            }
        }
        for (int i = 0; i < m; i++) {
            int first = fabs(ga[i]) < fabs(fb[i]);
            double y1 = first ? a1[i] : b1[i], y2 = first ? a2[i] : b2[i], y3 = first ? a3[i] : b3[i];
            if (kind != 2) { if (axis == 0) y1 = l[i]; else if (axis == 1) y2 = l[i]; else y3 = l[i]; }  /* snap */
            Y[3 * (lo + i)] = y1; Y[3 * (lo + i) + 1] = y2; Y[3 * (lo + i) + 2] = y3;
            theta[lo + i] = first ? a[i] : b[i];
            undecided[lo + i] = bad[i];
        }
    }
}
"""


def sections_entry(lanes: dict[str, str]) -> str:
    """The C of ``vp_sections`` around the shared lane code ``lanes`` (load, step, store) of
    :func:`.emit.kernel_source`."""
    return _C.replace("@LOAD@", lanes["load"]).replace("@STEP@", lanes["step"]).replace("@STORE@", lanes["store"])

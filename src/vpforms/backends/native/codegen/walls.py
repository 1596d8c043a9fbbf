"""The kernel entry ``vp_wall``: the steps of ``vp_run`` (no saves), stopping each line at a wall.

What :func:`vpforms.fieldlines.trace_to_wall` does in its JAX scan, per lane, after every step the
lane takes from x_n to X = Ψ_h(x_n):

* the cylindrical (R, φ, Z) of X (Cartesian points: R = hypot(X₁, X₂), φ = atan2(X₂, X₁); the
  toroidal coordinates (u = R²/2, φ, Z): R = √(2u), φ = X₂);
* the wall's even-odd test on (R, Z) (the same arithmetic as ``_inside_kernel`` of
  :mod:`vpforms._polygon`). A lane carries a *margin*: the distance from its last fully
  tested point to the polygon minus the length of the (R, Z) chords it has moved since. While the
  margin is positive the point is inside (the distance is 1-Lipschitz: a path shorter than the
  distance stays in the open disc that holds no edge), so the O(vertices) test runs only near the
  wall;
* outside: the lane stops with status ``left_domain`` and stays at x_n (its step index n), and
  the kernel records n and X, for the exit to be located on the step family afterwards;
* inside: the trapezoid ∫|B| |dt| += |h| (|B(x_n)| + |B(X)|)/2 (|B| from the field's C, in
  toroidal coordinates |B|² = (a¹/R)² + (R a²)² + (a³)²) and the toroidal angle += φ(X) − φ(x_n)
  (wrapped into [−π, π) for Cartesian points).

The per-line accumulators (|B|, φ, ∫|B| dt, Σ dφ, margin) live in arrays the caller keeps between
calls; ``init`` ≠ 0 sets |B| and φ from the starting points and zeroes the others.
"""

from __future__ import annotations

import os
from typing import Any

import sympy as sp

from ...._errors import RESULTS
from ....symbolic import _symbols as G
from . import data
from .assign import _C, _assign

__all__ = ["WALL_CDEF", "speed_fn", "wall_entry"]

WALL_CDEF = ("void vp_wall(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h, "
             "int32_t toroidal, int64_t nv, const double *Rv, const double *Zv, double tolm, int32_t init, "
             "double *s, double *phi, double *L, double *dphi, double *mg, int64_t *step, double *Xo, "
             "const double *fd);")


def speed_fn(field: Any, field_exprs) -> str:
    """``vp_speed(x1, x2, x3, toroidal, fd)``: |B| of the flow ẋ = a at x (``speed`` of
    :mod:`vpforms.fieldlines._geometry`), a from the field's expressions (``field_exprs``)."""
    xs = {G.x[i]: _C[f"x{i + 1}"] for i in range(3)}
    with data.scope(function=True):
        body = _assign([f"sp_a{i + 1}" for i in range(3)], [sp.sympify(e) for e in field_exprs(field)], xs, "sp")
    lines = "\n    ".join(body)
    return f"""{_simd_decls()}static inline _VP_INLINE double vp_speed(double x1, double x2, double x3, int32_t toroidal,
                                         const double *restrict fd) {{
    {lines}
    double R = sqrt(2.0 * x1), b1 = toroidal ? sp_a1 / R : sp_a1, b2 = toroidal ? R * sp_a2 : sp_a2;
    return sqrt(b1 * b1 + b2 * b2 + sp_a3 * sp_a3);
}}
"""


def _simd_decls() -> str:
    """libmvec's vector atan2 and hypot (glibc ≥ 2.35), declared where this C library has them, so
    that gcc vectorises the wall's per-step loop on Cartesian points (else it stays scalar)."""
    v = os.confstr("CS_GNU_LIBC_VERSION") if hasattr(os, "confstr") else None
    try:
        major, minor = (int(p) for p in (v or "").split()[-1].split(".")[:2])
    except (ValueError, IndexError):
        return ""
    if (major, minor) < (2, 35):
        return ""
    return "".join(f'__attribute__((__simd__("notinbranch"))) double {f}(double, double);\n'
                   for f in ("atan2", "hypot"))


_C_WALL = """
/* Walls (vpforms.backends.native.codegen.walls) */
#define VP_PI 3.141592653589793
static inline _VP_INLINE void vp_cyl(int32_t tor, double a1, double a2, double *R, double *ph) {
    *R = tor ? sqrt(2.0 * a1) : hypot(a1, a2);
    *ph = tor ? a2 : atan2(a2, a1);
}
/* even-odd rule: a ray from (R, Z) towards +R crosses an odd number of edges */
static int vp_wall_inside(int64_t nv, const double *Rv, const double *Zv, double R, double Z) {
    int odd = 0;
    for (int64_t k = 0; k < nv; k++) {
        int64_t k2 = k + 1 == nv ? 0 : k + 1;
        int straddle = (Zv[k] > Z) != (Zv[k2] > Z);
        double dz = straddle ? Zv[k2] - Zv[k] : 1.0;
        double Rx = Rv[k] + (Z - Zv[k]) / dz * (Rv[k2] - Rv[k]);
        odd ^= straddle & (R < Rx);
    }
    return odd;
}
/* the distance from (R, Z) to the nearest edge */
static double vp_wall_dist(int64_t nv, const double *Rv, const double *Zv, double R, double Z) {
    double best = INFINITY;
    for (int64_t k = 0; k < nv; k++) {
        int64_t k2 = k + 1 == nv ? 0 : k + 1;
        double dR = Rv[k2] - Rv[k], dZ = Zv[k2] - Zv[k], pR = R - Rv[k], pZ = Z - Zv[k];
        double t = (pR * dR + pZ * dZ) / (dR * dR + dZ * dZ);
        t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
        double eR = pR - t * dR, eZ = pZ - t * dZ, d = eR * eR + eZ * eZ;
        best = d < best ? d : best;
    }
    return sqrt(best);
}
void vp_wall(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h,
             int32_t toroidal, int64_t nv, const double *Rv, const double *Zv, double tolm, int32_t init,
             double *s, double *phi, double *L, double *dphi, double *mg, int64_t *step, double *Xo,
             const double *fd) {
    int64_t nb = (N + B - 1) / B;
    double ah = fabs(h);
    #pragma omp parallel for schedule(dynamic, 1) if (nb > 1)  /* one block: no thread team to wake and wait for */
    for (int64_t b = 0; b < nb; b++) {
@LOAD@        /* per lane: |B|, φ, R at the last point reached; ∫|B| dt, Σ dφ; the margin; and the step's
           candidates (c*) before the wall test accepts them */
        double ws[B], wp[B], wR[B], wL[B], wd[B], wm[B], p1[B], p2[B], p3[B], cs[B], cp[B], cR[B], cd[B];
        int64_t n0[B];
        int full[B];
        for (int i = 0; i < B; i++) {
            int64_t j = lo + (i < m ? i : 0);  /* padding lanes: a copy of the first, never live */
            double R, ph;
            vp_cyl(toroidal, a1[i], a2[i], &R, &ph);
            if (init && i < m) {
                s[j] = vp_speed(a1[i], a2[i], a3[i], toroidal, fd); phi[j] = ph;
                L[j] = 0.0; dphi[j] = 0.0; mg[j] = 0.0; step[j] = -1;
            }
            ws[i] = s[j]; wp[i] = phi[j]; wR[i] = R; wL[i] = L[j]; wd[i] = dphi[j]; wm[i] = mg[j];
        }
        for (int64_t k = nmin; k < n_target; k++) {
            for (int i = 0; i < B; i++) { p1[i] = a1[i]; p2[i] = a2[i]; p3[i] = a3[i]; n0[i] = nn[i]; }
@STEP@            /* the new point's (R, φ), |B| and angle increment; the margin less the (R, Z) chord */
            /* over all B lanes, not mv: a trip count that is a multiple of every vector width, so no
               lane runs in a scalar epilogue (libm's atan2 and libmvec's differ in the last bit, and a
               line's numbers must not depend on the lines beside it) */
            int anyfull = 0;
            #pragma omp simd reduction(|:anyfull)
            for (int i = 0; i < B; i++) {
                double R, ph;
                vp_cyl(toroidal, a1[i], a2[i], &R, &ph);
                double dR = R - wR[i], dZ = a3[i] - p3[i], d = ph - wp[i];
                double mgn = wm[i] - sqrt(dR * dR + dZ * dZ);
                int adv = nn[i] != n0[i];
                full[i] = adv & !(mgn > tolm);
                anyfull |= full[i];
                wm[i] = adv ? mgn : wm[i];
                cs[i] = vp_speed(a1[i], a2[i], a3[i], toroidal, fd);
                cd[i] = toroidal ? d : d - 2.0 * VP_PI * floor((d + VP_PI) / (2.0 * VP_PI));
                cp[i] = ph; cR[i] = R;
            }
            /* near the wall (or the first step): the full test; outside, the line stops at x_n and
               the kernel records the exit step n and X */
            if (anyfull) for (int i = 0; i < m; i++) {
                if (!full[i]) continue;
                int in = vp_wall_inside(nv, Rv, Zv, cR[i], a3[i]);
                wm[i] = in ? vp_wall_dist(nv, Rv, Zv, cR[i], a3[i]) : 0.0;
                if (in) continue;
                int64_t j = lo + i;
                step[j] = n0[i];
                Xo[3 * j] = a1[i]; Xo[3 * j + 1] = a2[i]; Xo[3 * j + 2] = a3[i];
                a1[i] = p1[i]; a2[i] = p2[i]; a3[i] = p3[i]; nn[i] = n0[i]; st[i] = @LEFT@;
            }
            /* the steps taken: the trapezoid ∫|B| |dt| and the toroidal angle */
            #pragma omp simd
            for (int i = 0; i < B; i++) {
                int acc = nn[i] != n0[i];
                wL[i] += acc ? 0.5 * ah * (ws[i] + cs[i]) : 0.0;
                wd[i] += acc ? cd[i] : 0.0;
                ws[i] = acc ? cs[i] : ws[i]; wp[i] = acc ? cp[i] : wp[i]; wR[i] = acc ? cR[i] : wR[i];
            }
        }
        for (int i = 0; i < m; i++) {
            int64_t j = lo + i;
            s[j] = ws[i]; phi[j] = wp[i]; L[j] = wL[i]; dphi[j] = wd[i]; mg[j] = wm[i];
        }
@STORE@    }
}
"""


def wall_entry(lanes: dict[str, str], speed: str) -> str:
    """The C of ``vp_wall`` around the shared lane code ``lanes`` (load, step, store) of
    :func:`.emit.kernel_source`, with ``speed`` the C of :func:`speed_fn`."""
    return speed + (_C_WALL.replace("@LOAD@", lanes["load"]).replace("@STEP@", lanes["step"])
                    .replace("@STORE@", lanes["store"]).replace("@LEFT@", str(RESULTS.left_domain)))

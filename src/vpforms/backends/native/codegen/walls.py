"""The kernel entry ``vp_wall``: the steps of ``vp_run`` (no saves), stopping each line at a wall.

What :func:`vpforms.fieldlines.trace_to_wall` does in its JAX scan, per lane, after every step the
lane takes from x_n to X = Ψ_h(x_n):

* the cylindrical (R, φ, Z) of X (Cartesian points: R = hypot(X₁, X₂), φ = atan2(X₂, X₁); the
  toroidal coordinates (u = R²/2, φ, Z): R = √(2u), φ = X₂);
* the even-odd test on (R, Z) of the boundary at the point's φ (the same arithmetic as
  :func:`vpforms.domains.boundary_inside`: a wall polygon, or the polygons of a
  :class:`~vpforms.domains.ToroidalDomain` interpolated linearly in φ between its planes). A lane
  carries a *margin*: the distance from its last fully tested point to the boundary minus the
  length of the (R, Z) chords it has moved since and minus ``vspeed``·|Δφ| (the boundary's vertices
  move at most ``vspeed`` per radian; 0 for a wall). While the margin is positive the point is
  inside (the distance is Lipschitz: a path shorter than the distance stays in the open disc that
  holds no edge), so the O(vertices) test runs only near the boundary;
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
             "int32_t toroidal, int64_t np_, const double *pp, double period, double vspeed, "
             "int64_t nv, const double *Rv, const double *Zv, double tolm, int32_t init, "
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
/* the boundary at φ (vpforms.domains): planes pp[0] < … < pp[np_−1] of one period, vertices
   V(φ) = (1 − w) V_j + w V_j2 between planes j and j2 (one plane: w = 0, its vertices exactly);
   the arithmetic of vpforms.domains._vertices_at (jnp.mod: fmod, then + period where the signs differ) */
static void vp_wall_plane(int64_t np_, const double *pp, double period, double ph,
                          int64_t *j, int64_t *j2, double *w) {
    if (np_ == 1) { *j = 0; *j2 = 0; *w = 0.0; return; }
    double r = fmod(ph - pp[0], period);
    if (r != 0.0 && (r < 0.0) != (period < 0.0)) r += period;
    double s = pp[0] + r;
    int64_t a = 0;
    while (a + 1 < np_ && pp[a + 1] <= s) a++;
    double hi = a + 1 < np_ ? pp[a + 1] : pp[0] + period;
    *j = a; *j2 = a + 1 < np_ ? a + 1 : 0; *w = (s - pp[a]) / (hi - pp[a]);
}
#define VP_VR(k) ((1.0 - w) * Rv[j * nv + (k)] + w * Rv[j2 * nv + (k)])
#define VP_VZ(k) ((1.0 - w) * Zv[j * nv + (k)] + w * Zv[j2 * nv + (k)])
/* even-odd rule: a ray from (R, Z) towards +R crosses an odd number of edges of V(φ) */
static int vp_wall_inside(int64_t np_, const double *pp, double period, int64_t nv, const double *Rv,
                          const double *Zv, double R, double ph, double Z) {
    int64_t j, j2;
    double w;
    vp_wall_plane(np_, pp, period, ph, &j, &j2, &w);
    int odd = 0;
    for (int64_t k = 0; k < nv; k++) {
        int64_t k2 = k + 1 == nv ? 0 : k + 1;
        double R1 = VP_VR(k), Z1 = VP_VZ(k), R2 = VP_VR(k2), Z2 = VP_VZ(k2);
        int straddle = (Z1 > Z) != (Z2 > Z);
        double dz = straddle ? Z2 - Z1 : 1.0;
        double Rx = R1 + (Z - Z1) / dz * (R2 - R1);
        odd ^= straddle & (R < Rx);
    }
    return odd;
}
/* the distance from (R, Z) to the nearest edge of V(φ) */
static double vp_wall_dist(int64_t np_, const double *pp, double period, int64_t nv, const double *Rv,
                           const double *Zv, double R, double ph, double Z) {
    int64_t j, j2;
    double w;
    vp_wall_plane(np_, pp, period, ph, &j, &j2, &w);
    double best = INFINITY;
    for (int64_t k = 0; k < nv; k++) {
        int64_t k2 = k + 1 == nv ? 0 : k + 1;
        double R1 = VP_VR(k), Z1 = VP_VZ(k);
        double dR = VP_VR(k2) - R1, dZ = VP_VZ(k2) - Z1, pR = R - R1, pZ = Z - Z1;
        double t = (pR * dR + pZ * dZ) / (dR * dR + dZ * dZ);
        t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
        double eR = pR - t * dR, eZ = pZ - t * dZ, d = eR * eR + eZ * eZ;
        best = d < best ? d : best;
    }
    return sqrt(best);
}
#undef VP_VR
#undef VP_VZ
void vp_wall(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h,
             int32_t toroidal, int64_t np_, const double *pp, double period, double vspeed,
             int64_t nv, const double *Rv, const double *Zv, double tolm, int32_t init,
             double *s, double *phi, double *L, double *dphi, double *mg, int64_t *step, double *Xo,
             const double *fd) {
    int64_t Bn = vp_block(N), nb = (N + Bn - 1) / Bn;
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
                cd[i] = toroidal ? d : d - 2.0 * VP_PI * floor((d + VP_PI) / (2.0 * VP_PI));
                /* the boundary moves by at most vspeed·|Δφ| (vpforms.domains: Lipschitz in φ) */
                double mgn = wm[i] - sqrt(dR * dR + dZ * dZ) - vspeed * fabs(cd[i]);
                int adv = nn[i] != n0[i];
                full[i] = adv & !(mgn > tolm);
                anyfull |= full[i];
                wm[i] = adv ? mgn : wm[i];
                cs[i] = vp_speed(a1[i], a2[i], a3[i], toroidal, fd);
                cp[i] = ph; cR[i] = R;
            }
            /* near the wall (or the first step): the full test; outside, the line stops at x_n and
               the kernel records the exit step n and X */
            if (anyfull) for (int i = 0; i < m; i++) {
                if (!full[i]) continue;
                int in = vp_wall_inside(np_, pp, period, nv, Rv, Zv, cR[i], cp[i], a3[i]);
                wm[i] = in ? vp_wall_dist(np_, pp, period, nv, Rv, Zv, cR[i], cp[i], a3[i]) : 0.0;
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

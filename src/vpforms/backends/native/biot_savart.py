"""A and B of filamentary coils at many points, natively (issue #38 item 2).

The segment loop is the SymPy-generated helper of the stepping kernels
(:func:`.codegen.coils._segment_helper`: Σ_s ê_s ∂^α f_s, f_s = (μ0 I_s/4π) log1p(2L_s/D_s),
Hanson & Hirshman with the cancellation-free D_s of :mod:`vpforms.coils._segments`), so the value
and its derivatives here are, term by term, those the native steps use. One kernel, compiled once
for every coil set (the coils are data: :func:`.codegen.coils._pack`):

* A = Σ_s ê_s f_s (α = 000);
* B = Σ_s g_s ê_s × (x − x_i), g_s = (μ0 I_s/4π) 2L(R_i+R_f)/(R_i R_f (R_i+R_f+L) D_s), the closed
  form of the same segments (:func:`.codegen.coils._segment_B_helper`, same D_s), equal to the
  curl of that A to rounding (tested against the first derivatives of the A loop) and ~2× cheaper
  than that curl (no logarithm).

The points are shared among OpenMP threads (``OMP_NUM_THREADS``); each point loops over every
segment with nothing stored per pair, so memory is the points and the coils (O(N + S)) for any
number of segments. :func:`evaluate` is what :func:`vpforms.coils.biot_savart` calls on the native
backend.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .build import build
from .codegen.coils import _LOG1P_DECL, _NAME, _pack, _segment_B_helper, _segment_helper

__all__ = ["evaluate"]

_CDEF = """
void vp_bs_A(const double *fd, const double *h, const double *x, int64_t n, double *out);
void vp_bs_B(const double *fd, const double *h, const double *x, int64_t n, double *out);
void vp_bs_dA(const double *fd, const double *h, const double *x, int64_t n, double *out);
"""

_FIRST = ((1, 0, 0), (0, 1, 0), (0, 0, 1))


@lru_cache(maxsize=1)
def _source() -> str:
    """The C source: the segment loops (A; B; A's first derivatives) and a point loop for each."""
    value = _segment_helper(((0, 0, 0),)).replace(_NAME, "vp_bs_value")
    closed = _segment_B_helper().replace(_NAME, "vp_bs_closed")
    first = _segment_helper(_FIRST).replace(_NAME, "vp_bs_first")
    return f"""#include <math.h>
#include <stdint.h>
{_LOG1P_DECL}{value}
{closed}
{first}
/* A at the points x (n × 3): Σ_s ê_s f_s */
void vp_bs_A(const double *fd, const double *h, const double *x, int64_t n, double *out) {{
    #pragma omp parallel for schedule(dynamic, 64)
    for (int64_t i = 0; i < n; i++)
        vp_bs_value(fd, h, x[3 * i], x[3 * i + 1], x[3 * i + 2], out + 3 * i);
}}

/* B at the points x: Σ_s g_s ê_s × (x − x_i) */
void vp_bs_B(const double *fd, const double *h, const double *x, int64_t n, double *out) {{
    #pragma omp parallel for schedule(dynamic, 64)
    for (int64_t i = 0; i < n; i++)
        vp_bs_closed(fd, h, x[3 * i], x[3 * i + 1], x[3 * i + 2], out + 3 * i);
}}

/* ∂_j A_k at the points x (n × 9, k·3 + j): the A loop's first derivatives */
void vp_bs_dA(const double *fd, const double *h, const double *x, int64_t n, double *out) {{
    #pragma omp parallel for schedule(dynamic, 64)
    for (int64_t i = 0; i < n; i++)
        vp_bs_first(fd, h, x[3 * i], x[3 * i + 1], x[3 * i + 2], out + 9 * i);
}}
"""


def _data(coils) -> tuple[np.ndarray, np.ndarray]:
    """(fd, h): the coils' segment arrays and their header, as the stepping kernels pack them."""
    parts = []

    def put(a):
        parts.append(np.asarray(a, np.float64))
        return 0  # the arrays start at fd[0]

    h = np.zeros(2)
    _pack(coils, h, put)
    return np.ascontiguousarray(parts[0]), h


def evaluate(coils, points: np.ndarray, what: str) -> np.ndarray:
    """A (``what="A"``, (N, 3), T·m), B (``"B"``, (N, 3), T) or the Jacobian of A (``"dA"``,
    (N, 3, 3): [k, j] = ∂_j A_k, T) of a :class:`vpforms.coils.CoilSet` at ``points`` (N, 3) (m)."""
    lib = build(_source(), _CDEF)
    fd, h = _data(coils)
    x = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    out = np.empty((x.shape[0], 9 if what == "dA" else 3))
    ffi = lib.ffi
    fn = {"A": lib.lib.vp_bs_A, "B": lib.lib.vp_bs_B, "dA": lib.lib.vp_bs_dA}[what]
    fn(ffi.from_buffer("double[]", fd), ffi.from_buffer("double[]", h), ffi.from_buffer("double[]", x),
       x.shape[0], ffi.from_buffer("double[]", out))
    return out.reshape(-1, 3, 3) if what == "dA" else out

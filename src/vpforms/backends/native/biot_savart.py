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

Current elements (:class:`vpforms.coils.QuadratureCoils`, simsopt's rule): A = (μ0/4π) Σ_k w_k/r_k,
B = (μ0/4π) Σ_k w_k × (x − γ_k)/r_k³, r_k = |x − γ_k| (:func:`.codegen.coils._element_helper`), as
:mod:`vpforms.coils._quadrature_coils` writes them for JAX.

The points are shared among OpenMP threads (``OMP_NUM_THREADS``); each point loops over every
segment with nothing stored per pair, so memory is the points and the coils (O(N + S)) for any
number of segments. :func:`evaluate` is what ``CoilSet.evaluate`` and ``QuadratureCoils.evaluate``
call on the native backend.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...coils import _coilset
from .build import available, build
from .codegen.coils import _LOG1P_DECL, _MU0_4PI, _NAME, _element_helper, _pack, _segment_B_helper, _segment_helper

__all__ = ["evaluate"]

_FIRST = ((1, 0, 0), (0, 1, 0), (0, 0, 1))


def _loops() -> dict[str, tuple[str, int, str]]:
    """Entry name → (the helper's C, doubles out per point, what it computes)."""
    return {
        "vp_bs_A": (_segment_helper(((0, 0, 0),)), 3, "A of segments: Σ_s ê_s f_s"),
        "vp_bs_B": (_segment_B_helper(), 3, "B of segments: Σ_s g_s ê_s × (x − x_i)"),
        "vp_bs_dA": (_segment_helper(_FIRST), 9, "∂_j A_k of segments (k·3 + j): the A loop's first derivatives"),
        "vp_el_A": (_element_helper("A"), 3, "A of current elements: Σ_k w_k/r_k"),
        "vp_el_B": (_element_helper("B"), 3, "B of current elements: Σ_k w_k × (x − γ_k)/r_k³"),
    }


_CDEF = "".join(f"void {name}(const double *fd, const double *h, const double *x, int64_t n, double *out);\n"
                for name in ("vp_bs_A", "vp_bs_B", "vp_bs_dA", "vp_el_A", "vp_el_B"))


@lru_cache(maxsize=1)
def _source() -> str:
    """The C source: each helper (one point, a loop over the segments or elements) and an OpenMP
    loop over the points calling it."""
    parts = ["#include <math.h>", "#include <stdint.h>", _LOG1P_DECL]
    for name, (helper, width, what) in _loops().items():
        parts += [helper.replace(_NAME, f"{name}_one"), f"""/* {what}, at the points x (n × 3) */
void {name}(const double *fd, const double *h, const double *x, int64_t n, double *out) {{
    #pragma omp parallel for schedule(dynamic, 64)
    for (int64_t i = 0; i < n; i++)
        {name}_one(fd, h, x[3 * i], x[3 * i + 1], x[3 * i + 2], out + {width} * i);
}}
"""]
    return "\n".join(parts)


def _data(coils) -> tuple[np.ndarray, np.ndarray, str]:
    """(fd, h, prefix): the coils' arrays, their header [offset 0, count] and the entries' prefix —
    a :class:`~vpforms.coils.CoilSet`'s segments as the stepping kernels pack them (``vp_bs``), or
    a :class:`~vpforms.coils.QuadratureCoils`' elements γ_k, (μ0/4π) w_k (``vp_el``)."""
    if hasattr(coils, "elements"):
        gamma, w = (np.asarray(a, np.float64) for a in coils.elements())
        fd = np.concatenate([gamma.T.ravel(), (_MU0_4PI * w).T.ravel()])
        return fd, np.array([0.0, gamma.shape[0]]), "vp_el"
    parts = []

    def put(a):
        parts.append(np.asarray(a, np.float64))
        return 0  # the arrays start at fd[0]

    h = np.zeros(2)
    _pack(coils, h, put)
    return np.ascontiguousarray(parts[0]), h, "vp_bs"


def evaluate(coils, points: np.ndarray, what: str) -> np.ndarray:
    """A (``what="A"``, (N, 3), T·m) or B (``"B"``, (N, 3), T) of a :class:`vpforms.coils.CoilSet`
    or :class:`~vpforms.coils.QuadratureCoils` at ``points`` (N, 3) (m); for a CoilSet also the
    Jacobian of A (``"dA"``, (N, 3, 3): [k, j] = ∂_j A_k, T)."""
    lib = build(_source(), _CDEF)
    fd, h, prefix = _data(coils)
    x = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    out = np.empty((x.shape[0], 9 if what == "dA" else 3))
    ffi = lib.ffi
    fn = getattr(lib.lib, f"{prefix}_{what}")
    fn(ffi.from_buffer("double[]", fd), ffi.from_buffer("double[]", h), ffi.from_buffer("double[]", x),
       x.shape[0], ffi.from_buffer("double[]", out))
    return out.reshape(-1, 3, 3) if what == "dA" else out


_coilset.NATIVE.update(evaluate=evaluate, available=available)  # CoilSet/QuadratureCoils.evaluate

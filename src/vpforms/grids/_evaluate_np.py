"""NumPy evaluation of tensor splines at many concrete points: no JAX compilation.

The same arithmetic as :func:`vpforms.grids._bspline.evaluate` (the knot interval of each
coordinate, the cell polynomials of :func:`~vpforms.grids._bspline.cell_polynomials` by Horner,
one coefficient block per point, contracted axis by axis), vectorised over the points instead of
traced. JAX compiles its evaluation once per grid *shape*; a tolerance search
(:func:`vpforms.grids.refine_to_tol`) builds a new shape every round and estimates its error at
1000 points, so the compilations cost more than everything else (13 compilations, 14 s of a
degree-5 search on the l = 2 coils, issue #39). Here nothing is compiled.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._bspline import basis_derivative, wrapped

__all__ = ["derivatives_np", "curl_np"]

#: points per block (the gathered coefficient blocks of a chunk: (C, (k+1)³, *rest) doubles)
_CHUNK = 4096


def _axis_np(t: np.ndarray, P: np.ndarray, k: int, period: float | None, x: np.ndarray,
             orders: Sequence[int]) -> tuple[dict[int, np.ndarray], np.ndarray]:
    """({n: the n-th derivatives of the k+1 non-zero basis functions at x, shape (N, k+1)}, index
    of each point's first coefficient (N,)) on one axis (``_bspline._axis`` over arrays)."""
    m = t.size - k - 1
    x, xs = wrapped(t, k, period, x, np)
    # the knot interval t_i ≤ x < t_{i+1}, k ≤ i ≤ m − 1 (the right end belongs to the last one)
    i = np.clip(np.searchsorted(t, np.nan_to_num(xs, nan=t[k]), side="right") - 1, k, m - 1)
    y = (x - t[i])[:, None]
    Pi = P[i - k]  # (N, k+1 basis functions, k+1 powers)
    return {n: basis_derivative(Pi, y, k, n) for n in sorted(set(orders))}, i - k


def derivatives_np(spline, points: np.ndarray, orders: Sequence[Sequence[int]]) -> np.ndarray:
    """∂^α s at ``points`` (N, 3) for α in ``orders``: shape (len(orders), N, *rest), NumPy (a
    :class:`~vpforms.grids._bspline.TensorSpline`; NaN off the grid on a non-periodic axis)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    knots = [np.asarray(t) for t in spline.knots]
    cells = [np.asarray(P) for P in spline.cells]
    c = np.asarray(spline.coefficients)
    k = spline.degrees
    rest = c.shape[3:]
    out = np.empty((len(orders), pts.shape[0], *rest))
    r = [np.arange(d + 1) for d in k]
    for lo in range(0, pts.shape[0], _CHUNK):
        q = pts[lo:lo + _CHUNK]
        Ns, starts = [], []
        for a in range(3):
            N, s = _axis_np(knots[a], cells[a], k[a], spline.periods[a], q[:, a], [o[a] for o in orders])
            Ns.append(N)
            starts.append(s)
        block = c[(starts[0][:, None, None, None] + r[0][None, :, None, None]),
                  (starts[1][:, None, None, None] + r[1][None, None, :, None]),
                  (starts[2][:, None, None, None] + r[2][None, None, None, :])]  # (C, k₀+1, k₁+1, k₂+1, *rest)
        partial = {}
        for j, o in enumerate(orders):
            # Σ_abc c_abc N¹_a N²_b N³_c, one axis at a time (shared partial sums)
            if o[0] not in partial:
                partial[o[0]] = np.einsum("na,nabc...->nbc...", Ns[0][o[0]], block)
            v = np.einsum("nb,nbc...->nc...", Ns[1][o[1]], partial[o[0]])
            out[j, lo:lo + _CHUNK] = np.einsum("nc,nc...->n...", Ns[2][o[2]], v)
    return out


#: the first derivatives ∂₁, ∂₂, ∂₃
_GRAD = ((1, 0, 0), (0, 1, 0), (0, 0, 1))


def curl_np(splines: Sequence, points: np.ndarray) -> np.ndarray:
    """∇×A (unit Jacobian: (∂₂A₃ − ∂₃A₂, ∂₃A₁ − ∂₁A₃, ∂₁A₂ − ∂₂A₁)) of three TensorSplines at
    ``points`` (..., 3): shape (..., 3), NumPy (the JAX ``curl_of`` of the same splines, to rounding)."""
    p = np.asarray(points, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"points must have shape (..., 3); got {p.shape}")
    d = [derivatives_np(s, p.reshape(-1, 3), _GRAD) for s in splines]  # d[i][j] = ∂_j A_i
    out = np.stack([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]], axis=-1)
    return out.reshape(p.shape)

"""Interpolation on part of a tensor grid (issue #38: grids only where the plasma is).

A grid that follows the plasma keeps the nodes of a *mask* (the cells that meet a domain, dilated)
and ignores the others — where a rectangle holds coil wires, A is singular and its interpolant
rings over the whole grid. The tensor spline is still one spline on the full knot vectors: fitted
axis by axis (as :meth:`TensorSpline.interpolate`), but every grid line is fitted only on its runs
of kept nodes. On a run x_a < … < x_b of at least k + 1 nodes the fit is the run's own not-a-knot
interpolant s_run (scipy's ``make_interp_spline`` on the run: O(hᵏ⁺¹) up to the run's ends, using
no value outside it). Its knots are nodes, so s_run lies in the span of the global B-splines on
[x_a, x_b] (the global knot vector has a knot at every node of the run, at least); its coefficients
in that basis follow cell by cell (:func:`_fit_map`: a (k + 1)-square solve per cell) — exact to rounding. A
line that is kept whole is fitted as the full grid is (not-a-knot, or periodic on a periodic axis);
a run on a periodic axis may wrap round the period (a B-spline that straddles the gap between the
two ends of a run is left out: the run alone cannot determine it). Coefficients that no run
touches, or that two runs of a line touch (a B-spline reaching over a gap of fewer than k + 1 nodes),
are NaN: the spline is NaN on every cell that needs one of them (a line there is outside
the grid's domain).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

__all__ = ["masked_axis_fit"]


def _runs(keep: np.ndarray, periodic: bool) -> list[tuple[int, int]]:
    """Maximal runs (start, length) of True in ``keep`` (n,); on a periodic axis a run may wrap
    (start + length > n); the whole line is (0, n)."""
    n = keep.size
    if keep.all():
        return [(0, n)]
    # on a periodic axis, walk from just after a gap, so that no run is cut by the walk's start
    start = int(np.flatnonzero(~keep)[0]) + 1 if periodic else 0
    out: list[tuple[int, int]] = []
    first, length = -1, 0
    for i in range(n):
        idx = (start + i) % n
        if keep[idx]:
            first, length = (idx, 1) if length == 0 else (first, length + 1)
        elif length:
            out.append((first, length))
            length = 0
    if length:
        out.append((first, length))
    return out


def masked_axis_fit(x: np.ndarray, t: np.ndarray, k: int, period: float | None, y: np.ndarray,
                    keep: np.ndarray, full_fit) -> np.ndarray:
    """Coefficients along axis 0 of the degree-k spline with knots ``t`` fitted to ``y`` (n, L)
    line by line on the runs of ``keep`` (n, L) (module docstring): shape (m, L), m = len(t) − k − 1,
    NaN where no run, or more than one, touches a coefficient. ``full_fit(Y)`` fits whole lines (n, L') the way the
    unmasked interpolation does (same knots)."""
    n, L = y.shape
    m = t.size - k - 1
    out = np.full((m, L), np.nan)
    groups: dict[tuple[int, int], list[np.ndarray]] = defaultdict(list)
    # the runs of each distinct mask column once (a grid's lines share a few hundred patterns)
    cols_bits = np.ascontiguousarray(np.packbits(np.asarray(keep, bool).T, axis=1))  # a column as bytes
    _, first, which = np.unique(cols_bits.view(np.dtype((np.void, cols_bits.shape[1]))).ravel(),
                                return_index=True, return_inverse=True)
    patterns = np.asarray(keep, bool).T[first]
    members = np.argsort(which.ravel(), kind="stable")
    bounds = np.searchsorted(which.ravel()[members], np.arange(patterns.shape[0] + 1))
    for p, pattern in enumerate(patterns):
        for run in _runs(pattern, period is not None):
            if run[1] >= k + 1:
                groups[run].append(members[bounds[p]:bounds[p + 1]])
    maps: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    runs_at = np.zeros((m, L), np.int16)  # how many runs of its line fitted each coefficient
    for (a, length), parts in groups.items():
        cols = np.sort(np.concatenate(parts))
        if length == n:
            out[:, cols] = full_fit(y[:, cols])
            continue
        idx = (a + np.arange(length)) % n
        xr = x[idx] + (period if period is not None else 0.0) * ((a + np.arange(length)) >= n)
        touched, c_of = _run_map(xr, t, k, n, period, maps, a)
        out[np.ix_(touched, cols)] = c_of @ y[np.ix_(idx, cols)]
        runs_at[np.ix_(touched, cols)] += 1
    # a B-spline that reaches over a gap of fewer than k + 1 nodes into the next run was fitted by
    # both runs, to two different values: neither run alone determines it, so it is NaN (and so are
    # the cells next to the gap that need it)
    out[runs_at > 1] = np.nan
    if period is not None:
        out[n:] = out[:k]
    return out


def _run_map(xr: np.ndarray, t: np.ndarray, k: int, n: int, period: float | None,
             maps: dict[bytes, tuple[np.ndarray, np.ndarray]], start: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(touched, M): the coefficients that the run of nodes ``xr`` (its first node ``start``)
    determines and the linear map M from its values to them, c[touched] = M @ y_run.

    M gives the coefficients of the run's not-a-knot interpolant (:func:`_fit_map`), a linear
    function of y_run. It depends only on the run's geometry — its nodes and the knots of
    the B-splines that meet it, up to an affine map — so runs of the same shape share it (on a
    uniform grid, every interior run of one length): ``maps`` holds it per shape (:func:`_shape`),
    with the coefficients counted from the run's first node."""
    key = _shape(xr, t, k, n, period, start)
    if key not in maps:
        touched, M = _fit_map(xr, t, k, n, period)
        maps[key] = ((touched - start) % n if period is not None else touched - start, M)
    rel, M = maps[key]
    return ((rel + start) % n if period is not None else rel + start), M


def _shape(xr: np.ndarray, t: np.ndarray, k: int, n: int, period: float | None, start: int) -> bytes:
    """The run's geometry as bytes: its nodes and the knots of every B-spline that meets it
    (indices relative to ``start``), relative to the run and scaled by its length, to ~3e-13
    (:func:`_quantized`). On a periodic axis the knots t_j, |j − start| ≤ 2k + 2 … up to 2k + 2 past
    the run's end, periodically continued (B-spline j starts within (k + 1)/2 nodes of node j)."""
    L = xr.size
    if period is None:  # B-spline j meets (x_a, x_b) iff t_j < x_b and t_{j+k+1} > x_a
        j = np.arange(max(int(np.searchsorted(t, xr[0], "right")) - k - 1, 0),
                      min(int(np.searchsorted(t, xr[-1], "left")) + k + 1, t.size))
        knots = t[j]
    else:  # t_{k + i + q n} = t_{k + i} + q T
        j = np.arange(start - 2 * k - 2, start + L + 2 * k + 3)
        q, i = np.divmod(j - k, n)
        knots = t[k + i] + q * period
    scale = xr[-1] - xr[0]
    return b"".join((np.array([k, n, L, j[0] - start, j[-1] - start, period is None]).tobytes(),
                     _quantized((xr - xr[0]) / scale), _quantized((knots - xr[0]) / scale)))


def _fit_map(xr: np.ndarray, t: np.ndarray, k: int, n: int, period: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(touched, M) of :func:`_run_map` for one run. On each cell of the run the k + 1 B-splines
    that do not vanish there are a basis of the polynomials of degree k, and the run's interpolant
    is one such polynomial (its knots are nodes): their coefficients solve a (k + 1)-square system
    at k + 1 Chebyshev points of the cell — exact, and the same from every cell a B-spline meets.
    One cell per B-spline is solved: the last cell of its support in the run (which fixes the k
    B-splines after it as well)."""
    frac = 0.5 - 0.5 * np.cos(np.pi * (2 * np.arange(k + 1) + 1) / (2 * k + 2))  # inside (0, 1)
    P = (xr[:-1, None] + np.diff(xr)[:, None] * frac).ravel()  # cell-major: cell c is rows c(k+1) …
    Pw = P if period is None else t[k] + np.mod(P - t[k], period)
    D = BSpline.design_matrix(Pw, t, k).toarray()
    if period is not None:  # c_{n+j} = c_j: fold the wrapped columns
        D[:, :k] += D[:, n:]
        D = D[:, :n]
    nz = (D != 0).reshape(xr.size - 1, k + 1, -1).any(axis=1)  # (cells, B-splines): B-spline meets cell
    ok = np.ones(xr.size - 1, bool)
    if period is not None:
        # a B-spline that straddles a short gap of the line meets both ends of the run: the run
        # cannot fix it alone — it stays NaN, and so do the cells that need it
        first = np.argmax(nz, axis=0)
        last = nz.shape[0] - 1 - np.argmax(nz[::-1], axis=0)
        straddles = nz.any(axis=0) & (last - first + 1 > nz.sum(axis=0))  # its cells are not one block
        ok = ~nz[:, straddles].any(axis=1)
    nz &= ok[:, None]
    touched = np.flatnonzero(nz.any(axis=0))
    # s_run = S @ y_run: the interpolant of each unit vector, at the points
    S = make_interp_spline(xr, np.eye(xr.size), k=k, axis=0)(P)
    M = np.full((touched.size, xr.size), np.nan)
    col = {j: i for i, j in enumerate(touched)}
    done = np.zeros(touched.size, bool)
    cells, ats = [], []
    for i, j in enumerate(touched):
        if done[i]:
            continue
        c = int(np.flatnonzero(nz[:, j])[-1])  # the last cell of B-spline j in the run
        at = [col[q] for q in np.flatnonzero(nz[c])]
        cells.append(c)
        ats.append(at)
        done[at] = True
    if not cells:  # a run no B-spline of which it fixes alone (a short periodic line, a 1-node gap)
        return touched, M
    # the cells' (k + 1)-square systems in one batched solve
    rows = np.asarray(cells)[:, None] * (k + 1) + np.arange(k + 1)  # (cells, k + 1)
    sol = np.linalg.solve(D[rows[:, :, None], touched[np.asarray(ats)][:, None, :]], S[rows])
    M[np.asarray(ats)] = sol
    return touched, M


def _quantized(a: np.ndarray) -> bytes:
    """``a`` to ~3e-13, as bytes: equal for arrays equal to rounding. The scale is irrational so that
    exact values (a uniform grid's nodes and knots relative to a run: fractions) never fall halfway
    between two steps, where rounding noise would split them."""
    return (np.round(a * (1e12 * np.pi)) + 0.0).tobytes()  # + 0.0: no −0.0

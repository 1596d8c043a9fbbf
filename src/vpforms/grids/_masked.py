"""Interpolation on part of a tensor grid (issue #38: grids only where the plasma is).

A grid that follows the plasma keeps the nodes of a *mask* (the cells that meet a domain, dilated)
and ignores the others — where a rectangle holds coil wires, A is singular and its interpolant
rings over the whole grid. The tensor spline is still one spline on the full knot vectors: fitted
axis by axis (as :meth:`TensorSpline.interpolate`), but every grid line is fitted only on its runs
of kept nodes. On a run x_a < … < x_b of at least k + 1 nodes the fit is the run's own not-a-knot
interpolant s_run (scipy's ``make_interp_spline`` on the run: O(hᵏ⁺¹) up to the run's ends, using
no value outside it). Its knots are nodes, so s_run lies in the span of the global B-splines on
[x_a, x_b] (the global knot vector has a knot at every node of the run, at least); its coefficients
in that basis are the least-squares fit of s_run at 4 points inside each cell — exact to rounding. A
line that is kept whole is fitted as the full grid is (not-a-knot, or periodic on a periodic axis);
a run on a periodic axis may wrap round the period (a B-spline that straddles the gap between the
two ends of a run is left out: the run alone cannot determine it). Coefficients that no run
touches are NaN: the spline is NaN on every cell that needs one of them (a line there is outside
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
    NaN where no run touches a coefficient. ``full_fit(Y)`` fits whole lines (n, L') the way the
    unmasked interpolation does (same knots)."""
    n, L = y.shape
    m = t.size - k - 1
    out = np.full((m, L), np.nan)
    groups: dict[tuple[int, int], list[np.ndarray]] = defaultdict(list)
    # the runs of each distinct mask column once (a grid's lines share a few hundred patterns)
    patterns, which = np.unique(np.asarray(keep, bool).T, axis=0, return_inverse=True)
    members = np.argsort(which.ravel(), kind="stable")
    bounds = np.searchsorted(which.ravel()[members], np.arange(patterns.shape[0] + 1))
    for p, pattern in enumerate(patterns):
        for run in _runs(pattern, period is not None):
            if run[1] >= k + 1:
                groups[run].append(members[bounds[p]:bounds[p + 1]])
    for (a, length), parts in groups.items():
        cols = np.sort(np.concatenate(parts))
        if length == n:
            out[:, cols] = full_fit(y[:, cols])
            continue
        idx = (a + np.arange(length)) % n
        xr = x[idx] + (period if period is not None else 0.0) * ((a + np.arange(length)) >= n)
        s_run = make_interp_spline(xr, y[idx][:, cols], k=k, axis=0)
        # 4 points inside each cell of the run: an overdetermined exact fit, blind to the B-splines
        # that only touch the run at an end node (they vanish there: the run cannot fix them)
        P = (xr[:-1, None] + np.diff(xr)[:, None] * np.array([0.1, 0.37, 0.63, 0.9])).ravel()
        Pw = P if period is None else t[k] + np.mod(P - t[k], period)
        D = BSpline.design_matrix(Pw, t, k).toarray()
        if period is not None:  # c_{n+j} = c_j: fold the wrapped columns
            D[:, :k] += D[:, n:]
            D = D[:, :n]
        rows = np.ones(P.size, bool)
        if period is not None:
            # a B-spline that straddles a short gap of the line is nonzero at both ends of the run:
            # the run cannot fix it alone — it stays NaN, and so do the cells that need it
            nz = D != 0
            for j in np.flatnonzero(nz.any(axis=0)):
                r = np.flatnonzero(nz[:, j])
                if r[-1] - r[0] + 1 > r.size:
                    rows &= ~nz[:, j]
        touched = np.flatnonzero(np.any(D[rows] != 0, axis=0))
        c, *_ = np.linalg.lstsq(D[rows][:, touched], s_run(P[rows]), rcond=None)
        out[touched[:, None], cols[None, :]] = c
    if period is not None:
        out[n:] = out[:k]
    return out

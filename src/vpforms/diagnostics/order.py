"""Observed order: errors at time T for a step-size sweep and a plateau-aware log–log fit."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._integrate import integrate
from ._common import _points

__all__ = ["reference_solution", "step_size_errors", "OrderFit", "fit_order", "observed_order"]


def reference_solution(field: Any, x0: Any, T: float, rtol: float = 1e-13, atol: float = 1e-13) -> np.ndarray:
    """x(T) from x0 for x' = a(x), as the truth for an order study.

    Exact ``expm(T A) x0`` when ``field.linear_matrix`` is a matrix; otherwise SciPy's DOP853 on the
    stacked system (all particles at once) with tight tolerances, the field evaluated by JAX.
    """
    pts, single = _points(x0)
    A = getattr(field, "linear_matrix", None)
    if A is not None:
        from scipy.linalg import expm

        out = pts @ expm(T * np.asarray(A, dtype=np.float64)).T
    else:
        from scipy.integrate import solve_ivp

        f = jax.jit(jax.vmap(lambda p: jnp.asarray(field(p))))

        def rhs(_t, y):
            return np.asarray(f(jnp.asarray(y.reshape(-1, 3)))).reshape(-1)

        sol = solve_ivp(rhs, (0.0, T), pts.reshape(-1), method="DOP853", rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"reference solution failed: {sol.message}")
        out = sol.y[:, -1].reshape(-1, 3)
    return out[0] if single else out


def step_size_errors(method: Any, x0: Any, T: float, hs: Any, reference: Any) -> np.ndarray:
    """max over particles of |x_n − x(T)|_∞ with n = T/h, for each h in hs.

    Each T/h must be (within 1e-9) an integer. ``reference`` is x(T), shape like x0.  A failed
    particle makes that h's error ``inf``.
    """
    ref = np.asarray(reference, dtype=np.float64)
    if not (math.isfinite(T) and T > 0):
        raise ValueError(f"T must be a positive number, got {T}")
    hs = _step_sizes(hs)
    errs = []
    for h in hs:
        n = T / h
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            raise ValueError(f"T/h must be an integer; T={T}, h={h}")
        sol = integrate(method, x0, h, int(round(n)), progress=False)
        if not sol.ok:
            errs.append(np.inf)
            continue
        errs.append(float(np.max(np.abs(sol.x_final - ref))))
    return np.asarray(errs)


def _step_sizes(hs: Any) -> np.ndarray:
    """hs as a 1-D float array of positive finite step sizes (a ValueError otherwise)."""
    hs = np.asarray(hs, dtype=np.float64)
    if hs.ndim != 1 or hs.size == 0 or not np.all(np.isfinite(hs) & (hs > 0)):
        raise ValueError(f"hs must be a non-empty list of positive finite step sizes, got {hs.tolist()}")
    return hs


@dataclass(frozen=True)
class OrderFit:
    """A log–log fit err ≈ 10^log10_c · h^order over the points ``used``.

    ``hs``, ``errors`` and ``used`` (a boolean mask) are sorted by increasing h (not in the
    caller's order); ``local_slopes[i]`` is the slope between sorted points i and i + 1.
    """

    order: float
    log10_c: float
    hs: np.ndarray
    errors: np.ndarray
    used: np.ndarray
    local_slopes: np.ndarray

    def predict(self, h: Any) -> np.ndarray:
        return 10.0 ** (self.log10_c + self.order * np.log10(np.asarray(h, dtype=np.float64)))


def fit_order(hs: Any, errors: Any, floor: float | None = None, tol: float = 0.15) -> OrderFit:
    """Plateau-aware least-squares slope of log10(err) against log10(h).

    Points at or below the round-off ``floor`` (default 1e3·eps·max(1, max err)) or non-finite are
    dropped: they sit on the rounding plateau.  Among the remaining points (sorted by h) the fit uses
    the longest run of consecutive points that a straight line fits within ``tol`` decades, preferring
    the run at the smallest h on ties (the asymptotic regime).  At least two points are needed.
    """
    hs = _step_sizes(hs)
    errors = np.asarray(errors, dtype=np.float64)
    if errors.shape != hs.shape:
        raise ValueError(f"hs and errors must have the same length; got {hs.shape} and {errors.shape}")
    order_idx = np.argsort(hs)
    hs_s, er_s = hs[order_idx], errors[order_idx]
    finite = np.isfinite(er_s) & (er_s > 0)
    if floor is None:
        scale = max(1.0, float(np.max(er_s[finite]))) if finite.any() else 1.0
        floor = 1e3 * np.finfo(float).eps * scale
    ok = finite & (er_s > floor)
    idx = np.flatnonzero(ok)
    lh, le = np.log10(hs_s), np.log10(np.where(finite, er_s, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        local = np.diff(le) / np.diff(lh)
    local = np.where(finite[1:] & finite[:-1], local, np.nan)
    if idx.size < 2:
        raise ValueError("fit_order needs at least two errors above the round-off floor")

    best = None
    # runs of consecutive usable points (consecutive in the sorted sweep)
    runs, cur = [], [idx[0]]
    for i in idx[1:]:
        if i == cur[-1] + 1:
            cur.append(i)
        else:
            runs.append(cur)
            cur = [i]
    runs.append(cur)
    for run in runs:
        for a in range(len(run)):
            for b in range(a + 2, len(run) + 1):
                sel = np.array(run[a:b])
                p, c = np.polyfit(lh[sel], le[sel], 1)
                resid = np.max(np.abs(le[sel] - (p * lh[sel] + c)))
                if resid <= tol:
                    key = (len(sel), -lh[sel[0]])
                    if best is None or key > best[0]:
                        best = (key, sel, p, c)
    if best is None:  # no straight run: use the two smallest-h usable points
        sel = idx[:2]
        p, c = np.polyfit(lh[sel], le[sel], 1)
        best = (None, sel, p, c)
    _, sel, p, c = best
    used_sorted = np.zeros(hs.size, dtype=bool)
    used_sorted[sel] = True
    local_full = np.full(hs.size - 1, np.nan)
    local_full[: local.size] = local
    return OrderFit(float(p), float(c), hs_s, er_s, used_sorted, local_full)


def observed_order(method: Any, x0: Any, T: float, hs: Any, reference: Any = None, field: Any = None) -> OrderFit:
    """Errors at time T for the step sizes hs and their plateau-aware fit (:func:`fit_order`).

    ``reference`` is x(T); if omitted it is computed by :func:`reference_solution` from ``field``
    (default ``method.field``).
    """
    if reference is None:
        field = field if field is not None else getattr(method, "field", None)
        if field is None:
            raise ValueError("observed_order needs reference=x(T) or a field to compute it")
        reference = reference_solution(field, x0, T)
    errs = step_size_errors(method, x0, T, hs, reference)
    return fit_order(hs, errs)

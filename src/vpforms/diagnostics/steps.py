"""The step count from a tolerance: step doubling on a sample of lines (issue #39, item 3).

A method of order p run with n steps per period T errs at the period boundaries by
e(n) ≈ C·n⁻ᵖ; the same lines run with 2n steps err by e(n)/2ᵖ, so their difference
d = |x_n − x_{2n}| = e(n)(1 − 2⁻ᵖ) measures e(n) = d·2ᵖ/(2ᵖ − 1) (Richardson). The error per period
is the largest over the sample's lines and saved periods of e_k(n)/k (a position error that grows
along the line, at the k-th period). :func:`steps_for_tol` raises n until that estimate is ≤ tol,
each n checked by its own pair of runs, and returns a :class:`StepChoice` to report beside the
result. The estimate is of the *method's* error on the traced field; the field's own error (a
spline's interpolation error) is not in it (:func:`vpforms.grids.refine_to_tol` bounds that).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .._integrate import integrate
from .._phases import phase

__all__ = ["StepChoice", "steps_for_tol"]


@dataclass(frozen=True)
class StepChoice:
    """What :func:`steps_for_tol` chose.

    Attributes
    ----------
    tol : float
        The tolerance: the largest position error per period.
    n : int
        Steps per period.
    h : float
        The step size, period / n.
    estimate : float
        The estimated error per period with n steps.
    order : int
        The order p used in the Richardson factor 2ᵖ/(2ᵖ − 1).
    lines : int
        How many lines the estimate sampled.
    periods : int
        How many periods each was run.
    rounds : tuple of (int, float)
        Every n tried and its estimate.
    """

    tol: float
    n: int
    h: float
    estimate: float
    order: int
    lines: int
    periods: int
    rounds: tuple[tuple[int, float], ...]

    def __str__(self) -> str:
        return (f"{self.n} steps per period (h = {self.h:.4g}): estimated error {self.estimate:.2e} per period "
                f"≤ tol {self.tol:.1e} (step doubling, order {self.order}, {self.lines} lines × {self.periods} "
                f"periods; tried n = {', '.join(str(n) for n, _ in self.rounds)})")


def steps_for_tol(method: Any, x0: Any, period: float, tol: float, *, n0: int = 8, periods: int = 4,
                  to_points: Callable[[np.ndarray], np.ndarray] | None = None, order: int | None = None,
                  max_n: int = 1 << 16, backend: str = "auto") -> StepChoice:
    """The fewest steps per ``period`` whose estimated position error per period is ≤ ``tol``
    (module docstring).

    Parameters
    ----------
    method : vpforms method
        Any method (its ``order`` is p unless ``order`` is given).
    x0 : array_like
        A sample of starting points (M, 3) in the method's coordinates (a few lines of the run).
    period : float
        The time of one period (2π/nfp with φ as the time; a transit's time otherwise).
    tol : float
        The largest position error per period, in the units of ``to_points``'s output.
    n0 : int
        The first n tried.
    periods : int
        Periods each sample line is run.
    to_points : callable, optional
        Saved states (..., 3) → the points whose distance is the error (e.g. (v, φ, Z) → (R, Z, 0)
        for φ-time); default the states themselves.
    order : int, optional
        The order p (default ``method.order``).
    max_n : int
        The most steps per period: beyond it, a clear error.
    backend : str
        Passed to :func:`vpforms.integrate`.

    Returns
    -------
    StepChoice
    """
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive length per period; got {tol!r}")
    tol = float(tol)
    p = int(order if order is not None else getattr(method, "order", 0))
    if p < 1:
        raise ValueError(f"the method's order must be ≥ 1 for step doubling; got {p}")
    x0 = np.atleast_2d(np.asarray(x0, dtype=float))
    T, K = float(period), int(periods)
    if not (math.isfinite(T) and T != 0) or K < 1:
        raise ValueError(f"period must be a non-zero time and periods ≥ 1; got {period!r}, {periods!r}")
    pts = to_points or (lambda x: x)

    def run(n):
        sol = integrate(method, x0, T / n, n * K, save_every=n, progress=False, backend=backend)
        if sol.n_failed:
            raise ValueError(f"steps_for_tol: {sol.n_failed} of {len(x0)} sample lines failed with {n} steps per "
                             "period (a line leaving the field's domain?): choose sample lines inside it")
        return np.asarray(pts(np.asarray(sol.xs)))  # (M, K + 1, ...)

    factor = 2.0 ** p / (2.0 ** p - 1.0)
    n, rounds = max(1, int(n0)), []
    fine = None
    while True:
        if n > max_n:
            last = rounds[-1] if rounds else (n, float("nan"))
            raise ValueError(f"steps_for_tol: tol = {tol:g} per period needs more than max_n = {max_n} steps per "
                             f"period (n = {last[0]} gave {last[1]:.2e}); the method's order or the field's "
                             "smoothness may not be what the estimate assumes")
        with phase(f"step doubling: {n} and {2 * n} steps per period on {len(x0)} lines"):
            coarse = fine if fine is not None and fine[0] == n else (n, run(n))
            fine = (2 * n, run(2 * n))
        d = np.linalg.norm((coarse[1] - fine[1]).reshape(len(x0), K + 1, -1), axis=-1)[:, 1:]
        e = float(np.max(d / np.arange(1, K + 1)) * factor)
        rounds.append((n, e))
        if e <= tol:
            return StepChoice(tol, n, T / n, e, p, len(x0), K, tuple(rounds))
        # e ∝ n⁻ᵖ: the n that meets tol, with 10 % to spare; never less than doubling when the
        # estimate did not fall as n⁻ᵖ (pre-asymptotic)
        want = n * (e / tol) ** (1.0 / p) * 1.1
        n = int(math.ceil(want)) if len(rounds) < 2 or rounds[-2][1] / e >= 1.5 ** p else 2 * n

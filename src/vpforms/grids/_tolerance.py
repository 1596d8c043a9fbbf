"""A tolerance in, a grid out: the resolution of a spline grid chosen by an a-posteriori error
estimate (issue #39, item 1).

The user gives ``tol``, a bound on the relative error of the interpolated *field* (B = ∇×A for a
spline of A; b = ∇×C for the φ-time K) on a region — the plasma domain, never the coil wires.
:func:`refine_to_tol` builds grids until the error estimated on that region is below ``tol``:

1. build the spline on the current grid n = (n₁, n₂, n₃) and **measure** its error e against the
   exact field at seeded random points of the region (the estimate);
2. **measure each axis's share**: fit the same samples again with every other node of axis a
   dropped (no new samples) and estimate that spline's error e_a; with a share s_a ∝ h_aᵖ, doubling
   h_a gives e_a ≈ e + (2ᵖ − 1)s_a, so s_a = (e_a − e)/(2ᵖ − 1) (p = k for a field of first
   derivatives of a degree-k spline; k + 1 along an axis the field does not differentiate along,
   the φ of the φ-time K). Measured, not modelled: a model of the shares from the samples' own
   (k+1)-th differences put the l = 2 stellarator's error in φ when it was in R and Z (three rounds
   refined φ for nothing);
3. give each axis a third of the target t = tol/√3 (the geometric middle of [tol/3, tol]):
   h_a ← h_a (t / (3 s_a))^{1/p} (at most 4× finer, at least 0.75× as fine per round; never coarser
   while e > tol). Node counts stay odd on open axes and even on periodic ones, so that every other
   node is again a grid with the same ends;
4. repeat until tol/3 ≤ e ≤ tol (or e ≤ tol when a coarser grid no longer reaches tol), at most
   ``max_rounds`` builds; the grid is never refined past ``max_memory`` (a clear error says what
   the tolerance would need).

The result carries a :class:`GridChoice`: the tolerance, the grid, the estimate, the memory of its
coefficients, and every round (grid, estimate, seconds) — reported, never hidden.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import jax
import numpy as np

from .._phases import phase

__all__ = ["GridChoice", "GridRound", "TOL_FLOOR", "check_tol", "refine_to_tol", "spline_nbytes"]

#: below this relative field error the interpolant's own rounding (coefficients of size ~1, sums of
#: (k+1)³ terms, a derivative divided by h) is of the same size: float64 cannot be asked for it
TOL_FLOOR = 1e-12

#: the default memory budget of one grid's coefficients (bytes)
DEFAULT_MAX_MEMORY = 4 * 2**30


@dataclass(frozen=True)
class GridRound:
    """One round of :func:`refine_to_tol`: its grid, the estimated error, the seconds of the round
    (with the three coarser fits that measure the axes' shares), the bytes of its coefficients and
    the seconds of its build alone (samples, fit, estimate)."""

    grid: tuple[int, int, int]
    estimate: float
    seconds: float
    memory: int
    build_seconds: float = 0.0


@dataclass(frozen=True)
class GridChoice:
    """What :func:`refine_to_tol` chose, and why.

    Attributes
    ----------
    tol : float
        The tolerance asked for (relative field error on the region).
    degree : int
        The spline degree per axis.
    grid : tuple of int
        The chosen node counts per axis.
    estimate : float
        The estimated error of the chosen grid (max relative error at ``n_check`` points).
    n_check : int
        How many seeded random points of the region the estimate uses.
    memory : int
        Bytes of the chosen grid's spline coefficients.
    seconds : float
        Seconds of all builds and estimates together.
    rounds : tuple of GridRound
        Every build, in order.
    region : str
        Where the error was estimated.
    """

    tol: float
    degree: int
    grid: tuple[int, int, int]
    estimate: float
    n_check: int
    memory: int
    seconds: float
    rounds: tuple[GridRound, ...] = field(default_factory=tuple)
    region: str = ""

    def __str__(self) -> str:
        g = "×".join(map(str, self.grid))
        return (f"tol {self.tol:.1e}: degree-{self.degree} grid {g}, estimated error {self.estimate:.2e} "
                f"at {self.n_check} points of {self.region or 'the region'}, {self.memory / 2**20:.1f} MiB, "
                f"{len(self.rounds)} build(s) in {self.seconds:.1f} s")

    def table(self) -> str:
        """The rounds as a Markdown table."""
        rows = ["| round | grid | estimated error | memory (MiB) | build (s) | round, with the axes' shares (s) |",
                "|---:|---|---:|---:|---:|---:|"]
        for i, r in enumerate(self.rounds):
            rows.append(f"| {i + 1} | {'×'.join(map(str, r.grid))} | {r.estimate:.2e} | "
                        f"{r.memory / 2**20:.1f} | {r.build_seconds:.1f} | {r.seconds:.1f} |")
        return "\n".join(rows)


def spline_nbytes(pot: Any) -> int:
    """Bytes of the arrays of a :class:`~vpforms.grids.SplinePotential`'s three splines (knots,
    cell polynomials, coefficients; its antiderivatives, built when a method needs them, add about
    as much again per pair)."""
    return int(sum(np.asarray(leaf).nbytes for s in pot.splines for leaf in jax.tree_util.tree_leaves(s)))


def check_tol(tol: Any, what: str = "tol") -> float:
    """``tol`` as a float, or a ValueError: it must be a finite number in [TOL_FLOOR, 1)."""
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.floating, np.integer)):
        raise ValueError(f"{what} must be a number (a relative field error); got {tol!r}")
    tol = float(tol)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"{what} must be a positive relative field error; got {tol!r}")
    if tol < TOL_FLOOR:
        raise ValueError(f"{what} = {tol:g} is below what float64 interpolation can reach (≈ {TOL_FLOOR:g} "
                         "relative: the rounding of the spline's own sums); ask for ≥ {TOL_FLOOR:g}")
    if tol >= 1:
        raise ValueError(f"{what} = {tol:g} is not a relative error (< 1)")
    return tol


def _every_other(n: int, periodic: bool) -> slice | None:
    """The nodes of the grid twice as coarse along an axis of n nodes (same ends), or None."""
    if periodic:
        return slice(0, None, 2) if n % 2 == 0 else None
    return slice(0, None, 2) if n % 2 == 1 else None


def _count(x: float, periodic: bool, least: int) -> int:
    """A node count ≥ least near x: even on a periodic axis, odd on an open one."""
    n = max(int(math.ceil(x)), least)
    return n + (n % 2 if periodic else 1 - n % 2)


def refine_to_tol(sample: Callable[[tuple[int, int, int]], Any],
                  fit: Callable[[Any, tuple[slice, slice, slice]], Any],
                  estimate: Callable[[Any], float], start: Sequence[int], *, degree: int, tol: float,
                  periodic: Sequence[bool], memory: Callable[[Any], int], orders: Sequence[int] | None = None,
                  max_memory: float = DEFAULT_MAX_MEMORY, max_rounds: int = 6, n_check: int = 0,
                  region: str = "", what: str = "grid") -> tuple[Any, GridChoice]:
    """Refine a spline grid until its estimated field error is ≤ ``tol`` (module docstring).

    Parameters
    ----------
    sample : callable
        grid (n₁, n₂, n₃) → the samples on that grid (any object ``fit`` takes).
    fit : callable
        (samples, (s₁, s₂, s₃)) → the spline fitted on the sub-grid of the slices sᵢ of the nodes
        (``slice(None)``: all; ``slice(0, None, 2)``: every other node).
    estimate : callable
        spline → its relative field error on the region (max over seeded points).
    start : sequence of int
        The first grid (rounded to odd / even node counts).
    degree : int
        The spline degree k.
    tol : float
        The tolerance (:func:`check_tol`).
    periodic : sequence of bool
        Which axes are periodic (node count = intervals).
    memory : callable
        spline → bytes of its coefficients (the budget is checked on the prediction before a build).
    orders : sequence of int, optional
        The order of the field's error along each axis (default k on every axis).
    max_memory : float
        Budget in bytes for one grid.
    max_rounds : int
        The most builds.
    n_check : int
        Points of the estimate (for the report).
    region : str
        Where the error is estimated (for the report).
    what : str
        A name for messages.

    Returns
    -------
    (spline, GridChoice)
    """
    tol = check_tol(tol)
    k = int(degree)
    p = tuple(int(o) for o in (orders if orders is not None else (k, k, k)))
    lo = tuple(k if periodic[a] else k + 1 for a in range(3))
    # the every-other-node grid must still hold a spline: 2·least (− 1) nodes
    least = tuple(2 * m if periodic[a] else 2 * m - 1 for a, m in enumerate(lo))
    n = tuple(_count(g, periodic[a], least[a]) for a, g in enumerate(start))
    t_all = time.perf_counter()
    rounds: list[GridRound] = []
    best: tuple[Any, GridRound] | None = None  # the coarsest grid that met tol
    bytes_per_node = None
    target = tol / math.sqrt(3.0)
    full = (slice(None),) * 3
    for r in range(int(max_rounds)):
        nodes = int(np.prod(n))
        if bytes_per_node is not None and nodes * bytes_per_node > max_memory:
            need = nodes * bytes_per_node
            if best is not None:
                break
            raise MemoryError(
                f"{what}: tol = {tol:g} needs about a {'×'.join(map(str, n))} grid "
                f"({need / 2**30:.2f} GiB of coefficients; the last grid reached {rounds[-1].estimate:.2e}), "
                f"over the budget max_memory = {max_memory / 2**30:.2f} GiB: raise max_memory, a higher degree, "
                "or a larger tol")
        t = time.perf_counter()
        with phase(f"round {r + 1}: the {'×'.join(map(str, n))} {what}"):
            data = sample(n)
            obj = fit(data, full)
            e = float(estimate(obj))
        t_build = time.perf_counter() - t
        mem = int(memory(obj))
        bytes_per_node = mem / nodes
        if not math.isfinite(e):
            raise ValueError(f"{what}: the {'×'.join(map(str, n))} grid's error estimate is {e} (NaN "
                             "or infinite samples in the region?)")
        if e <= tol and (best is None or nodes < int(np.prod(best[1].grid))):
            best = (obj, GridRound(n, e, time.perf_counter() - t, mem, t_build))
        done = (tol / 3 <= e <= tol) or (e > tol and best is not None) or r == int(max_rounds) - 1
        if done:
            rounds.append(GridRound(n, e, time.perf_counter() - t, mem, t_build))
            break
        # each axis's share, from the same samples fitted with every other node of that axis
        share = np.zeros(3)
        with phase(f"round {r + 1}: each axis's share of the error (three coarser fits)"):
            for a in range(3):
                sub = _every_other(n[a], periodic[a])
                if sub is None:  # _count keeps the parity that makes it exist; never guess a share
                    raise AssertionError(f"{what}: {n[a]} nodes on axis {a} have no every-other-node sub-grid")
                e_a = float(estimate(fit(data, tuple(sub if b == a else slice(None) for b in range(3)))))
                share[a] = max(e_a - e, 0.0) / (2.0 ** p[a] - 1.0) if math.isfinite(e_a) else e
        rounds.append(GridRound(n, e, time.perf_counter() - t, mem, t_build))
        if share.sum() <= 0:  # coarser along every axis is no worse: the error is not the grid's
            if e <= tol:
                break
            share[:] = e / 3
        share *= e / max(share.sum(), e)  # the shares do not add up to more than the error
        grow = [min(4.0, max(0.75, (3 * max(sh, 1e-300) / target) ** (1.0 / pa))) for sh, pa in zip(share, p)]
        if e > tol:  # never coarsen an axis while the error is above tol
            grow = [max(1.0, g) for g in grow]
        new = tuple(_count(g * (c if periodic[a] else c - 1) + (0 if periodic[a] else 1), periodic[a], least[a])
                    for a, (g, c) in enumerate(zip(grow, n)))
        if new == n:
            if e > tol:  # the shares ask for nothing more: refine the largest by itself
                a = int(np.argmax(share))
                new = tuple(_count(c * 1.25, periodic[b], least[b]) if b == a else c for b, c in enumerate(n))
            else:
                break
        n = new
    if best is None:
        last = rounds[-1]
        raise ValueError(f"{what}: tol = {tol:g} not reached in {len(rounds)} builds (the last, "
                         f"{'×'.join(map(str, last.grid))}, estimated {last.estimate:.2e}); raise max_rounds "
                         "or tol")
    obj, rnd = best
    choice = GridChoice(tol, k, rnd.grid, rnd.estimate, int(n_check), rnd.memory, time.perf_counter() - t_all,
                        tuple(rounds), region)
    return obj, choice

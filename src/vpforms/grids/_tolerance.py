"""A tolerance in, a grid out: the resolution of a spline grid chosen by an a-posteriori error
estimate (issue #39, item 1).

The user gives ``tol``, a bound on the relative error of the interpolated *field* (B = ∇×A for a
spline of A; b = ∇×C for the φ-time K) on a region — the plasma domain, never the coil wires.
:func:`refine_to_tol` builds grids until the error estimated on that region is below ``tol``:

1. build the spline on the current grid n = (n₁, n₂, n₃) and **measure** its error e against the
   exact field at seeded random points of the region (the estimate);
2. read, from the samples themselves, how much each axis contributes: along axis a the
   (k+1)-th differences of the node values are Δ_aᵏ⁺¹f ≈ h_aᵏ⁺¹ ∂_aᵏ⁺¹f, and the error of the first
   derivatives of a degree-k interpolant (the field) is O(h_aᵏ ∂_aᵏ⁺¹f), so
   I_a = max |Δ_aᵏ⁺¹f| / h_a over the nodes near the region is axis a's term, up to a constant;
3. **calibrate** e ≈ κ Σ_a I_a (κ from the measured e) and give each axis a third of the target
   t = tol/√3 (the geometric middle of [tol/3, tol]): h_a ← h_a (t / (3 κ I_a))^{1/k};
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

import numpy as np

from .._phases import phase

__all__ = ["GridChoice", "GridRound", "TOL_FLOOR", "axis_indicators", "check_tol", "refine_to_tol", "spline_nbytes"]

#: below this relative field error the interpolant's own rounding (coefficients of size ~1, sums of
#: (k+1)³ terms, a derivative divided by h) is of the same size: float64 cannot be asked for it
TOL_FLOOR = 1e-12

#: the default memory budget of one grid's coefficients (bytes)
DEFAULT_MAX_MEMORY = 4 * 2**30


@dataclass(frozen=True)
class GridRound:
    """One build of :func:`refine_to_tol`: its grid, the estimated error and the seconds it took."""

    grid: tuple[int, int, int]
    estimate: float
    seconds: float
    memory: int


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
        rows = ["| round | grid | estimated error | memory (MiB) | seconds |", "|---:|---|---:|---:|---:|"]
        for i, r in enumerate(self.rounds):
            rows.append(f"| {i + 1} | {'×'.join(map(str, r.grid))} | {r.estimate:.2e} | "
                        f"{r.memory / 2**20:.1f} | {r.seconds:.1f} |")
        return "\n".join(rows)


def spline_nbytes(pot: Any) -> int:
    """Bytes of the arrays of a :class:`~vpforms.grids.SplinePotential`'s three splines (knots,
    cell polynomials, coefficients; its antiderivatives, built when a method needs them, add about
    as much again per pair)."""
    import jax

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


def axis_indicators(samples: Any, spacings: Sequence[float], degree: int, periodic: Sequence[bool],
                    where: Any = None, derivatives: Sequence[int] = (0, 1, 2)) -> tuple[np.ndarray, np.ndarray]:
    """Each axis's share of the error of a field made of first derivatives of a degree-k
    interpolant of ``samples`` (shape (C, n₁, n₂, n₃); NaN at nodes not sampled), and the order of
    that share (module docstring): the field holds ∂_d of the samples for d in ``derivatives``.

    * axis a among them: the error of ∂_a is O(h_aᵏ ∂_aᵏ⁺¹f): I_a = max |Δ_aᵏ⁺¹f| / h_a, order k;
    * axis a not among them (the φ of the φ-time K: b = (−∂_ZK, 1, ∂_vK)): interpolating along a
      errs by O(h_aᵏ⁺¹ ∂_aᵏ⁺¹f) and ∂_d of that is the field's error: I_a = max_d |Δ_aᵏ⁺¹Δ_d f| / h_d,
      order k + 1.

    Maxima over the components and the nodes of ``where`` (bool (n₁, n₂, n₃), default all); h =
    ``spacings`` in units that make Δ_d f / h_d the field's components. Periodic axes wrap.
    Returns (I, orders), each of shape (3,)."""
    s = np.asarray(samples, dtype=float)
    if s.ndim == 3:
        s = s[None]
    k1 = int(degree) + 1
    w = None if where is None else np.broadcast_to(np.asarray(where, bool), s.shape[1:])

    def diff(d, a, n):  # n-th forward differences along axis a (wrapped where periodic), same shape
        if periodic[a]:
            for _ in range(n):
                d = np.roll(d, -1, axis=a + 1) - d
            return d
        out = np.full(d.shape, np.nan)
        if d.shape[a + 1] > n:
            idx = [slice(None)] * d.ndim
            idx[a + 1] = slice(0, d.shape[a + 1] - n)
            out[tuple(idx)] = np.diff(d, n=n, axis=a + 1)
        return out

    def peak(m):
        if w is not None:
            m = np.where(w[None], m, np.nan)
        m = np.abs(m)
        return float(np.nanmax(m)) if np.any(np.isfinite(m)) else 0.0

    I, orders = np.zeros(3), np.zeros(3, int)
    for a in range(3):
        if not periodic[a] and s.shape[a + 1] <= k1:
            I[a], orders[a] = np.inf, k1 - 1  # too few nodes to see the (k+1)-th derivative: refine
            continue
        if a in derivatives:
            I[a], orders[a] = peak(diff(s, a, k1)) / float(spacings[a]), k1 - 1
        else:
            I[a] = max(peak(diff(diff(s, d, 1), a, k1)) / float(spacings[d]) for d in derivatives)
            orders[a] = k1
    return I, orders


def refine_to_tol(build: Callable[[tuple[int, int, int]], tuple[Any, Any, Any]],
                  estimate: Callable[[Any], float], start: Sequence[int], *, degree: int, tol: float,
                  spacings: Callable[[tuple[int, int, int]], Sequence[float]], periodic: Sequence[bool],
                  memory: Callable[[Any], int], derivatives: Sequence[int] = (0, 1, 2), max_memory: float = DEFAULT_MAX_MEMORY,
                  max_rounds: int = 6, n_check: int = 0, region: str = "", what: str = "grid",
                  ) -> tuple[Any, GridChoice]:
    """Refine a spline grid until its estimated field error is ≤ ``tol`` (module docstring).

    Parameters
    ----------
    build : callable
        grid (n₁, n₂, n₃) → (object, samples (C, n₁, n₂, n₃), where (bool (n₁, n₂, n₃) or None)):
        the spline built on that grid, its node samples and the nodes near the region.
    estimate : callable
        object → its relative field error on the region (max over seeded points).
    start : sequence of int
        The first grid.
    degree : int
        The spline degree (the field error is O(hᵏ)).
    tol : float
        The tolerance (:func:`check_tol`).
    spacings : callable
        grid → the node spacing per axis in physical units (φ as arclength).
    periodic : sequence of bool
        Which axes are periodic (node count = intervals).
    derivatives : sequence of int
        The axes along which the field differentiates the samples (:func:`axis_indicators`).
    memory : callable
        object → bytes of its coefficients (the budget is checked on the prediction before a build).
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
    (object, GridChoice)
    """
    tol = check_tol(tol)
    k = int(degree)
    lo = tuple(k if periodic[a] else k + 1 for a in range(3))
    n = tuple(max(int(g), m) for g, m in zip(start, lo))
    t_all = time.perf_counter()
    rounds: list[GridRound] = []
    best: tuple[Any, GridRound] | None = None  # the coarsest grid that met tol
    bytes_per_node = None
    target = tol / math.sqrt(3.0)
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
            obj, samples, where = build(n)
            e = float(estimate(obj))
        mem = int(memory(obj))
        bytes_per_node = mem / nodes
        rounds.append(GridRound(n, e, time.perf_counter() - t, mem))
        if not math.isfinite(e):
            raise ValueError(f"{what}: the {'×'.join(map(str, n))} grid's error estimate is {e} (NaN "
                             "or infinite samples in the region?)")
        if e <= tol and (best is None or nodes < int(np.prod(best[1].grid))):
            best = (obj, rounds[-1])
        if tol / 3 <= e <= tol:
            break
        if e > tol and best is not None:
            break  # a coarser try missed tol after a finer one met it: keep the finer one
        I, orders = axis_indicators(samples, spacings(n), k, periodic, where, derivatives)
        if not np.all(np.isfinite(I)):
            grow = [2.0 if not np.isfinite(v) else 1.0 for v in I]
        else:
            total = float(np.sum(I))
            if total <= 0:  # the samples are polynomial of degree ≤ k: the grid is exact already
                break
            kappa = e / total
            share = np.maximum(I * kappa, 1e-300)
            grow = [min(4.0, max(0.5, (3 * sh / target) ** (1 / p))) for sh, p in zip(share, orders)]
            if e > tol:  # never coarsen an axis while the error is above tol
                grow = [max(1.0, g) for g in grow]
        new = tuple(max(m, int(math.ceil(g * (c if periodic[a] else c - 1))) + (0 if periodic[a] else 1))
                    for a, (g, c, m) in enumerate(zip(grow, n, lo)))
        if new == n:
            if e > tol:  # the model asks for nothing more: refine the worst axis by itself
                a = int(np.argmax(I)) if np.all(np.isfinite(I)) else 0
                new = tuple(c + max(1, c // 4) if i == a else c for i, c in enumerate(n))
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

"""Section crossings recorded by the native kernel (``vp_sections``, :mod:`.codegen.sections`).

:func:`run_events` advances points natively as :func:`.runner.run_points` does (the same steps, the
same lazy JAX recovery of failed steps) and returns, instead of saved states, the steps at which a
line crossed a section surface: (line, step n, state before, state after). Only those steps are
refined afterwards (:mod:`vpforms.diagnostics.poincare`), so a section costs little more than the
trace.

Overflow is never silent: the kernel returns how many crossings it found; when that exceeds the
buffers, the segment is run again from its starting states with buffers that large (``reruns``
counts these). A step recovered through JAX is checked for a crossing here, by the caller's
``crossed`` (the JAX surface's own test).

:func:`locate` solves the recorded crossings on the step family natively (``vp_locate``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .runner import CALLS, kernel_for, run_with_events

__all__ = ["Crossings", "Events", "locate", "run_events"]


class Events:
    """The crossing buffers of one run, filled segment by segment (see :func:`run_events`)."""

    def __init__(self, surface: tuple[int, int, float, float], direction: int,
                 crossed: Callable[[np.ndarray, np.ndarray], np.ndarray], capacity: int):
        self.surface, self.direction, self.crossed = surface, int(direction), crossed
        self.reruns = 0
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._alloc(max(1, int(capacity)))

    def _alloc(self, cap: int) -> None:
        self.line, self.step = np.empty(cap, np.int64), np.empty(cap, np.int64)
        self.states = np.empty((cap, 6))

    def advance(self, kernel, x, status, n, n_target, h) -> None:
        """One kernel call to n_target, recording crossings; on overflow, the call again from the same
        states with buffers that hold them all."""
        x0, s0, n0 = x.copy(), status.copy(), n.copy()
        while True:
            count = kernel.sections(x, status, n, n_target, h, self.surface, self.direction,
                                    self.line, self.step, self.states)
            if count <= self.line.size:
                self._keep(self.line[:count], self.step[:count], self.states[:count])
                return
            self.reruns += 1
            x[:], status[:], n[:] = x0, s0, n0
            self._alloc(2 * count)  # room for the next segments too

    def recovered(self, idx: np.ndarray, n: np.ndarray, x: np.ndarray, X: np.ndarray) -> None:
        """Steps n → n+1 of lines ``idx`` taken through JAX (from x to X): their crossings."""
        k = np.asarray(self.crossed(x, X), bool)
        if k.any():
            self._keep(idx[k], n[k], np.concatenate([x[k], X[k]], axis=1), True)

    def stopped(self, idx: np.ndarray) -> np.ndarray:
        """Which of the lines ``idx`` the kernel stopped without a failure: none (sections stop no line)."""
        return np.zeros(idx.size, bool)

    def _keep(self, line, step, states, recovered=False) -> None:
        self._parts.append((line.copy(), step.copy(), states.copy(), np.full(line.size, recovered)))

    def collected(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(line (M,), step (M,), states (M, 6), recovered (M,): a JAX-recovered step) of every
        crossing so far, in no particular order."""
        if not self._parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 6)), np.zeros(0, bool)
        return tuple(np.concatenate(p) for p in zip(*self._parts))  # type: ignore[return-value]


@dataclass(frozen=True)
class Crossings:
    """What :func:`run_events` returns: the crossings sorted by (line, step) — line, step, the
    states before and after the step, whether the step was recovered through JAX — and per line the
    final status and recovered-step count, the recovered steps by kind (``how``), the final states,
    and the overflow re-runs."""

    line: np.ndarray
    step: np.ndarray
    before: np.ndarray
    after: np.ndarray
    recovered_step: np.ndarray
    status: np.ndarray
    recovered: np.ndarray
    how: dict
    x: np.ndarray
    reruns: int


def run_events(method: Any, pts: np.ndarray, h: float, n_steps: int, surface: tuple[int, int, float, float],
               direction: int, crossed: Callable[[np.ndarray, np.ndarray], np.ndarray],
               progress_cb: Callable[[int], Any] | None = None, capacity: int | None = None,
               engine: str = "auto", calls: int = CALLS) -> Crossings:
    """Advance points (N, 3) natively for n_steps steps of h, recording the crossings of ``surface``
    = (kind, axis, value, period) of :mod:`.codegen.sections` in ``direction``; ``crossed(x, X)``
    (M,) says which JAX-recovered steps cross. ``capacity``: the first buffers (default 4N + 1024
    crossings per call; they grow on overflow). At most ``calls`` kernel calls (the progress bar's
    granularity), each followed by the JAX recovery of the steps that failed in it."""
    kernel = kernel_for(method, engine, "sections")
    N = pts.shape[0]
    events = Events(surface, direction, crossed, 4 * N + 1024 if capacity is None else capacity)
    x, status, _, recovered, how = run_with_events(kernel, method, pts, h, n_steps, events, progress_cb, calls)
    line, step, states, rec = events.collected()
    order = np.lexsort((step, line))
    return Crossings(line=line[order], step=step[order], before=states[order, :3], after=states[order, 3:],
                     recovered_step=rec[order], status=status, recovered=recovered, how=how, x=x, reruns=events.reruns)


def locate(method: Any, h: float, surface: tuple[int, int, float, float], x: np.ndarray, X: np.ndarray,
           level: np.ndarray, engine: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The crossings of the levels ``level`` (M,) in the steps x → X (M, 3), located natively on the
    bare step family θ ↦ Ψ_{θh}(x), Ψ_h(x) = X (``vp_locate``: the Illinois regula falsi of
    :func:`vpforms.diagnostics._locate.illinois`): (points (M, 3), θ (M,), undecided (M,) — an
    evaluation failed there: locate those with the JAX locator)."""
    kernel = kernel_for(method, engine, "sections")
    f = kernel._ffi
    x, X = (np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3) for a in (x, X))
    level = np.ascontiguousarray(level, dtype=np.float64)
    M = x.shape[0]
    Y, theta, undecided = np.empty((M, 3)), np.empty(M), np.empty(M, np.int32)
    kernel.lib.lib.vp_locate(M, f.cast("double *", x.ctypes.data), f.cast("double *", X.ctypes.data),
                             f.cast("double *", level.ctypes.data),
                             float(h), int(surface[0]), int(surface[1]), f.cast("double *", Y.ctypes.data),
                             f.cast("double *", theta.ctypes.data), f.cast("int32_t *", undecided.ctypes.data),
                             kernel._fd())
    return Y, theta, undecided.astype(bool)

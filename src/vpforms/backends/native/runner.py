"""Run a generated native kernel: save blocks, freezing, JAX recovery of failed steps, Solution.

:func:`run_points` is the low-level entry (no argument checks: a NaN initial condition gives the
``nonfinite`` status); :func:`integrate_native` is what :func:`vpforms.integrate` dispatches to.

Recovery: the kernel is built for ``method.without_recovery()``; a particle whose native step
fails stops at that step, and :func:`vpforms.backends._advance.advance_with_recovery` — the splice
the JAX backend uses too — takes that one step with the recovering method
(:func:`vpforms._recovery.recover_points`); on success the particle goes on natively from the next
step (``recovered`` counts these steps); otherwise, and always for a bare method, it stays frozen
with the bare status.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..._errors import RESULTS
from ..._progress import _Bar, _is_terminal
from ..._solution import make_solution, saved_steps
from .._advance import advance_with_recovery, failed_steps, start_state
from .build import build
from .codegen import kernel_parts
from .codegen.entries import ENTRIES, entries_cdef

__all__ = ["NativeKernel", "integrate_native", "run_points", "run_saving"]

#: kernel calls per run at most (the progress bar's granularity; each call costs ~10 µs + a thread wake-up)
CALLS = 20


class NativeKernel:
    """The compiled ``vp_run`` of one method (built on first use, cached on disk) and the field's
    run-time data ``fd`` (a spline's knots and coefficients; None without: NULL is passed), so
    that a new grid of the same structure reuses the compiled kernel; with ``entry="sections"``
    its ``vp_sections`` and ``vp_locate`` instead (:mod:`.codegen.sections`, :meth:`sections`), with
    ``entry="wall"`` its ``vp_wall`` (:mod:`.codegen.walls`, :mod:`.walls`)."""

    def __init__(self, method: Any, engine: str = "auto", entry: str = "run"):
        self.method = method
        self.source, self.data = kernel_parts(method, engine, entry)
        # the entries the source defines (one object for all of them where the stages are called)
        self.lib = build(self.source, entries_cdef(self.source))
        from cffi import FFI

        self._ffi = FFI()

    def advance(self, x: np.ndarray, status: np.ndarray, n: np.ndarray, n_target: int, h: float,
                save_every: int = 0, n_total: int = 0, xs: np.ndarray | None = None, recovered=None):
        """In place: every live particle with n < n_target steps until n_target or its failure
        (the contract of :mod:`vpforms.backends._advance`; ``recovered`` is not touched: the C step
        never recovers, the splice does).

        With ``save_every`` > 0 the kernel also writes the saved states into ``xs`` (N, S, 3),
        C-contiguous: slot j the state after step j·save_every, the last slot after ``n_total``
        (a frozen particle's later slots: its frozen state)."""
        f = self._ffi
        if save_every > 0:
            assert xs is not None and xs.flags.c_contiguous and xs.shape[0] == x.shape[0]
            out, n_saves = f.cast("double *", xs.ctypes.data), xs.shape[1] - 1
        else:
            out, n_saves = f.NULL, 0
        self.lib.lib.vp_run(
            x.shape[0],
            f.cast("double *", x.ctypes.data),
            f.cast("int32_t *", status.ctypes.data),
            f.cast("int64_t *", n.ctypes.data),
            int(n_target), float(h), int(save_every), int(n_total), out, int(n_saves),
            self._fd(),
        )

    def _fd(self):
        """The field's run-time data for the kernel (``const double *fd``; NULL without)."""
        f = self._ffi
        return f.NULL if self.data is None else f.cast("double *", self.data.ctypes.data)

    def sections(self, x: np.ndarray, status: np.ndarray, n: np.ndarray, n_target: int, h: float,
                 surface: tuple[int, int, float, float], direction: int, line: np.ndarray,
                 step: np.ndarray, states: np.ndarray) -> int:
        """:meth:`advance` (no saves), recording the crossings of ``surface`` = (kind, axis, value,
        period) into line (C,), step (C,), states (C, 6) (before, after the step): returns the number
        of crossings, which exceeds C = ``line.size`` when the buffers overflowed (then re-run from
        the same states with buffers that large)."""
        f = self._ffi
        kind, axis, value, period = surface
        return int(self.lib.lib.vp_sections(
            x.shape[0],
            f.cast("double *", x.ctypes.data),
            f.cast("int32_t *", status.ctypes.data),
            f.cast("int64_t *", n.ctypes.data),
            int(n_target), float(h), int(kind), int(axis), float(value), float(period), int(direction),
            int(line.size),
            f.cast("int64_t *", line.ctypes.data),
            f.cast("int64_t *", step.ctypes.data),
            f.cast("double *", states.ctypes.data),
            self._fd(),
        ))


_kernels: dict[tuple[int, str, str], tuple[Any, NativeKernel]] = {}
def kernel_for(method: Any, engine: str = "auto", entry: str = "run") -> NativeKernel:
    """The kernel of ``method`` with ``entry``, made once per method object; a kernel made for
    another entry serves where its object holds this one too (:mod:`.codegen.entries`)."""
    hit = _kernels.get((id(method), engine, entry))
    if hit is None or hit[0] is not method:
        mark = ENTRIES[entry][0]
        other = next((k for (i, e, _), (m, k) in _kernels.items()
                      if i == id(method) and e == engine and m is method and mark in k.source), None)
        hit = (method, other if other is not None else NativeKernel(method, engine, entry))
        _kernels[(id(method), engine, entry)] = hit
    return hit[1]


def run_with_events(kernel, method, pts, h, n_steps, events, progress_cb=None, calls=CALLS):
    """Advance points (N, 3) natively for n_steps steps of h with ``events`` (the section crossings
    of :class:`.events.Events`, the wall of :class:`.walls.WallRun`) in at most ``calls`` kernel
    calls (the progress bar's granularity), each followed by the JAX recovery of the steps that
    failed in it; stops early once no line is live. Returns (x, status, n, recovered, how)."""
    N = pts.shape[0]
    x, status, n, recovered = start_state(pts)
    how: dict[str, int] = {}
    ends = np.unique(np.linspace(0, n_steps, min(n_steps, calls) + 1).astype(np.int64))[1:]
    done = 0
    for end in ends:
        advance_with_recovery(kernel, method, x, status, n, recovered, int(end), h, how, events=events)
        if progress_cb is not None:
            progress_cb(N * int(end - done))
        done = int(end)
        if not np.any(status == RESULTS.successful):  # every line stopped
            if progress_cb is not None:
                progress_cb(N * int(n_steps - done))
            break
    return x, status, n, recovered, how


#: one particle's state, (3,) float64, as one item: copying rows of 24 bytes, not 3 doubles each
_ROW = np.dtype((np.void, 24))


def _put(xs: np.ndarray, j: int, x: np.ndarray) -> None:
    """``xs[:, j] = x`` for xs (N, S, 3) and x (N, 3), both C-contiguous float64: the same bytes,
    copied a particle at a time (half the time of NumPy's 3-wide inner loop at N = 10⁵)."""
    xs.view(_ROW)[:, j, 0] = x.view(_ROW)[:, 0]


def run_points(method, pts, h, steps, progress_cb=None, engine="auto", save=None, how=None):
    """Advance points (N, 3) natively and return (xs (N, S, 3), status, failed_step, recovered).

    ``steps`` are the target step indices (increasing, first 0); ``save`` (bool per target,
    default all) says which are kept in xs — memory is N·S·24 bytes for S saved states.
    No argument checks.  ``how`` (a dict) collects the recovered steps by kind.
    """
    how = {} if how is None else how
    save = np.ones(len(steps), bool) if save is None else np.asarray(save, bool)
    kernel = kernel_for(method, engine)
    N = pts.shape[0]
    x, status, n, recovered = start_state(pts)
    slot = np.cumsum(save) - 1
    xs = np.empty((N, int(save.sum()), 3))
    if save[0]:
        _put(xs, 0, x)
    for j in range(1, len(steps)):
        advance_with_recovery(kernel, method, x, status, n, recovered, int(steps[j]), h, how)
        if save[j]:
            _put(xs, int(slot[j]), x)
        if progress_cb is not None:
            progress_cb(N * int(steps[j] - steps[j - 1]))
    return xs, status, failed_steps(status, n), recovered


def run_saving(method, pts, h, n_steps, save_every, progress_cb=None, engine="auto", how=None, calls=CALLS):
    """Like :func:`run_points` for the saves of ``save_every`` (steps 0, k, 2k, …, n_steps), but the
    kernel writes the saved states itself: at most ``calls`` kernel calls (the progress bar's
    granularity) whatever the number of saves, so saving every step costs no call per save."""
    how = {} if how is None else how
    kernel = kernel_for(method, engine)
    steps = saved_steps(n_steps, save_every)
    N, S = pts.shape[0], steps.size
    x, status, n, recovered = start_state(pts)
    xs = np.empty((N, S, 3))
    _put(xs, 0, x)
    # segment ends at saved steps, ≤ `calls` of them (the last is n_steps)
    ends = np.unique(steps[np.linspace(0, S - 1, min(S - 1, calls) + 1).astype(np.int64)][1:])
    done = 0
    for end in ends:
        advance_with_recovery(kernel, method, x, status, n, recovered, int(end), h, how,
                               saving=(int(save_every), int(n_steps), xs))
        if progress_cb is not None:
            progress_cb(N * int(end - done))
        done = int(end)
    return xs, status, failed_steps(status, n), recovered


def integrate_native(method, pts, single, h, n_steps, save_every, t0, progress, reason):
    """The native counterpart of the JAX loop in :func:`vpforms.integrate` (same Solution)."""
    steps = saved_steps(n_steps, save_every)
    N = pts.shape[0]
    bar = _Bar(progress, N * n_steps, "integrating (native)")
    # ≤ CALLS kernel calls are for a progress bar; where none can show, one call (each call loads
    # and stores every lane: 20 calls cost 2× the kernel on 10⁵ particles × 40 steps)
    calls = CALLS if progress is True or (progress == "auto" and _is_terminal()) else 1
    t_wall = time.perf_counter()
    try:
        how: dict[str, int] = {}
        if save_every is not None and n_steps > 0:
            xs, status, failed, recovered = run_saving(method, pts, h, n_steps, int(save_every), bar.update, how=how,
                                                       calls=calls)
        else:
            # without saving, intermediate targets only for the progress bar (≤ calls), not saved
            if calls == 1:
                targets, keep = steps, None  # = the saved steps, 0 and n_steps: all kept
            else:
                targets = np.unique(np.linspace(0, n_steps, min(n_steps, calls) + 1).astype(np.int64))
                keep = np.isin(targets, steps)
            xs, status, failed, recovered = run_points(method, pts, h, targets, bar.update, save=keep, how=how)
    finally:
        bar.close()
    stats = dict(wall_s=time.perf_counter() - t_wall, chunk_size=N, n_chunks=1 if N else 0, backend="native",
                 backend_reason=reason)
    return make_solution(method, single, h, n_steps, save_every, t0, steps, xs, status, failed, recovered,
                         stats, how)

"""Particle tracing: ``jit`` + ``lax.scan`` over steps, ``vmap`` over particles, chunks over particles.

:func:`integrate` advances one point (shape (3,)) or a cloud of particles (shape (N, 3)) by
``n_steps`` steps of a one-step method and returns a :class:`Solution`.  It needs only

    method.step_with_status(x, h) -> (X, status)      # x of shape (3,), status a RESULTS code

so any vpforms method (``vpforms.scheme``, ``vpforms.compose``), the :class:`RK4` baseline here, or a
user object with that method works.  Contract:

* **Memory is bounded.** Particles are processed in chunks of ``chunk_size`` (all chunks padded to
  the same size, so one compilation serves every chunk); inside a chunk the steps run in segments
  of a fixed number of save-blocks, so the device holds one segment of saved states at a time and
  the host holds only the saved states requested by ``save_every``.
* **A failed particle is frozen, never NaN.** When a step returns a non-zero status for a particle,
  that particle keeps its last good state for the rest of the run; ``Solution.status`` holds the
  first failure code and ``Solution.failed_step`` the index n of the step t_n → t_{n+1} that failed
  (−1 for particles that never failed).
* **Chunking does not change results.** Every particle's trajectory is the same sequence of
  ``step_with_status`` calls whatever the chunk size (see ``tests/test_integrate.py``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from . import _config  # noqa: F401  (float64)
from ._errors import RESULTS, raise_for_status

__all__ = ["integrate", "Solution", "RK4", "describe", "auto_chunk_size"]

#: Default device-memory budget (bytes) for the saved states of one chunk and one segment.
_SEGMENT_BYTES = 64 * 2**20
#: Largest chunk chosen automatically: big enough to amortise dispatch, small enough for cache.
_MAX_AUTO_CHUNK = 2**13


def describe(method: Any) -> str:
    """A one-line human description of a method: its ``description``, else name, case and order."""
    d = getattr(method, "description", None)
    if isinstance(d, str) and d:
        return d
    name = getattr(method, "name", None)
    if isinstance(name, str) and name:
        parts = [name]
        case = getattr(method, "case", None)
        if case is not None:
            parts.append(f"case {case}")
        cls = getattr(method, "cls", None)
        if isinstance(cls, str) and cls not in name:
            parts.append(f"class {cls}")
        order = getattr(method, "order", None)
        if order is not None:
            parts.append(f"order {order}")
        return ", ".join(parts)
    return repr(method)


# --------------------------------------------------------------------------------------------
# The baseline every comparison uses: classical explicit RK4 (not volume preserving).
# --------------------------------------------------------------------------------------------
class RK4:
    """Classical fourth-order Runge–Kutta for x' = a(x): the usual baseline (not volume preserving).

    ``field`` is any callable x (3,) -> a(x) (3,) in JAX, e.g. a :class:`vpforms.Field`.  It has the
    method interface that :func:`integrate` and the diagnostics need: ``step``,
    ``step_with_status`` (status is ``nonfinite`` when the result is not finite), ``order = 4``.
    """

    order = 4
    symmetric = False

    def __init__(self, field: Callable[[jax.Array], jax.Array]):
        self.field = field
        self.description = f"RK4 (classical, explicit) on {getattr(field, 'name', 'field')}"

    def step(self, x: Any, h: Any) -> jax.Array:
        a = self.field
        x = jnp.asarray(x, dtype=jnp.result_type(float))
        if x.ndim == 2:
            return jax.vmap(lambda p: self.step(p, h))(x)
        k1 = a(x)
        k2 = a(x + 0.5 * h * k1)
        k3 = a(x + 0.5 * h * k2)
        k4 = a(x + h * k3)
        return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def step_with_status(self, x: Any, h: Any):
        X = self.step(x, h)
        bad = ~jnp.all(jnp.isfinite(X), axis=-1)
        return X, jnp.where(bad, RESULTS.nonfinite, RESULTS.successful).astype(jnp.int32)

    def __repr__(self) -> str:
        return f"RK4({getattr(self.field, 'name', self.field)!s})"


# --------------------------------------------------------------------------------------------
# Solution
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Solution:
    """The result of :func:`integrate` (NumPy arrays on the host).

    Attributes
    ----------
    ts:
        Saved times, shape (S,): ``t0 + h * steps``.
    steps:
        Saved step indices, shape (S,): 0, k, 2k, …, and always ``n_steps`` last (k = save_every).
    xs:
        Saved states, shape (S, 3) for a single x0 of shape (3,), else (N, S, 3).
    status:
        Per-particle ``RESULTS`` code of the first failure (0 = every step succeeded); shape () or (N,).
    failed_step:
        Index n of the step t_n → t_{n+1} at which the particle failed, −1 if it never failed.  A
        failed particle stays frozen at its state at step n.
    method:
        The method's description.
    h, n_steps, save_every, t0:
        The run's parameters.
    stats:
        ``wall_s`` (excluding nothing: compile included), ``n_chunks``, ``chunk_size``,
        ``ns_per_particle_step``.
    """

    ts: np.ndarray
    steps: np.ndarray
    xs: np.ndarray
    status: np.ndarray
    failed_step: np.ndarray
    method: str
    h: float
    n_steps: int
    save_every: int | None
    t0: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def x_final(self) -> np.ndarray:
        """The final state(s): shape (3,) or (N, 3)."""
        return self.xs[..., -1, :]

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.status != RESULTS.successful))

    @property
    def ok(self) -> bool:
        return self.n_failed == 0

    def raise_for_status(self) -> None:
        """Raise the named :class:`vpforms.VPFormsError` if any particle failed."""
        raise_for_status(self.status, what=f"integrate({self.method})")

    def summary(self) -> dict[str, Any]:
        """A flat dictionary for printing: counts, times, failures by code."""
        st = np.atleast_1d(self.status)
        fails = {
            RESULTS.messages[int(c)]: int(np.count_nonzero(st == c))
            for c in np.unique(st)
            if c != RESULTS.successful
        }
        return {
            "method": self.method,
            "particles": int(st.size),
            "h": self.h,
            "steps": self.n_steps,
            "t_final": float(self.ts[-1]),
            "saved states": int(self.ts.size),
            "failed particles": int(np.count_nonzero(st != RESULTS.successful)),
            **({"failures": fails} if fails else {}),
            **self.stats,
        }

    def save(self, path: str) -> None:
        """Write an ``.npz`` with ts, steps, xs, status, failed_step and the run parameters."""
        np.savez_compressed(
            path,
            ts=self.ts,
            steps=self.steps,
            xs=self.xs,
            status=self.status,
            failed_step=self.failed_step,
            method=np.array(self.method),
            h=np.array(self.h),
            n_steps=np.array(self.n_steps),
            save_every=np.array(-1 if self.save_every is None else self.save_every),
            t0=np.array(self.t0),
        )


# --------------------------------------------------------------------------------------------
# The kernel
# --------------------------------------------------------------------------------------------
def _advance(step_with_status, x, status, failed, n, h, n_stop):
    """One step for one particle with freezing; a no-op once n ≥ n_stop (a padded step)."""

    def do(args):
        x, status, failed = args
        X, st = step_with_status(x, h)
        st = jnp.asarray(st, dtype=jnp.int32)
        # a non-finite result reported as a success (a user method) is a failure too: never NaN
        st = jnp.where((st == RESULTS.successful) & ~jnp.all(jnp.isfinite(X)), RESULTS.nonfinite, st)
        alive = status == RESULTS.successful
        good = alive & (st == RESULTS.successful)
        x = jnp.where(good, X, x)  # a failed step leaves the particle where it was: frozen
        newly = alive & (st != RESULTS.successful)
        return x, jnp.where(newly, st, status), jnp.where(newly, n, failed).astype(failed.dtype)

    return lax.cond(n < n_stop, do, lambda a: a, (x, status, failed))


@partial(jax.jit, static_argnums=(0, 1, 2))
def _segment_kernel(step_with_status, save_every, n_blocks, x, status, failed, n0, h, n_stop):
    """Run n_blocks blocks of save_every steps from step n0 (steps ≥ n_stop are skipped).

    Shapes: x (C, 3), status/failed (C,).  Returns the new carry and the states after each block,
    (C, n_blocks, 3).  One particle's trajectory is a scan over steps, vmapped over particles.
    """

    def one_particle(x, status, failed):
        def block(carry, b):
            def step(c, j):
                x, st, fl = c
                n = n0 + b * save_every + j
                # steps past n_stop (the overshoot of the last segment) are skipped by a cond on
                # the unbatched step index: no work is done for them
                return _advance(step_with_status, x, st, fl, n, h, n_stop), None

            carry, _ = lax.scan(step, carry, jnp.arange(save_every))
            return carry, carry[0]

        carry, saved = lax.scan(block, (x, status, failed), jnp.arange(n_blocks))
        return carry, saved

    (x, status, failed), saved = jax.vmap(one_particle)(x, status, failed)
    return x, status, failed, saved


def auto_chunk_size(n_particles: int, n_saves: int = 2) -> int:
    """A chunk size that keeps one chunk's saved states and work arrays around ≤ 64 MiB."""
    per_particle = 8 * 3 * max(n_saves, 16) + 512
    c = max(1, min(n_particles, _MAX_AUTO_CHUNK, _SEGMENT_BYTES // per_particle))
    return int(c)


class _StepFn:
    """``method.step_with_status`` as a static jit argument, hashed by the method's identity."""

    __slots__ = ("method",)

    def __init__(self, method: Any):
        self.method = method

    def __call__(self, x, h):
        return self.method.step_with_status(x, h)

    def __hash__(self) -> int:
        return id(self.method)

    def __eq__(self, other) -> bool:
        return isinstance(other, _StepFn) and other.method is self.method


def _is_terminal() -> bool:
    """Whether rich would animate a bar here (not in pipes, logs or captured test output)."""
    from rich.console import Console

    return Console(stderr=True).is_terminal


class _Bar:
    """A rich progress bar that appears only for runs expected to take more than ~1 s."""

    def __init__(self, mode: bool | str, total: int, label: str):
        self.mode, self.total, self.label = mode, total, label
        self.done = 0
        self.t_start = time.perf_counter()
        self.progress = None
        self.task = None

    def _start(self):
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        from rich.console import Console

        self.progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("particle-steps"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            transient=True,
            console=Console(stderr=True),
        )
        self.progress.start()
        self.task = self.progress.add_task(self.label, total=self.total, completed=self.done)

    def update(self, k: int):
        self.done += k
        if self.mode is False:
            return
        if self.progress is None:
            elapsed = time.perf_counter() - self.t_start
            frac = self.done / max(self.total, 1)
            expected = elapsed / max(frac, 1e-12)
            if self.mode is True or (
                elapsed > 0.25 and expected > 1.0 and frac < 0.9 and _is_terminal()
            ):
                self._start()
        if self.progress is not None:
            self.progress.update(self.task, completed=self.done)

    def close(self):
        if self.progress is not None:
            self.progress.stop()


def _check_run(method: Any, x0: Any, h: Any, n_steps: Any, t0: Any = 0.0) -> tuple[np.ndarray, bool, float, int]:
    """Validate the arguments every run shares; return (points (N, 3), single, h, n_steps).

    A bad argument is a named error here, never a NaN or a silently failed run later.
    """
    if not hasattr(method, "step_with_status"):
        raise TypeError("method must have step_with_status(x, h) -> (X, status)")
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.ndim not in (1, 2) or x0.shape[-1] != 3:
        raise ValueError(f"x0 must have shape (3,) or (N, 3); got {x0.shape}")
    if not np.all(np.isfinite(x0)):
        raise ValueError("x0 contains NaN or infinite values")
    if isinstance(n_steps, bool) or int(n_steps) != n_steps:
        raise ValueError(f"n_steps must be an integer, got {n_steps!r}")
    n_steps = int(n_steps)
    if n_steps < 0:
        raise ValueError(f"n_steps must be ≥ 0, got {n_steps}")
    h = float(h)
    if not math.isfinite(h) or h == 0.0:
        raise ValueError(f"h must be a finite non-zero number, got {h}")
    if not math.isfinite(float(t0)):
        raise ValueError(f"t0 must be a finite number, got {t0}")
    return x0.reshape(-1, 3), x0.ndim == 1, h, n_steps


def integrate(
    method: Any,
    x0: Any,
    h: float,
    n_steps: int,
    save_every: int | None = None,
    t0: float = 0.0,
    chunk_size: int | None = None,
    progress: bool | str = "auto",
    segment_blocks: int | None = None,
) -> Solution:
    """Advance x0 by ``n_steps`` steps of size h with ``method``; return a :class:`Solution`.

    Parameters
    ----------
    method:
        Anything with ``step_with_status(x, h) -> (X, status)`` for x of shape (3,) (jit- and
        vmap-compatible, h possibly traced).
    x0:
        Shape (3,) (one trajectory) or (N, 3) (N particles).
    h, n_steps:
        Step size (may be negative: backward in time) and number of steps (≥ 0).
    save_every:
        Save every k-th state: steps 0, k, 2k, … and always the last.  ``None`` saves only the
        initial and final states (the memory-light choice for large N).
    t0:
        Initial time (the fields are autonomous; ``ts = t0 + h * steps``).
    chunk_size:
        Particles per compiled call; ``None`` chooses one from a 64 MiB budget (≤ 8192).
    progress:
        ``True`` / ``False`` / ``"auto"``: a rich bar on stderr; ``"auto"`` shows it on a terminal
        when the run is expected to take more than ~1 s.
    segment_blocks:
        Save-blocks per compiled call inside a chunk (the progress granularity); ``None`` = auto.
    """
    pts, single, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    N = pts.shape[0]
    if save_every is None:
        # only x0 and the final state are kept: fixed blocks (32 steps, 8 per call) so that every
        # n_steps (e.g. a step-size sweep) reuses one compilation
        steps = np.array([0, n_steps]) if n_steps else np.array([0])
        k, L = 32, 8
        n_blocks = -(-n_steps // k)
    else:
        k = int(save_every)
        if k < 1:
            raise ValueError(f"save_every must be ≥ 1, got {save_every}")
        n_blocks = -(-n_steps // k)  # ceil: the last block may be partial (extra steps skipped)
        steps = np.minimum(np.arange(n_blocks + 1) * k, n_steps)
    S = steps.size

    C = auto_chunk_size(N, S) if chunk_size is None else int(chunk_size)
    if C < 1:
        raise ValueError(f"chunk_size must be ≥ 1, got {chunk_size}")
    C = min(C, N) if N > 0 else 1
    n_chunks = -(-N // C) if N else 0
    if segment_blocks is not None:
        L = int(segment_blocks)
    elif save_every is not None:
        # ≤ 64 MiB of saved states per call, and ≥ ~20 calls per chunk for a live progress bar
        cap = max(1, _SEGMENT_BYTES // (24 * C))
        L = max(1, min(cap, -(-n_blocks // 20) if n_blocks else 1))
    n_segments = -(-n_blocks // L)

    xs = np.empty((N, S, 3))
    status = np.zeros(N, dtype=np.int32)
    failed = np.full(N, -1, dtype=np.int64)
    xs[:, 0] = pts
    step_fn = _StepFn(method)
    kernel = partial(_segment_kernel, step_fn, k, L)
    hj = jnp.asarray(h)
    stop = jnp.asarray(n_steps)  # steps n ≥ n_steps of an overshooting segment are skipped

    bar = _Bar(progress, N * n_steps, "integrating")
    t_wall = time.perf_counter()
    try:
        for c in range(n_chunks):
            lo, hi = c * C, min((c + 1) * C, N)
            block = pts[lo:hi]
            if hi - lo < C:  # pad the last chunk so that it reuses the compiled kernel
                block = np.concatenate([block, np.repeat(block[-1:], C - (hi - lo), axis=0)])
            x = jnp.asarray(block)
            st = jnp.zeros(C, dtype=jnp.int32)
            fl = jnp.full(C, -1, dtype=jnp.int32)
            for s in range(n_segments):
                n0 = s * L * k
                x, st, fl, saved = kernel(x, st, fl, jnp.asarray(n0), hj, stop)
                x.block_until_ready()  # dispatch is asynchronous: sync so the bar tracks real work
                if save_every is not None:
                    b_lo = s * L
                    b_hi = min(b_lo + L, n_blocks)
                    xs[lo:hi, 1 + b_lo : 1 + b_hi] = np.asarray(saved)[: hi - lo, : b_hi - b_lo]
                bar.update((hi - lo) * (min(n0 + L * k, n_steps) - n0))
            if save_every is None and n_steps:
                xs[lo:hi, -1] = np.asarray(x)[: hi - lo]
            status[lo:hi] = np.asarray(st)[: hi - lo]
            failed[lo:hi] = np.asarray(fl)[: hi - lo]
    finally:
        bar.close()
    wall = time.perf_counter() - t_wall

    stats = {
        "wall_s": wall,
        "chunk_size": C,
        "n_chunks": n_chunks,
        "ns_per_particle_step": (1e9 * wall / (N * n_steps)) if N * n_steps else float("nan"),
    }
    ts = t0 + h * steps.astype(np.float64)
    if single:
        return Solution(ts, steps, xs[0], status[0], failed[0], describe(method), h, n_steps, save_every, t0, stats)
    return Solution(ts, steps, xs, status, failed, describe(method), h, n_steps, save_every, t0, stats)


"""The JAX backend of :func:`vpforms.integrate`: ``jit`` + ``lax.scan`` over steps, the method's
batched step over a chunk of particles, chunks over particles; recovery of failed bare steps on the
host (:mod:`vpforms._recovery`). The peer of :mod:`vpforms.backends.native.runner`: both take the
checked points and return the same :class:`~vpforms.Solution` (:func:`vpforms._solution.make_solution`).

* **Memory is bounded.** Particles are processed in chunks of ``chunk_size`` (all chunks padded to
  the same size, so one compilation serves every chunk); inside a chunk the steps run in segments
  of a fixed number of save-blocks, so the device holds one segment of saved states at a time and
  the host holds only the saved states requested by ``save_every``.
* **A failed particle is frozen, never NaN** (its last good state, the first failure code and the
  index of the step that failed).
* **Chunking does not change results.** Every particle's trajectory is the same sequence of
  ``step_with_status`` calls whatever the chunk size.
"""

from __future__ import annotations

import time
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .. import _config  # noqa: F401  (float64)
from .._errors import RESULTS
from .._progress import _Bar
from .._recovery import bare_method
from .._solution import make_solution, saved_steps
from ._advance import advance_with_recovery, failed_steps, start_state

__all__ = ["JaxKernel", "auto_chunk_size", "integrate_jax"]

#: Default device-memory budget (bytes) for the saved states of one chunk and one segment.
_SEGMENT_BYTES = 64 * 2**20
#: Largest chunk chosen automatically: big enough to amortise dispatch, small enough for cache.
_MAX_AUTO_CHUNK = 2**13


# --------------------------------------------------------------------------------------------
# The kernel
# --------------------------------------------------------------------------------------------
@partial(jax.jit, static_argnums=(0, 1, 2))
def _segment_kernel(step_with_status, save_every, n_blocks, x, status, failed, n0, h, n_stop,
                    recovered=None, start=None):
    """Run n_blocks blocks of save_every steps from step n0 (steps ≥ n_stop are skipped).

    Shapes: x (C, 3), status/failed/recovered/start (C,); a particle takes steps n ≥ start only.  Returns the new carry and the states after
    each block, (C, n_blocks, 3).  The scan over steps is outside, the step is the method's BATCHED
    step on the whole chunk (so a recovering method decides recovery once per chunk, issue #12).
    """
    if recovered is None:
        recovered = jnp.zeros_like(status)
    if start is None:  # per-particle first step (a particle resumed after a recovered step)
        start = jnp.zeros_like(status)
    with_rec = hasattr(step_with_status, "with_recovery")

    def advance(c, n):
        def do(c):
            x, status, failed, rec = c
            if with_rec:
                X, st, r = step_with_status.with_recovery(x, h)
            else:
                # a user method's contract is one point (3,): vmap it as before
                X, st = jax.vmap(step_with_status, in_axes=(0, None))(x, h)
                r = jnp.zeros_like(status)
            st = jnp.asarray(st, dtype=jnp.int32)
            # a non-finite result reported as a success (a user method) is a failure too: never NaN
            st = jnp.where((st == RESULTS.successful) & ~jnp.all(jnp.isfinite(X), axis=-1),
                           RESULTS.nonfinite, st)
            alive = (status == RESULTS.successful) & (n >= start)
            good = alive & (st == RESULTS.successful)
            x = jnp.where(good[:, None], X, x)  # a failed step leaves the particle where it was
            newly = alive & (st != RESULTS.successful)
            rec = rec + (good & (jnp.asarray(r) > 0)).astype(rec.dtype)
            return (x, jnp.where(newly, st, status),
                    jnp.where(newly, n, failed).astype(failed.dtype), rec)

        # a batch whose lanes are all frozen skips its remaining steps (they would be masked out:
        # the same numbers), e.g. the few particles resumed after a recovered step, failing again
        return lax.cond((n < n_stop) & jnp.any(c[1] == RESULTS.successful), do, lambda a: a, c)

    def block(carry, b):
        def step(c, j):
            return advance(c, n0 + b * save_every + j), None

        carry, _ = lax.scan(step, carry, jnp.arange(save_every))
        return carry, carry[0]

    (x, status, failed, recovered), saved = lax.scan(
        block, (x, status, failed, recovered), jnp.arange(n_blocks))
    return x, status, failed, saved.transpose(1, 0, 2), recovered


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

    def __getattr__(self, item):  # step_with_recovery where the method has it (issue #12)
        if item == "with_recovery" and hasattr(self.method, "step_with_recovery"):
            return self.method.step_with_recovery
        raise AttributeError(item)

    def __hash__(self) -> int:
        return id(self.method)

    def __eq__(self, other) -> bool:
        return isinstance(other, _StepFn) and other.method is self.method




class JaxKernel:
    """The JAX peer of :class:`vpforms.backends.native.runner.NativeKernel`: the same in-place
    :meth:`advance` (the contract of :mod:`vpforms.backends._advance`), by :func:`_segment_kernel`
    on batches of particles.

    A batch is a fixed chunk of ``chunk`` particles by index (the last one padded with copies of
    its last particle, so one compilation serves every batch; frozen members ride along, masked)
    or, for particles resumed after a recovered step while the others are already at the target,
    ``small`` of those alone: a second compiled shape, so that resuming a few particles does not
    cost a whole chunk. Each kernel call runs ``blocks`` save-blocks of ``k``
    steps from a multiple of k; a particle takes only its own steps n ≥ its n (``start``)."""

    def __init__(self, method: Any, chunk: int, k: int, blocks: int, small: int = 64):
        self.step = _StepFn(method)
        self.chunk, self.k, self.blocks = int(chunk), int(k), int(blocks)
        self.small = min(int(small), self.chunk)
        self._kernel = partial(_segment_kernel, self.step, self.k, self.blocks)

    def advance(self, x: np.ndarray, status: np.ndarray, n: np.ndarray, n_target: int, h: float,
                save_every: int = 0, n_total: int = 0, xs: np.ndarray | None = None, recovered=None):
        """In place: every live particle with n < n_target steps until n_target or its failure.

        With ``save_every`` > 0 (it must equal ``k``) the states after steps j·k are written into
        slot j of ``xs`` (N, S, 3), the state after ``n_total`` into the last slot; a frozen
        particle's later slots get its frozen state. ``recovered`` counts the steps that a user
        method's own ``step_with_recovery`` recovered."""
        need = (status == RESULTS.successful) & (n < n_target)
        live = np.flatnonzero(need)
        if live.size == 0:
            return
        if save_every:
            assert save_every == self.k and xs is not None
        rec = np.zeros(n.shape, np.int64) if recovered is None else recovered
        if live.size < np.count_nonzero(status == RESULTS.successful):
            # particles resumed after a recovered step (the others already at n_target): batches
            # of `small` of them alone
            for lo in range(0, live.size, self.small):
                idx = live[lo:lo + self.small]
                self._batch(idx, self.small, 0, x, status, n, rec, n_target, h, save_every, n_total, xs)
            return
        # the fixed chunks [cC, (c+1)C): a particle's batch never depends on which others failed
        # (the steps of a batch are vectorised: its frozen members ride along, masked)
        for lo in range(0, need.size, self.chunk):
            if need[lo:lo + self.chunk].any():
                idx = np.arange(lo, min(lo + self.chunk, need.size))
                self._batch(idx, self.chunk, idx.size - 1, x, status, n, rec, n_target, h, save_every,
                            n_total, xs)

    def _batch(self, idx, B, fill, x, status, n, rec, n_target, h, save_every, n_total, xs):
        """One batch of B lanes: the particles idx, padded with copies of idx[fill]."""
        if idx[-1] - idx[0] == idx.size - 1:  # a range (a fixed chunk): views, no gather
            idx = slice(int(idx[0]), int(idx[-1]) + 1)
        x_i, st0, n_i = x[idx], status[idx], n[idx]
        size = st0.size

        def padded(a):
            return a if size == B else np.concatenate([a, np.repeat(a[fill:fill + 1], B - size, axis=0)])

        xb, stb = jnp.asarray(padded(x_i)), jnp.asarray(padded(st0), dtype=jnp.int32)
        flb, rcb = jnp.full(B, -1, jnp.int32), jnp.zeros(B, jnp.int32)
        go = st0 == RESULTS.successful
        startb = jnp.asarray(padded(n_i), dtype=jnp.int32)
        hj, stop = jnp.asarray(h), jnp.asarray(n_target)
        n0 = int(n_i[go & (n_i < n_target)].min()) // self.k * self.k
        if save_every:  # the rows whose saves this batch writes: its live particles
            rows = np.arange(idx.start, idx.stop) if isinstance(idx, slice) else idx
            every = bool(go.all())
            rows, n_go = (rows, n_i) if every else (rows[go], n_i[go])
        while n0 < n_target:
            xb, stb, flb, saved, rcb = self._kernel(xb, stb, flb, jnp.asarray(n0), hj, stop, rcb, startb)
            if save_every:
                sv = np.asarray(saved)[:size]
                self._save(xs, rows, n_go, sv if every else sv[go], n0, n_target, n_total)
            n0 += self.k * self.blocks
        stb, flb = np.asarray(stb)[:size], np.asarray(flb)[:size]
        x[idx] = np.asarray(xb)[:size]
        status[idx] = stb
        n[idx] = np.where(~go, n_i, np.where(stb == RESULTS.successful, np.maximum(n_i, n_target), flb))
        rec[idx] += np.asarray(rcb)[:size]

    def _save(self, xs, idx, n_i, saved, n0, n_target, n_total):
        """The block states of one kernel call into their slots: block b ends at step e = n0 +
        (b + 1)k (slot e/k), or at n_target where the call's last block was cut there (the last
        slot when n_target = n_total); only blocks ending after a particle's own start."""
        k, S = self.k, xs.shape[1]
        full = max(0, min(saved.shape[1], (n_target - n0) // k))  # blocks ending at e ≤ n_target
        if full:
            e = n0 + k * np.arange(1, full + 1)
            s0 = n0 // k + 1  # their slots s0 … s0 + full − 1
            new = n_i[:, None] < e[None, :]
            if new.all() and idx[-1] - idx[0] == idx.size - 1:  # the common case: one slice
                xs[idx[0]:idx[-1] + 1, s0:s0 + full] = saved[:, :full]
            else:
                r, c = np.nonzero(new)
                xs[idx[r], s0 + c] = saved[r, c]
        cut = n0 + (full + 1) * k  # the next block ends past n_target: its state is that at n_target
        if full < saved.shape[1] and n_target == n_total and n_total % k and cut - k < n_target:
            new = n_i < n_target
            xs[idx[new], S - 1] = saved[new, full]


def _fill_frozen(xs, steps, status, n, x):
    """The saved slots after a frozen particle's failed step n hold its frozen state (as on the
    native backend): the kernel wrote those of the call it failed in, not of later calls."""
    dead = np.flatnonzero(status != RESULTS.successful)
    if dead.size:
        r, c = np.nonzero(steps[None, :] > n[dead][:, None])
        xs[dead[r], c] = x[dead[r]]


def integrate_jax(method: Any, pts: np.ndarray, single: bool, h: float, n_steps: int,
                  save_every: int | None, t0: float, chunk_size: int | None, progress: Any,
                  segment_blocks: int | None, backend_reason: str):
    """The JAX counterpart of :func:`vpforms.backends.native.runner.integrate_native`: the same
    arguments (checked by :func:`vpforms.integrate`), the same :class:`~vpforms.Solution`, the same
    recovery splice (:func:`vpforms.backends._advance.advance_with_recovery`)."""
    N = pts.shape[0]
    steps = saved_steps(n_steps, save_every)
    # save_every None: only x0 and the final state are kept; fixed blocks (32 steps, 8 per call)
    # so that every n_steps (e.g. a step-size sweep) reuses one compilation
    k, L = (32, 8) if save_every is None else (int(save_every), 1)
    n_blocks = -(-n_steps // k)  # ceil: the last block may be partial (extra steps skipped)
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

    xs = np.empty((N, S, 3))
    xs[:, 0] = pts
    x, status, n, recovered = start_state(pts)
    # recovery runs lazily, on the host, where a bare step failed
    kernel = JaxKernel(bare_method(method), C, k, L)
    how: dict[str, int] = {}
    saving = (k, n_steps, xs) if save_every is not None else None
    ends = [min(e, n_steps) for e in range(L * k, n_steps + L * k, L * k)] if n_steps else []

    bar = _Bar(progress, N * n_steps, "integrating")
    t_wall = time.perf_counter()
    try:
        done = 0
        for end in ends:
            advance_with_recovery(kernel, method, x, status, n, recovered, end, h, how, saving=saving)
            bar.update(N * (end - done))
            done = end
    finally:
        bar.close()
    wall = time.perf_counter() - t_wall
    if save_every is None and n_steps:
        xs[:, -1] = x
    else:
        _fill_frozen(xs, steps, status, n, x)

    stats = dict(wall_s=wall, chunk_size=C, n_chunks=n_chunks, backend="jax", backend_reason=backend_reason)
    return make_solution(method, single, h, n_steps, save_every, t0, steps, xs, status,
                         failed_steps(status, n), recovered, stats, how)

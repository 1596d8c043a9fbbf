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
from .._recovery import bare_method, count_how, recover_points
from .._solution import make_solution, saved_steps

__all__ = ["auto_chunk_size", "integrate_jax"]

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

        return lax.cond(n < n_stop, do, lambda a: a, c)

    def block(carry, b):
        def step(c, j):
            return advance(c, n0 + b * save_every + j), None

        carry, _ = lax.scan(step, carry, jnp.arange(save_every))
        return carry, carry[0]

    (x, status, failed, recovered), saved = lax.scan(
        block, (x, status, failed, recovered), jnp.arange(n_blocks))
    return x, status, failed, saved.transpose(1, 0, 2), recovered


def _recover_segment(method, block_kernel, C, n_real, k, L, n0, h, stop, st_before, x, st, fl, saved,
                     rc, how):
    """Recover the bare steps that failed in this segment and resume those particles (issue #12).

    A particle whose bare step n failed is frozen at its state before step n: take step n with
    the recovering method there (:func:`vpforms._recovery.recover_points`), then run the rest of
    the segment for the re-simulated particles alone, one save-block at a time (so a particle
    that fails again costs one block, not the segment), overwriting their saved states from the
    block holding step n on.  Particles no alternative can step stay frozen with the bare status.
    """
    st_np = np.asarray(st)
    fresh = np.flatnonzero((np.asarray(st_before) == RESULTS.successful) & (st_np != RESULTS.successful))
    fresh = fresh[fresh < n_real]  # not the copies that pad the last chunk
    if fresh.size == 0:
        return x, st, fl, saved, rc
    x, st, fl, saved, rc = (np.array(a) for a in (x, st, fl, saved, rc))
    blk = (fl[fresh] - n0) // k
    start = np.zeros(st.shape, np.int64)
    R = min(C, 64)  # re-simulated particles per call (one more compiled shape of the bare kernel)
    members = np.empty(0, np.int64)

    def run_block(idx, nb):
        for lo in range(0, idx.size, R):
            part = idx[lo:lo + R]
            pad = np.concatenate([np.arange(part.size), np.zeros(R - part.size, np.int64)])
            out = block_kernel(jnp.asarray(x[part][pad]), jnp.zeros(R, jnp.int32),
                               jnp.full(R, -1, jnp.int32), jnp.asarray(nb), h, stop,
                               jnp.zeros(R, jnp.int32), jnp.asarray(start[part][pad], dtype=jnp.int32))
            x[part], st[part], fl[part] = (np.asarray(o)[: part.size] for o in out[:3])

    for b in range(int(blk.min()), L):
        nb = n0 + b * k
        if nb >= int(stop):
            break
        members = np.concatenate([members, fresh[blk == b]])
        run = members[st[members] == RESULTS.successful]
        start[run] = nb
        pending = members[st[members] != RESULTS.successful]
        while True:
            if pending.size:  # take the failed step with the recovering method
                X, s2, code = recover_points(method, x[pending], float(h))
                count_how(code, how)
                ok = s2 == RESULTS.successful
                good, dead = pending[ok], pending[~ok]
                saved[dead, b:] = x[dead][:, None]  # frozen for good, with the bare status and step
                members = np.setdiff1d(members, dead)
                x[good], rc[good], start[good] = X[ok], rc[good] + 1, fl[good] + 1
                st[good], fl[good] = RESULTS.successful, -1
                run = np.concatenate([run, good])
            if run.size == 0:
                break
            run_block(run, nb)
            pending, run = run[st[run] != RESULTS.successful], np.empty(0, np.int64)
        saved[members, b] = x[members]
    return tuple(jnp.asarray(a) for a in (x, st, fl, saved, rc))


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




def integrate_jax(method: Any, pts: np.ndarray, single: bool, h: float, n_steps: int,
                  save_every: int | None, t0: float, chunk_size: int | None, progress: Any,
                  segment_blocks: int | None, backend_reason: str):
    """The JAX counterpart of :func:`vpforms.backends.native.runner.integrate_native`: the same
    arguments (checked by :func:`vpforms.integrate`), the same :class:`~vpforms.Solution`."""
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
    n_segments = -(-n_blocks // L)

    xs = np.empty((N, S, 3))
    status = np.zeros(N, dtype=np.int32)
    failed = np.full(N, -1, dtype=np.int64)
    recovered = np.zeros(N, dtype=np.int64)
    xs[:, 0] = pts
    bare = bare_method(method)  # recovery runs lazily, on the host, where a bare step failed
    kernel = partial(_segment_kernel, _StepFn(bare), k, L)
    block_kernel = partial(_segment_kernel, _StepFn(bare), k, 1)  # re-simulation after a recovery
    recovered_how: dict[str, int] = {}
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
            rc = jnp.zeros(C, dtype=jnp.int32)
            for s in range(n_segments):
                n0 = s * L * k
                st_before = st
                x, st, fl, saved, rc = kernel(x, st, fl, jnp.asarray(n0), hj, stop, rc)
                x.block_until_ready()  # dispatch is asynchronous: sync so the bar tracks real work
                if bare is not method:
                    x, st, fl, saved, rc = _recover_segment(
                        method, block_kernel, C, hi - lo, k, L, n0, hj, stop, st_before, x, st, fl, saved, rc, recovered_how)
                if save_every is not None:
                    b_lo = s * L
                    b_hi = min(b_lo + L, n_blocks)
                    xs[lo:hi, 1 + b_lo : 1 + b_hi] = np.asarray(saved)[: hi - lo, : b_hi - b_lo]
                bar.update((hi - lo) * (min(n0 + L * k, n_steps) - n0))
            if save_every is None and n_steps:
                xs[lo:hi, -1] = np.asarray(x)[: hi - lo]
            status[lo:hi] = np.asarray(st)[: hi - lo]
            failed[lo:hi] = np.asarray(fl)[: hi - lo]
            recovered[lo:hi] = np.asarray(rc)[: hi - lo]
    finally:
        bar.close()
    wall = time.perf_counter() - t_wall

    stats = dict(wall_s=wall, chunk_size=C, n_chunks=n_chunks, backend="jax", backend_reason=backend_reason)
    return make_solution(method, single, h, n_steps, save_every, t0, steps, xs, status, failed, recovered,
                         stats, recovered_how)



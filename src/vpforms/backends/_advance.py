"""The one recovery splice of :func:`vpforms.integrate`, shared by the JAX and native backends (issue #19).

Both backends expose the same in-place *advance* (``kernel.advance(x, status, n, n_target, h,
save_every, n_total, xs)``: :class:`vpforms.backends.native.runner.NativeKernel`,
:class:`vpforms.backends.jax_runner.JaxKernel`): every live particle with n < n_target takes bare
steps until n_target or its first failure, which leaves it at its state before the failed step
with the failure's status and n = the failed step's index. :func:`advance_with_recovery` drives
either: it advances, takes each newly failed step with the recovering method on the host
(:func:`vpforms._recovery.recover_points`: the same alternatives in the same order as
``method.step_with_recovery``) and, where an alternative succeeded, goes on with the bare kernel
from the next step — until no live particle is short of n_target. So a run recovers the same
steps, the same way, whichever backend advances it.
"""

from __future__ import annotations

import numpy as np

from .._errors import RESULTS
from .._recovery import bare_method, count_how, recover_points

__all__ = ["advance_with_recovery", "failed_steps", "start_state"]


def start_state(pts: np.ndarray):
    """The runner's state at step 0: a C-contiguous copy of the points, statuses, step counts,
    recovered-step counts (what ``kernel.advance`` and :func:`advance_with_recovery` update in place)."""
    N = pts.shape[0]
    return (np.array(pts, dtype=np.float64, order="C", copy=True), np.zeros(N, dtype=np.int32),
            np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64))


def failed_steps(status: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The failed step of each particle (its step count n where it failed, −1 elsewhere), written
    over ``n`` (the runner's scratch, not used afterwards): no new (N,) array."""
    np.putmask(n, status == RESULTS.successful, -1)
    return n


def advance_with_recovery(kernel, method, x, status, n, recovered, n_target, h, how, saving=None,
                          events=None):
    """Advance with ``kernel`` to n_target; recover failed steps lazily and go on with the kernel.

    ``saving`` = (save_every, n_total, xs): the kernel writes the saves; a recovered step's own save
    is written here. ``events`` (native only: :class:`.native.events.Events`): the kernel records
    section crossings instead of saving, and a recovered step is checked for one here; or
    (:class:`.native.walls.WallRun`) the kernel stops lines at a wall, and a recovered step that
    leaves it (``events.recovered`` returns that mask) stops its line there."""
    lazy = bare_method(method) is not method
    save_every, n_total, xs = saving if saving is not None else (0, 0, None)
    while True:
        before = status.copy()
        if events is None:
            kernel.advance(x, status, n, n_target, h, save_every, n_total, xs, recovered=recovered)
        else:
            events.advance(kernel, x, status, n, n_target, h)
        # a line that left the domain (a wall, a gridded field's box) stopped: every alternative
        # evaluates the same field, which does not exist out there, so it is never retried
        idx = np.flatnonzero((before == RESULTS.successful) & (status != RESULTS.successful)
                             & (status != RESULTS.left_domain))
        # a non-finite state fails every alternative too (each maps the same point): not tried
        idx = idx[np.all(np.isfinite(x[idx]), axis=1)]
        if events is not None:  # a line the kernel stopped at a wall did not fail: not retried
            idx = idx[~events.stopped(idx)]
        if idx.size == 0 or not lazy:
            return
        X, st, code = recover_points(method, x[idx], h)
        count_how(code, how)
        good = st == RESULTS.successful
        g = idx[good]
        if g.size == 0:
            return
        Xg = X[good]
        if events is not None:  # the recovered step n → n+1, from x (before) to X
            stop = events.recovered(g, n[g], x[g], Xg)
            if stop is not None:  # a wall: the lines it takes out stay at x_n, stopped
                status[g[stop]] = RESULTS.left_domain
                g, Xg = g[~stop], Xg[~stop]
        x[g] = Xg
        status[g] = RESULTS.successful
        n[g] += 1
        recovered[g] += 1
        if xs is not None:  # the recovered step's save (the kernel filled the frozen state there)
            at = (n[g] % save_every == 0) | (n[g] == n_total)
            slot = np.where(n[g] % save_every == 0, n[g] // save_every, xs.shape[1] - 1)
            xs[g[at], slot[at]] = x[g[at]]

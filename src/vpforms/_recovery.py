"""Host-side, lazy recovery of failed steps (issue #12), shared by every backend.

A backend advances the BARE method (``method.without_recovery()``): the recovering step is only
compiled and run where a bare step failed.  :func:`recover_points` takes those points (each at the
state before its failed step) and returns the recovering method's step there: the same
alternatives, in the same order, as ``method.step_with_recovery`` (``_methods/recover.py``), so a
run recovers exactly the steps that ``method.step`` would.  The backend then continues those
particles from the recovered state with the bare step.

Why lazy: a recovering step compiles every alternative (≈ 10 generating maps); when no step fails
— the common case — a run should cost (and compile) what the bare run does.  A point's result
depends on that point only, so the output does not depend on chunking or on which other points
failed.

Layer (issue #40: no import cycle, lazy ones included): this module sits BELOW the methods —
``Method.step_with_recovery``'s host path (``_methods/_base.py``) calls :func:`recover_points` —
so it knows the methods only by their traits: a :class:`~vpforms._methods.recover.Recovering`
recovers itself (its ``_host_recover``: the alternatives in order), a composition stage by stage
(``stages``), and ``takes_batches`` (``Method``, ``RK4``) says that ``step_with_status`` takes a
batch (N, 3) rather than one point.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from ._errors import RECOVERY, RESULTS
from ._fieldops import padded_blocks

__all__ = ["bare_method", "recover_points", "count_how", "bare_first", "padded_steps", "checked_status"]

#: points per call of the recovering step (one compilation per method)
_BUFFER = 32


def bare_method(method: Any) -> Any:
    """The method with recovery stripped, or ``method`` itself (a user method, a bare one)."""
    strip = getattr(method, "without_recovery", None)
    return method if strip is None else strip()


def bare_first(run, method: Any, succeeded):
    """``run(m)`` of a trajectory diagnostic whose scan traces the step (``log_det``,
    ``poincare_section``), with the bare method first.

    Where no bare step fails, the recovering step IS the bare map, so that result stands and only
    the bare step was compiled; if ``succeeded(result)`` is False (some step failed), the run is
    repeated with the recovering ``method``, whose every alternative is then compiled into the
    scan.  Methods without recovery run once.
    """
    bare = bare_method(method)
    if bare is method:
        return run(method)
    out = run(bare)
    return out if succeeded(out) else run(method)


def padded_steps(fn, x: np.ndarray, h: float):
    """fn(block (B, 3), h) -> arrays (B, …) on x (M, 3) in blocks of B = _BUFFER (one shape)."""
    return padded_blocks(lambda block: fn(block, h), x, _BUFFER)


def checked_status(X: np.ndarray, st: np.ndarray) -> np.ndarray:
    """The status (M,) of steps X (M, 3): ``nonfinite`` where a step marked successful is not finite."""
    st = np.broadcast_to(np.asarray(st, np.int32), X.shape[:1])
    bad = ~np.all(np.isfinite(X), axis=1)
    return np.where((st == RESULTS.successful) & bad, RESULTS.nonfinite, st).astype(np.int32)


def _host_step(method: Any, x: np.ndarray, h: float, bare_failed: bool = False):
    """(X, status, how) of the recovering ``method`` at x (M, 3), alternative by alternative.

    A :class:`~vpforms._methods.recover.Recovering` step recovers itself (``_host_recover``: its
    bare step, then each alternative on the points still failing, in order; an alternative is
    compiled only when a point needs it).  Compositions recover stage by stage (each stage its own
    recovery, as in their ``_batched_step``); ``how`` is then the largest code of the stages.
    ``bare_failed``: the caller already knows the bare step failed at every point (skip it).
    """
    own = getattr(method, "_host_recover", None)
    if own is not None:  # a Recovering step: its alternatives in order (_methods/recover.py)
        return own(x, h, bare_failed)
    stages = getattr(method, "stages", ())
    if len(stages) > 1:  # a composition: stage by stage, each stage its own recovery
        X, st, how = x, np.zeros(x.shape[0], np.int32), np.zeros(x.shape[0], np.int32)
        for stage in stages:
            X, s, r = _host_step(stage.method, X, stage.coefficient * h)
            st, how = np.where(st != RESULTS.successful, st, s), np.maximum(how, r)
        return X, st, how
    if bare_method(method) is method:  # a bare (part of a) method: no recovery
        X, st = padded_steps(_per_batch(method, "step_with_status"), x, h)
        return X, checked_status(X, st), np.zeros(x.shape[0], np.int32)
    if hasattr(method, "_jitted"):  # another vpforms recovering method (e.g. an Adjoint of one)
        X, st, _, how = padded_steps(method._jitted(), x, h)  # its whole recovering step in one jit
    else:  # a user method with step_with_recovery
        X, st, how = padded_steps(_per_batch(method, "step_with_recovery"), x, h)
    return X, checked_status(X, st), np.asarray(how, np.int32)


def _per_batch(method: Any, name: str):
    """``method.<name>`` on a batch (B, 3): vpforms' own methods take batches; a user method's
    contract (as in :func:`vpforms.integrate`) is one point (3,), so it is vmapped."""
    fn = getattr(method, name)
    return fn if getattr(method, "takes_batches", False) else jax.vmap(fn, in_axes=(0, None))


def recover_points(method: Any, x: np.ndarray, h: float):
    """The recovering step at points x (M, 3) whose bare step failed: (X, status, how), numpy.

    ``status`` is 0 where the step was recovered (``how`` is then the :class:`RECOVERY` code of
    the alternative taken, the largest over the stages of a composition); elsewhere the failure
    code, and X must not be used.  The same alternatives in the same order as
    ``method.step_with_recovery``, but each compiled only when some point needs it.
    """
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    X, st, how = _host_step(method, x, float(h), bare_failed=True)
    return X, st, np.where(st == RESULTS.successful, how, RECOVERY.none).astype(np.int32)


def count_how(how: np.ndarray, into: dict[str, int] | None = None) -> dict[str, int]:
    """Add the recovered steps of ``how`` (RECOVERY codes, 0 = not recovered) by message."""
    out = {} if into is None else into
    for code in np.unique(how):
        if code != RECOVERY.none:
            name = RECOVERY.messages[int(code)]
            out[name] = out.get(name, 0) + int(np.count_nonzero(how == code))
    return out

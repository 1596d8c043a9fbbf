"""Particle tracing, the front door: check the arguments, choose a backend, run it.

:func:`integrate` advances one point (shape (3,)) or a cloud of particles (shape (N, 3)) by
``n_steps`` steps of a one-step method and returns a :class:`Solution`.  It needs only

    method.step_with_status(x, h) -> (X, status)      # x of shape (3,), status a RESULTS code

so any vpforms method (``vpforms.scheme``, ``vpforms.compose``), the :class:`RK4` baseline (``_methods/rk4.py``), or a
user object with that method works.  Contract:

* **Memory is bounded** (the JAX backend, :mod:`vpforms.backends.jax_runner`: chunks of particles,
  segments of save-blocks; the native backend, :mod:`vpforms.backends.native.runner`: blocks of
  lanes, the saves written by the kernel).
* **A failed particle is frozen, never NaN.** When a step returns a non-zero status for a particle,
  that particle keeps its last good state for the rest of the run; ``Solution.status`` holds the
  first failure code and ``Solution.failed_step`` the index n of the step t_n → t_{n+1} that failed
  (−1 for particles that never failed).
* **Chunking does not change results.** Every particle's trajectory is the same sequence of
  ``step_with_status`` calls whatever the chunk size (see ``tests/test_integrate.py``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import _config  # noqa: F401  (float64)
from ._methods.rk4 import RK4
from ._solution import Solution, describe
from .backends import select_backend  # the one dispatch hook (issue 9)
from .backends.jax_runner import integrate_jax
from .backends.native.runner import integrate_native

__all__ = ["integrate", "Solution", "RK4", "describe"]

def _check_run(method: Any, x0: Any, h: Any, n_steps: Any, t0: Any = 0.0) -> tuple[np.ndarray, bool, float, int]:
    """Validate the arguments every run shares; return (points (N, 3), single, h, n_steps).

    A bad argument is a named error here, never a NaN or a silently failed run later.
    """
    if not hasattr(method, "step_with_status"):
        raise TypeError("method must have step_with_status(x, h) -> (X, status)")
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.ndim not in (1, 2) or x0.shape[-1] != 3:
        raise ValueError(f"x0 must have shape (3,) or (N, 3); got {x0.shape}")
    # a finite sum needs finite terms (one pass, no temporary); an overflowing one is checked term by term
    with np.errstate(all="ignore"):
        total = float(np.sum(x0))
    if not (math.isfinite(total) or np.all(np.isfinite(x0))):
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
    backend: str = "auto",
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
    backend:
        ``"auto"`` (native C kernel when the method can be generated and a compiler exists, else
        JAX), ``"jax"`` or ``"native"`` (a :class:`VPFormsError` says why if it cannot); see
        :mod:`vpforms.backends`.  ``Solution.stats["backend"]`` says which ran.
    """
    pts, single, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    check = getattr(method, "check_domain", None)
    if check is not None and pts.shape[0]:
        check(pts)  # issue #23: potentials that do not hold at x0 are refused before any step
    backend, backend_reason = select_backend(method, backend)
    if backend == "native":
        if chunk_size is not None and int(chunk_size) < 1:  # the same check as the JAX path
            raise ValueError(f"chunk_size must be ≥ 1, got {chunk_size}")
        return integrate_native(method, pts, single, h, n_steps, save_every, t0, progress, backend_reason)
    return integrate_jax(method, pts, single, h, n_steps, save_every, t0, chunk_size, progress,
                         segment_blocks, backend_reason)

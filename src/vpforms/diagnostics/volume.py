"""Volume along trajectories: per-step and accumulated log |det DΨ_h| (forward-mode AD)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .. import _config  # noqa: F401
from .._errors import RESULTS
from .._integrate import _check_run, describe
from .._recovery import bare_first
from ..backends.jax_runner import _StepFn, auto_chunk_size
from ._common import _chunks, _pad

__all__ = ["LogDet", "log_det"]


@dataclass(frozen=True)
class LogDet:
    """Per-step and accumulated log |det J| along trajectories.

    ``per_step[..., n]`` = log |det DΨ_h(x_n)|, shape (N, n_steps) (or (n_steps,));
    ``accumulated[..., n]`` = log |det D(Ψ_h^n)(x_0)| = Σ_{k<n} per_step[k], shape (N, n_steps + 1);
    ``ts`` the times of ``accumulated``; ``status`` the per-particle first-failure code (a failed
    particle is frozen and contributes 0 from its failure on).
    """

    ts: np.ndarray
    per_step: np.ndarray
    accumulated: np.ndarray
    status: np.ndarray
    method: str

    @property
    def n_failed(self) -> int:
        """Particles with a failed step: their ``accumulated`` stops at the failure (not a volume)."""
        return int(np.count_nonzero(np.asarray(self.status) != RESULTS.successful))

    @property
    def ok(self) -> bool:
        return self.n_failed == 0

    @property
    def max_abs(self) -> float:
        """max over particles and times of |log det D(Ψ_h^n)| (0 for an exactly VP method).

        Failed particles contribute only their steps before the failure: check :attr:`ok` /
        :attr:`n_failed` before reading this as the volume error of the whole run.
        """
        return float(np.max(np.abs(self.accumulated))) if self.accumulated.size else 0.0


@partial(jax.jit, static_argnums=(0, 1))
def _logdet_kernel(step_fn, n_steps, x, h):
    def one(x):
        def body(carry, _):
            x, st, acc = carry
            def f(z):
                X, s = step_fn(z, h)
                return X, (X, s)

            J, (X, s) = jax.jacfwd(f, has_aux=True)(x)
            _, ld = jnp.linalg.slogdet(J)  # log |det J|, forward-mode J (exact through the solves)
            good = (st == RESULTS.successful) & (s == RESULTS.successful) & jnp.isfinite(ld)
            ld = jnp.where(good, ld, 0.0)
            code = jnp.where(s != RESULTS.successful, s, RESULTS.nonfinite).astype(st.dtype)
            st = jnp.where((st == RESULTS.successful) & ~good, code, st)
            x = jnp.where(good, X, x)
            return (x, st, acc + ld), ld

        (x, st, _), lds = lax.scan(body, (x, jnp.int32(0), jnp.float64(0.0)), None, length=n_steps)
        return lds, st

    return jax.vmap(one)(x)


def log_det(
    method: Any,
    x0: Any,
    h: float,
    n_steps: int,
    t0: float = 0.0,
    chunk_size: int | None = None,
) -> LogDet:
    """log |det DΨ_h| per step and accumulated along the trajectories of ``method`` from x0.

    The Jacobian of each step is ``jax.jacfwd`` of ``step_with_status(·, h)[0]`` at the current
    point: exact derivatives, so an exactly volume-preserving method shows rounding-level values
    (≈1e-16 per step) and a non-VP method (RK4) its true volume error.  A particle whose step
    fails is frozen and adds 0 from then on; its code is in ``status`` (see :attr:`LogDet.ok`).
    """
    pts, single, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    N = pts.shape[0]
    C = min(N, chunk_size or auto_chunk_size(N, n_steps))

    def trace(m):
        per = np.empty((N, n_steps))
        status = np.empty(N, dtype=np.int32)
        fn = _StepFn(m)
        for lo, hi in _chunks(N, C):
            lds, st = _logdet_kernel(fn, int(n_steps), jnp.asarray(_pad(pts[lo:hi], C)), jnp.asarray(h))
            per[lo:hi] = np.asarray(lds)[: hi - lo]
            status[lo:hi] = np.asarray(st)[: hi - lo]
        return per, status

    # a recovering method: the bare scan, and the recovering one only where a bare step failed
    per, status = bare_first(trace, method, lambda r: bool(np.all(r[1] == RESULTS.successful)))
    acc = np.concatenate([np.zeros((N, 1)), np.cumsum(per, axis=1)], axis=1)
    ts = t0 + h * np.arange(n_steps + 1)
    if single:
        return LogDet(ts, per[0], acc[0], status[0], describe(method))
    return LogDet(ts, per, acc, status, describe(method))

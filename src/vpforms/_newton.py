"""One scalar Newton solver, shared by every implicit equation in vpforms.

The iteration runs on ``stop_gradient`` of its parameters (so ``lax.while_loop`` is never
differentiated); the root z* is returned with the derivative of a final Newton step taken *with*
the live parameters (its value is not added: at a converged root it is below rounding, and the
native kernels, which need no derivative, skip it).  At a converged root g(z*) = 0 that step has
derivative dz/dθ = -∂_θ g / ∂_z g, the implicit-function-theorem derivative, exact to rounding.
Hence ``jax.jacfwd``/``jax.grad`` through a solve are exact, and a method built on solves is volume preserving to rounding, not to the Newton tolerance.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import lax

from ._errors import RESULTS

__all__ = ["newton_scalar"]

_RUNNING = -1


def newton_scalar(
    g: Callable[[Any, Any], Any],
    dg: Callable[[Any, Any], Any],
    z0: Any,
    params: Any,
    *,
    tol: float = 1e-13,
    max_iter: int = 50,
    twist_tol: float = 1e-12,
    divergence_bound: float = 1e8,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Solve the scalar equation g(z, params) = 0 for z by Newton's method.

    Parameters
    ----------
    g, dg:
        The residual and its z-derivative (from autodiff), both ``(z, params) -> scalar``.
    z0:
        Initial guess (scalar).
    params:
        A pytree of parameters; derivatives with respect to it are exact (IFT) through the solve.
    tol:
        Converged when the Newton step |δ| ≤ tol · (1 + |z|).
    max_iter:
        Iteration cap; reaching it gives ``RESULTS.not_converged``.
    twist_tol:
        |dg| ≤ twist_tol (or a non-finite dg) is a twist failure: the equation is not locally
        solvable for z.
    divergence_bound:
        An iterate farther than divergence_bound · (1 + |z0|) from the guess means Newton ran
        away (e.g. towards an asymptote, where dg also vanishes): ``RESULTS.not_converged``.

    Returns
    -------
    (z, status, iterations) — scalar root, ``int32`` status code, ``int32`` iteration count.
    """
    z0 = jnp.asarray(z0, dtype=jnp.result_type(float))
    frozen = lax.stop_gradient(params)
    z_far = divergence_bound * (1.0 + jnp.abs(lax.stop_gradient(z0)))

    def cond(state):
        _, it, status = state
        return (status == _RUNNING) & (it < max_iter)

    def body(state):
        z, it, _ = state
        gz = g(z, frozen)
        dz = dg(z, frozen)
        twist = ~(jnp.abs(dz) > twist_tol)  # also true for NaN derivative
        step = gz / jnp.where(twist, 1.0, dz)
        z_new = z - step
        diverged = ~jnp.isfinite(z_new) | (jnp.abs(z_new - z0) > z_far)
        converged = jnp.abs(step) <= tol * (1.0 + jnp.abs(z_new))
        status = jnp.where(
            twist,
            RESULTS.twist_failure,
            jnp.where(
                diverged,
                RESULTS.not_converged,
                jnp.where(converged, RESULTS.successful, _RUNNING),
            ),
        ).astype(jnp.int32)
        z_new = jnp.where(twist | diverged, z, z_new)
        return z_new, it + 1, status

    z0 = lax.stop_gradient(z0)
    z_star, iters, status = lax.while_loop(cond, body, (z0, jnp.int32(0), jnp.int32(_RUNNING)))
    status = jnp.where(status == _RUNNING, RESULTS.not_converged, status).astype(jnp.int32)

    # The one differentiable Newton step δ = g/g' at z*, live in the parameters: the value stays z*
    # exactly (δ − stop_gradient(δ) = 0; δ itself is below rounding at a converged root), the
    # derivative is that of z* − δ, −∂_θ g/∂_z g: the IFT derivative. The native kernels return z*.
    z_star = lax.stop_gradient(z_star)
    ok = status == RESULTS.successful
    dz = dg(z_star, params)
    delta = g(z_star, params) / jnp.where(ok, dz, 1.0)
    z = jnp.where(ok, z_star - (delta - lax.stop_gradient(delta)), z_star)
    return z, status, iters

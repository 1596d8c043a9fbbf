"""The consistency guard (issue #23): a step that reports success follows the field.

Every consistent one-step method (order p ≥ 1) satisfies

    X − x − h a(x) = (h²/2) (Da·a)(x) + O(h³),   so   |X − x − h a(x)| ≲ (h L / 2) · |h a(x)|

with L = |Da| near x. The guard marks a step whose Newton solves converged but whose result X is farther than κ·|h a(x)|
(+ rounding) from the explicit predictor x + h a(x) — the Euler point every solve starts from —
with its own status :attr:`RESULTS.inconsistent`: a root on another branch, a pair of potentials
that does not reproduce the field there, a jump.  κ = 8 (:data:`KAPPA`) is a jump detector, not an
accuracy control: the error constant of a consistent order-1 step is not bounded by the spectral
radius of Da (measured ρ = |X − x − h a|/|h a| on 256 initial conditions of each library problem,
all classes, orders 1 and 4: ≤ 0.3 at h = 0.1 except Lotka–Volterra, where the correction-map S1
reaches 2.6 at h = 0.1 and 4.6 at h = 0.2 — steps less accurate than their own displacement, yet
consistent); the jump of issue #23 (Solov'ev tokamak, DL+DL recovered through a singular
relabelled pair) has ρ = 9.2.  The same test runs in the JAX step, in recovery (an alternative is
accepted only if it passes) and in the native kernel; it costs one evaluation of the field.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp

from ._errors import RESULTS

__all__ = ["KAPPA", "guard_status"]

#: relative bound of the guard: |X − x − h a(x)| ≤ KAPPA·|h a(x)| + rounding
KAPPA = 8.0
#: rounding floor, in units of eps·(1 + |x|)
FLOOR = 64.0


def guard_status(x: Any, X: Any, euler: Any, status: Any, kappa: float | None = KAPPA):
    """Status with ``inconsistent`` where a finite, successful step X from x (…, 3) misses the
    predictor ``euler`` = x + h a(x) by more than κ·|h a(x)|_∞ + FLOOR·eps·(1 + |x|_∞)."""
    status = jnp.asarray(status, jnp.int32)
    if kappa is None:
        return status
    eps = jnp.finfo(jnp.result_type(float)).eps
    defect = jnp.max(jnp.abs(X - euler), axis=-1)
    scale = jnp.max(jnp.abs(euler - x), axis=-1)
    bound = kappa * scale + FLOOR * eps * (1.0 + jnp.max(jnp.abs(x), axis=-1))
    finite = jnp.all(jnp.isfinite(X), axis=-1)
    bad = (status == RESULTS.successful) & finite & ~(defect <= bound)
    return jnp.where(bad, jnp.int32(RESULTS.inconsistent), status)


#: an alternative of recovery (another case, another class) must agree with the classical RK4
#: step over the same h to KAPPA_ALT·|h a(x)|: it replaces a failed step, so it must be right, not
#: merely consistent (issue #23: on the Solov'ev tokamak a correction-map alternative whose
#: integral passed near the magnetic axis was off by 2.7·|h a| yet within the guard)
KAPPA_ALT = 0.5


def rk4_step(a, x, h):
    """One classical RK4 step of x' = a(x) (the one copy of the formula: :class:`vpforms.RK4`
    uses it too); ``a`` maps (..., 3) to (..., 3)."""
    k1 = a(x)
    k2 = a(x + 0.5 * h * k1)
    k3 = a(x + 0.5 * h * k2)
    k4 = a(x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rk4_points(components, x, h):
    """(RK4 step, Euler point x + h a(x)) of the field (scalar callables ``components``) from x (N, 3)."""

    def a(p):
        return jnp.stack([jnp.asarray(c(p[..., 0], p[..., 1], p[..., 2]), float) for c in components],
                         axis=-1)

    return rk4_step(a, x, h), x + h * a(x)


def alternative_status(components, x, X, h, status, kappa: float = KAPPA_ALT):
    """Status with ``inconsistent`` where a successful alternative X differs from the RK4 step
    by more than κ·|h a(x)|_∞ + rounding (batched (N, 3))."""
    status = jnp.asarray(status, jnp.int32)
    ref, euler = rk4_points(components, x, h)
    eps = jnp.finfo(jnp.result_type(float)).eps
    err = jnp.max(jnp.abs(X - ref), axis=-1)
    bound = kappa * jnp.max(jnp.abs(euler - x), axis=-1) + FLOOR * eps * (
        1.0 + jnp.max(jnp.abs(x), axis=-1))
    ok_ref = jnp.all(jnp.isfinite(ref), axis=-1)
    bad = (status == RESULTS.successful) & ~((err <= bound) & ok_ref)
    return jnp.where(bad, jnp.int32(RESULTS.inconsistent), status)

"""Shared helpers of the method tests (issue #5); this module holds no tests.

Every expected value is computed: reference trajectories by scipy's DOP853 at tight tolerances,
orders by least-squares fits, Jacobians by forward-mode AD through the steps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.integrate import solve_ivp

from vpforms.problems import get

#: field name → (problem name, box for random points). The boxes keep every off-diagonal
#: ∂a_i/∂x_j away from 0, so that the twist conditions of all 36 cases hold (DL, S1, S2 need them).
FIELD_BOXES = {
    "linear": ("linear", (-1.0, 1.0)),
    "abc": ("abc", (0.45, 1.1)),  # inside (0, π/2)³: every sin and cos of the ABC field ≠ 0
    "lotka_volterra": ("lotka_volterra", (0.5, 2.0)),
}


def field_and_points(name: str, n: int = 6, seed: int = 0):
    prob, (lo, hi) = FIELD_BOXES[name]
    field = get(prob).field
    pts = np.random.default_rng(seed).uniform(lo, hi, (n, 3))
    return field, pts


def kernel(method):
    """One compiled function per method: F(x (N,3), h (N,)) → X, status, iterations, J, res, twist.

    ``res`` is the residual of the determining equations (eq:volpot) of ``method.case`` through
    the method's own generating map (NaN for the correction maps, which have none); ``twist`` is
    (∂X₋/∂x₊, ∂x₋/∂X₊) of the case.
    """
    c = method.case
    has_map = method.generating_map(jnp.float64(0.1), jnp.zeros(3)) is not None

    def one(p, h):
        def fwd(z):
            X, st, it = method._forward(z, h)
            return X, (X, st, it)

        J, (X, st, it) = jax.jacfwd(fwd, has_aux=True)(p)
        if has_map:
            res = method.generating_map(h, p).residual(p, X)
        else:
            res = jnp.full(3, jnp.nan)
        t1 = J[c.X_minus - 1, c.x_plus - 1]
        t2 = jnp.linalg.inv(J)[c.x_minus - 1, c.X_plus - 1]
        return dict(X=X, status=st, iters=it, J=J, res=res, twist=jnp.stack([t1, t2]))

    return jax.jit(jax.vmap(one)), has_map


def reference_flow(field, x0, T: float):
    """x(T) for every row of x0 by DOP853 (rtol = atol = 1e-13)."""
    x0 = np.asarray(x0, float)

    def f(t, y):
        return np.asarray(field(jnp.asarray(y.reshape(-1, 3)))).ravel()

    sol = solve_ivp(f, (0.0, T), x0.ravel(), method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    return sol.y[:, -1].reshape(x0.shape)


def fit_order(hs, errs) -> float:
    """Slope of log(err) against log(h) by least squares."""
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


def global_errors(step, x0, T: float, ns, ref):
    """max-norm global errors at time T for n steps each (step(x, h) batched, called per step)."""
    errs = []
    for n in ns:
        h = T / n
        x = np.asarray(x0, float)
        for _ in range(n):
            x = step(x, h)
        errs.append(float(np.max(np.abs(np.asarray(x) - ref))))
    return np.asarray(errs)


def step_jac(method):
    """One compiled function per method: G(x (N,3), h) → (X, J, status)."""

    def one(p, h):
        def fwd(z):
            X, st, _ = method._forward(z, h)
            return X, (X, st)

        J, (X, st) = jax.jacfwd(fwd, has_aux=True)(p)
        return X, J, st

    f = jax.jit(jax.vmap(one, in_axes=(0, None)))
    return lambda x, h: f(jnp.asarray(x, float), jnp.asarray(h, float))


def step_det(method):
    """G(x (N,3), h) → (X, det J, status), one compilation per method."""
    f = step_jac(method)

    def g(x, h):
        X, J, st = f(x, h)
        return X, jnp.linalg.det(J), st

    return g

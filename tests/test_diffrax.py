"""vpforms.diffrax.VPSolver: diffeqsolve with a vpforms method = vpforms.integrate (1e-13)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

diffrax = pytest.importorskip("diffrax")

import vpforms
import vpforms.problems
from vpforms.diffrax import VPSolver, field_term


@pytest.fixture(scope="module")
def method():
    return vpforms.scheme(vpforms.problems.get("abc").field)


def test_same_numbers_as_integrate_at_step_times(method):
    y0, h, n = jnp.array([0.1, 0.2, 0.3]), 0.1, 20
    ts = jnp.arange(n + 1) * h
    sol = diffrax.diffeqsolve(field_term(method), VPSolver(method), 0.0, n * h, h, y0,
                              saveat=diffrax.SaveAt(ts=ts))
    ref = vpforms.integrate(method, y0, h, n, save_every=1)
    assert sol.result == diffrax.RESULTS.successful
    assert np.max(np.abs(np.asarray(sol.ys) - ref.xs)) <= 1e-13


def test_adaptive_controller_is_refused(method):
    with pytest.raises(RuntimeError, match="error estimates"):
        diffrax.diffeqsolve(field_term(method), VPSolver(method), 0.0, 1.0, 0.1,
                            jnp.array([0.1, 0.2, 0.3]),
                            stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-6))


def test_vmap_jit_over_y0_and_failure_maps_to_results(method):
    h, n = 0.1, 10
    Y0 = jnp.array([[0.1, 0.2, 0.3], [0.5, -0.4, 1.0], [jnp.nan, 0.0, 0.0]])

    @jax.jit
    def solve(Y0):
        return jax.vmap(lambda y0: diffrax.diffeqsolve(
            field_term(method), VPSolver(method), 0.0, n * h, h, y0, throw=False))(Y0)

    sol = solve(Y0)
    ref = vpforms.integrate(method, Y0[:2], h, n)
    assert np.max(np.abs(np.asarray(sol.ys[:2, -1]) - ref.x_final)) <= 1e-13
    codes = np.asarray(sol.result._value)  # vmapped EnumerationItem: one code per y0
    assert codes[0] == codes[1] == diffrax.RESULTS.successful._value
    assert codes[2] == diffrax.RESULTS.nonfinite._value  # a vpforms non-finite status

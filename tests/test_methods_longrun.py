"""Long runs (issue #5): ABC (A, B, C) = (1, √(2/3), √(1/3)), h = 0.1, 10⁴ steps.

|Σ log det DΨ_h| ≤ 1e-9 along the trajectory for every class's method — S1/S2 through Quispel's
correction maps, the DL classes through their stage form (``fast=True``, the same map as the
engine where the DL twist holds: ABC trajectories cross the fold planes sin x₃ = 0 / cos x₃ = 0
where the DL generating forms cease to exist, and there the engine reports a twist failure, as
asserted below) — while classical RK4 (written here as the baseline) visibly drifts.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax

from vpforms import RESULTS, scheme
from vpforms.problems import get

N_STEPS, H = 10_000, 0.1
X0 = jnp.array([0.5, 0.7, 0.9])


def log_det_run(forward, x0, h, n):
    """(Σ log |det J|, number of failed steps, x_n) along n steps, J by forward-mode AD."""

    def body(carry, _):
        x, total, bad = carry

        def f(z):
            X, st = forward(z, h)
            return X, (X, st)

        J, (X, st) = jax.jacfwd(f, has_aux=True)(x)
        return (X, total + jnp.log(jnp.abs(jnp.linalg.det(J))), bad + (st != 0)), None

    (x, total, bad), _ = lax.scan(body, (x0, 0.0, 0), None, length=n)
    return total, bad, x


@pytest.fixture(scope="module")
def abc():
    prob = get("abc")
    assert np.allclose([prob.params[k] for k in "ABC"], [1, np.sqrt(2 / 3), np.sqrt(1 / 3)])
    return prob.field


@pytest.mark.slow
@pytest.mark.parametrize(
    "cls,opts",
    [
        ("SE+SE", {}),
        ("SE+DL", {"fast": True}),
        ("DL+DL", {"fast": True}),
        ("DL+DL", {"fast": True, "theta": 0.5}),
        ("S1", {}),
        ("S2", {}),
    ],
)
def test_long_run_log_det(abc, cls, opts):
    m = scheme(abc, cls, **opts)
    run = jax.jit(lambda x0, h: log_det_run(lambda z, h: m._forward(z, h)[:2], x0, h, N_STEPS))
    total, bad, x = run(X0, H)
    assert int(bad) == 0 and bool(jnp.all(jnp.isfinite(x)))
    assert abs(float(total)) <= 1e-9, float(total)


@pytest.mark.slow
def test_rk4_baseline_drifts(abc):
    a = abc._vec

    def rk4(x, h):
        k1 = a(x)
        k2 = a(x + h / 2 * k1)
        k3 = a(x + h / 2 * k2)
        k4 = a(x + h * k3)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), jnp.int32(0)

    total, _, _ = jax.jit(lambda x0, h: log_det_run(rk4, x0, h, N_STEPS))(X0, H)
    assert abs(float(total)) >= 1e-6, float(total)  # ≥ 1000× the VP methods' bound


def test_dl_engine_reports_the_fold_the_stage_form_crosses(abc):
    # on the fold x₃ = 0 the SE+DL twist ∂X₂/∂x₃ = −hA sin x₃ + … vanishes: L_d¹ does not exist
    x = jnp.array([[0.7, 0.4, 0.0], [0.7, 0.4, 0.5]])
    eng, fast = scheme(abc, "SE+DL"), scheme(abc, "SE+DL", fast=True)
    _, status = eng.step_with_status(x, H)
    assert int(status[0]) == RESULTS.twist_failure and int(status[1]) == 0
    X, status = fast.step_with_status(x, H)
    assert np.all(np.asarray(status) == 0)
    assert float(jnp.max(jnp.abs(fast.det(x, H) - 1))) <= 1e-14
    t = np.asarray(fast.twist(x, H))
    assert abs(t[0, 0]) <= 1e-15 < abs(t[1, 0])
    assert float(jnp.max(jnp.abs(X[1] - eng.step(x[1], H)))) <= 1e-13

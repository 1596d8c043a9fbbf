"""Long runs (issue #5): ABC (A, B, C) = (1, √(2/3), √(1/3)), h = 0.1, 10⁴ steps.

|Σ log det DΨ_h| ≤ 1e-9 along the trajectory for every class's method — S1/S2 through Quispel's
correction maps, the DL classes through their stage form (``fast=True``, the same map as the
engine where the DL twist holds: ABC trajectories cross the fold planes sin x₃ = 0 / cos x₃ = 0
where the DL generating forms cease to exist, and there the engine reports a twist failure, as
asserted below) — while classical RK4 (``vpforms.RK4``) visibly drifts.  Σ log |det J| is
``vpforms.diagnostics.log_det`` (J by forward-mode AD through each step).
"""

import jax.numpy as jnp
import numpy as np
import pytest

from vpforms import RESULTS, RK4, scheme
from vpforms.diagnostics import log_det
from vpforms.problems import get

N_STEPS, H = 10_000, 0.1
X0 = jnp.array([0.5, 0.7, 0.9])


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
    ld = log_det(m, X0, H, N_STEPS)
    assert ld.ok, ld.status  # no step failed, so the sum covers the whole trajectory
    assert abs(float(ld.accumulated[-1])) <= 1e-9, float(ld.accumulated[-1])


@pytest.mark.slow
def test_rk4_baseline_drifts(abc):
    ld = log_det(RK4(abc), X0, H, N_STEPS)
    assert ld.ok
    total = float(ld.accumulated[-1])
    assert abs(total) >= 1e-6, total  # ≥ 1000× the VP methods' bound


def test_dl_engine_reports_the_fold_the_stage_form_crosses(abc):
    # on the fold x₃ = 0 the SE+DL twist ∂X₂/∂x₃ = −hA sin x₃ + … vanishes: L_d¹ does not exist
    x = jnp.array([[0.7, 0.4, 0.0], [0.7, 0.4, 0.5]])
    eng, fast = scheme(abc, "SE+DL", recover=False, fast=False), scheme(abc, "SE+DL", recover=False)
    _, status = eng.step_with_status(x, H)
    assert int(status[0]) == RESULTS.twist_failure and int(status[1]) == 0
    X, status = fast.step_with_status(x, H)
    assert np.all(np.asarray(status) == 0)
    assert float(jnp.max(jnp.abs(fast.det(x, H) - 1))) <= 1e-14
    t = np.asarray(fast.twist(x, H))
    assert abs(t[0, 0]) <= 1e-15 < abs(t[1, 0])
    assert float(jnp.max(jnp.abs(X[1] - eng.step(x[1], H)))) <= 1e-13

"""Fixed points of the return map from native traces (issue #41 item 1): the same points, tangent maps
and ι as the JAX return map's exact forward-mode derivatives, in seconds."""

from __future__ import annotations

import numpy as np
import pytest

import vpforms
from vpforms import problems
from vpforms.fieldlines import magnetic_axis, return_map
from vpforms.fieldlines._fixedpoints import _value_and_jac, find_fixed_point
from vpforms.fieldlines._native_map import native_value_and_jac

from .test_fieldlines import TwistMethod


def test_backend_is_checked():
    P = return_map(TwistMethod(), 0.05, guess=(1.1, 0.0))
    with pytest.raises(ValueError, match="backend must be 'auto', 'jax' or 'native'"):
        find_fixed_point(P, (1.05, 0.0), backend="C")
    with pytest.raises(ValueError, match="backend='native': the native backend does not run this method"):
        find_fixed_point(P, (1.05, 0.0), backend="native")
    assert native_value_and_jac(P, 1)(np.array([1.05, 0.0])) is None  # auto falls back to JAX


@pytest.mark.slow  # the JAX return map's derivative compiles for ~30 s
def test_native_map_and_axis_equal_the_jax_ones_on_the_tokamak():
    """Closed-form tokamak (native C): P(z) equal to 1e-11, DP (central differences against forward
    mode) to 1e-6, and the axis and its ι (branch by the neighbouring line against the JAX tangent
    winding) to 1e-10 and 1e-7. P² differs by the integrator's own error: the JAX map restarts the
    steps at the first crossing, the native trace goes on along the line (1.8e-7 at h = 0.05, order
    2; both approximate the exact P² to that order)."""
    prob = problems.get("tokamak", coordinates="toroidal")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE", recover=False), order=2)
    guess = prob.axis_guess
    P = return_map(m, 0.05, 0.0, 1, guess=guess)
    z = np.array([guess[0] + 0.05, 0.02])
    for k in (1, 2):
        zn, stn, Jn = native_value_and_jac(P, k)(z)
        zj, stj, Jj = (np.asarray(a) for a in _value_and_jac(P, k)(z))
        assert int(stn) == int(stj) == 0
        np.testing.assert_allclose(zn, zj, rtol=0, atol=1e-11 if k == 1 else 1e-6)
        np.testing.assert_allclose(Jn, Jj, rtol=0, atol=(1e-6 if k == 1 else 1e-5) * np.abs(Jj).max())
    an = magnetic_axis(m, guess, 0.05, backend="native")
    aj = magnetic_axis(m, guess, 0.05, backend="jax")
    assert abs(an.R - aj.R) < 1e-10 and abs(an.Z - aj.Z) < 1e-10
    assert abs(an.iota - aj.iota) < 1e-7 and an.kind == aj.kind == "O"


@pytest.mark.slow  # the JAX ι scan compiles for ~15 s
def test_native_iota_equals_the_jax_iota_on_the_tokamak():
    """ι read at 16 planes per turn from native traces against the per-step JAX sums: the same
    weighted Birkhoff limits (agreement far inside either's own error estimate)."""
    from vpforms.fieldlines import rotational_transform

    prob = problems.get("tokamak", coordinates="toroidal")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE", recover=False), order=2)
    ax = magnetic_axis(m, prob.axis_guess, 0.05)
    got = {b: rotational_transform(m, prob.x0[:3], 0.05, 4000, ax, backend=b, progress=False) for b in ("native", "jax")}
    n, j = got["native"], got["jax"]
    assert np.all(n.status == 0) and np.all(j.status == 0)
    assert np.all(np.abs(n.iota - j.iota) <= 1e-5 + 0.1 * j.error), (n.iota, j.iota, j.error)
    np.testing.assert_allclose(n.transits, j.transits, rtol=2e-3)  # the last plane vs the last step
    with pytest.raises(ValueError, match="backend must be 'auto', 'jax' or 'native'"):
        rotational_transform(m, prob.x0[:1], 0.05, 10, ax, backend="C")

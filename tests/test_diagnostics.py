"""vpforms.diagnostics: log |det J| by forward-mode AD, invariant drift, order fit, Poincaré sections.

Every expected value is computed here: matrix powers for linear fields, exact rotations, synthetic
error curves built with a known slope, the invariant of the integrable ABC flow.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm

from vpforms.diagnostics import (
    fit_order,
    invariant_drift,
    log_det,
    observed_order,
    poincare_section,
    reference_solution,
)
from vpforms import RK4, integrate

from .test_integrate import SE, abc


class Linear:
    """x' = M x as a callable field with its matrix (for the exact reference)."""

    def __init__(self, M):
        self.linear_matrix = np.asarray(M, dtype=float)
        self._M = jnp.asarray(self.linear_matrix)
        self.name = "linear"

    def __call__(self, x):
        return self._M @ x


# rotation about x₃ (traceless): x₁ + i x₂ turns at unit angular speed, x₃ is constant
ROT = Linear([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
# a generic traceless matrix
M3 = np.array([[0.3, -1.0, 0.4], [0.8, -0.1, 0.2], [-0.5, 0.6, -0.2]])
LIN = Linear(M3)
RK_ROT, RK_LIN = RK4(ROT), RK4(LIN)


def test_log_det_matches_the_rk4_stability_matrix_and_vp_is_rounding():
    h, n = 0.1, 30
    x0 = np.random.default_rng(0).normal(size=(4, 3))
    ld = log_det(RK_LIN, x0, h, n)
    # RK4 on x' = Mx is x ↦ R x with R = Σ_{k≤4} (hM)^k/k!: log|det R| per step, exactly
    hM = h * M3
    R = sum(np.linalg.matrix_power(hM, k) / math.factorial(k) for k in range(5))
    expected = np.log(abs(np.linalg.det(R)))
    assert abs(expected) > 1e-9  # RK4 is not volume preserving here
    # log det of a matrix near I: absolute rounding ~1e-16 per step
    np.testing.assert_allclose(ld.per_step, expected, rtol=0, atol=2e-16 * 8)
    np.testing.assert_allclose(ld.accumulated[:, -1], n * expected, rtol=0, atol=n * 2e-16 * 8)
    np.testing.assert_allclose(ld.ts, h * np.arange(n + 1))
    assert ld.per_step.shape == (4, n) and ld.accumulated.shape == (4, n + 1)
    # the generating-form method: det ≡ 1 to rounding along a whole trajectory
    vp = log_det(SE, np.random.default_rng(1).uniform(0, 2 * np.pi, (3, 3)), 0.1, 50)
    assert vp.max_abs < 1e-12 and np.all(vp.status == 0)


def test_invariant_drift():
    # exact rotation states: x₁² + x₂² and x₃ are invariants, x₁ is not
    t = np.linspace(0.0, 3.0, 7)
    xs = np.stack([np.cos(t), np.sin(t), np.full_like(t, 0.5)], axis=-1)
    inv = {"r2": lambda x: x[0] ** 2 + x[1] ** 2, "x3": lambda x: x[2], "x1": lambda x: x[0]}
    d = invariant_drift(inv, xs)
    assert np.max(np.abs(d["r2"])) < 1e-15 and np.max(np.abs(d["x3"])) == 0
    np.testing.assert_allclose(d["x1"], np.cos(t) - 1.0, atol=1e-15)
    d2 = invariant_drift(inv, np.stack([xs, 2 * xs]), relative=True)
    assert d2["x1"].shape == (2, 7)
    np.testing.assert_allclose(d2["x1"][1], (2 * np.cos(t) - 2.0) / 2.0, atol=1e-15)


def test_fit_order_ignores_plateau_and_preasymptotic_points():
    hs = 0.4 / 2.0 ** np.arange(10)
    p = 3.0
    err = 2.0 * hs**p
    err[0] *= 7.0  # pre-asymptotic at the largest step
    # a plateau well above the default round-off floor (so the run selection, not the floor,
    # must drop it): the three smallest steps sit on it
    err = np.maximum(err, 1e-7 * (1 + np.arange(10) % 2))
    fit = fit_order(hs, err)
    assert abs(fit.order - p) < 1e-6
    # fit.hs / fit.errors / fit.used are sorted by increasing h
    np.testing.assert_array_equal(fit.hs, np.sort(hs))
    on_curve = (err == 2.0 * hs**p) & (np.arange(10) > 0)  # neither plateau nor pre-asymptotic
    assert on_curve.sum() == 6
    np.testing.assert_array_equal(fit.used, on_curve[np.argsort(hs)])
    np.testing.assert_allclose(fit.predict(hs[3]), 2.0 * hs[3] ** p, rtol=1e-6)
    with pytest.raises(ValueError):
        fit_order([0.1, 0.05], [1e-17, 1e-17])
    for hs_bad in ([0.1, 0.0], [0.1, -0.05], [0.1, np.nan]):
        with pytest.raises(ValueError, match="hs must be"):
            fit_order(hs_bad, [1e-3, 1e-4])
    with pytest.raises(ValueError, match="same length"):
        fit_order([0.1, 0.05, 0.025], [1e-3, 1e-4])


def test_observed_order_rk4_and_first_order_vp_method():
    x0 = np.random.default_rng(2).normal(size=(3, 3))
    T = 1.0
    ref = reference_solution(LIN, x0, T)
    np.testing.assert_allclose(ref, x0 @ expm(T * M3).T, rtol=0, atol=1e-14)  # exact branch
    fit = observed_order(RK_LIN, x0, T, [0.2, 0.1, 0.05, 0.025])
    for hs_bad in ([0.2, 0.0], [0.2, np.inf]):
        with pytest.raises(ValueError, match="hs must be"):
            observed_order(RK_LIN, x0, T, hs_bad, reference=ref)
    assert abs(fit.order - 4) < 0.15
    fit1 = observed_order(SE, np.random.default_rng(3).uniform(0, 6, (2, 3)), T, [0.1, 0.05, 0.025, 0.0125])
    assert abs(fit1.order - 1) < 0.1  # reference: DOP853 from SE.field (the ABC flow)


def test_poincare_crossings_of_a_rotation_land_on_the_circle():
    # x' = (−x₂, x₁, 0): every crossing of x₂ = 0 upward is at (r, 0, x₃(0)), r = |(x₁, x₂)|
    x0 = np.array([[1.0, 0.3, 0.2], [0.4, -0.2, -1.0], [-2.0, 0.5, 3.0]])
    r = np.hypot(x0[:, 0], x0[:, 1])
    h, n = 0.05, 800  # t = 40: six turns
    sec = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=1)
    assert sec.points.shape[0] == sec.counts.sum() and sec.dropped == 0
    th0 = np.arctan2(x0[:, 1], x0[:, 0])  # crossings at t = 2πk − θ₀ ∈ (0, 40]
    np.testing.assert_array_equal(sec.counts, np.floor((40 + th0) / (2 * np.pi)) - np.floor(th0 / (2 * np.pi)))
    p = sec.points
    assert np.max(np.abs(p[:, 1])) < 1e-13  # on the plane
    err_step = np.max(np.abs(p[:, 0] - r[sec.particle]))
    assert err_step < 1e-6  # RK4 accuracy: interpolation on the step family keeps the order
    np.testing.assert_array_equal(p[:, 2], x0[sec.particle, 2])
    # crossing times: θ(t) = θ₀ + t hits 2πk
    k = np.round((sec.t + th0[sec.particle]) / (2 * np.pi))
    np.testing.assert_allclose(sec.t, 2 * np.pi * k - th0[sec.particle], atol=1e-6)
    assert np.all((sec.theta >= 0) & (sec.theta <= 1))
    # the chord (order-1 interpolation) cuts inside the circle: a visibly larger error
    lin = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=1, interpolation="linear")
    err_lin = np.max(np.abs(lin.points[:, 0] - r[lin.particle]))
    assert err_lin > 100 * err_step
    # downward crossings are on the other half-line
    down = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=-1)
    assert np.all(down.points[:, 0] < 0)
    both = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=0)
    assert both.points.shape[0] == sec.points.shape[0] + down.points.shape[0]
    assert sec.n_fallback == 0 and lin.n_fallback == 0


def test_poincare_flags_crossings_the_step_family_cannot_locate():
    # a method whose full steps succeed but whose sub-steps Ψ_{θh}, θ < 1, all fail: every
    # crossing falls back to the chord and must say so (not pass as an order-4 location)
    class FullStepsOnly:
        order = 4

        def step_with_status(self, x, h):
            X, s = RK_ROT.step_with_status(x, h)
            return X, jnp.where(jnp.abs(h) < 0.05 * (1 - 1e-12), 2, s).astype(jnp.int32)

    x0 = np.array([[1.0, 0.3, 0.2], [0.4, -0.2, -1.0]])
    sec = poincare_section(FullStepsOnly(), x0, 0.05, 300, axis=1, value=0.0, direction=1)
    lin = poincare_section(RK_ROT, x0, 0.05, 300, axis=1, value=0.0, direction=1, interpolation="linear")
    assert sec.points.shape[0] > 0 and np.all(sec.status == 0)
    assert sec.n_fallback == sec.points.shape[0] and np.all(sec.fallback)
    np.testing.assert_allclose(sec.points, lin.points, rtol=0, atol=1e-15)


def test_poincare_modulo_period_integrable_abc():
    # ABC with C = 0 is integrable: I = A cos x₃ + B sin x₁ is constant along orbits, so the
    # crossings of x₂ = 0 (mod 2π) lie on the level curves I(x₁, x₃) = I(x(0))
    A, B = 1.0, math.sqrt(2 / 3)

    def field(x):
        return jnp.stack([A * jnp.sin(x[2]), B * jnp.sin(x[0]) + A * jnp.cos(x[2]), B * jnp.cos(x[0])])

    x0 = np.random.default_rng(5).uniform(0, 2 * np.pi, (6, 3))
    I0 = A * np.cos(x0[:, 2]) + B * np.sin(x0[:, 0])
    sec = poincare_section(RK4(field), x0, 0.05, 2000, axis=1, value=0.0, direction=0, period=2 * np.pi)
    assert sec.points.shape[0] > 20
    p = sec.points
    np.testing.assert_allclose(np.mod(p[:, 1] + 1e-9, 2 * np.pi), 1e-9, atol=1e-8)  # x₂ ≡ 0 mod 2π
    I = A * np.cos(p[:, 2]) + B * np.sin(p[:, 0])
    assert np.max(np.abs(I - I0[sec.particle])) < 1e-7
    uv = sec.coordinates()
    assert uv.shape == (p.shape[0], 2) and uv.min() >= 0 and uv.max() < 2 * np.pi


def test_poincare_vp_method_points_are_steps_of_the_method(tmp_path):
    # with interpolation="step" a crossing is Ψ_{θh}(x_n): check it against the method itself
    x0 = np.random.default_rng(7).uniform(0, 2 * np.pi, (4, 3))
    h = 0.1
    sec = poincare_section(SE, x0, h, 600, axis=2, value=1.0, direction=1, period=2 * np.pi)
    assert sec.points.shape[0] > 0
    sol = integrate(SE, x0, h, 600, save_every=1, progress=False)
    x_n = sol.xs[sec.particle, sec.step]
    again = np.stack([np.asarray(SE.step_with_status(jnp.asarray(x), th * h)[0])
                      for x, th in zip(x_n, sec.theta)])
    np.testing.assert_allclose(sec.points, again, rtol=0, atol=1e-12)
    assert np.max(np.abs(np.mod(sec.points[:, 2] - 1.0 + 1.0, 2 * np.pi) - 1.0)) < 1e-12
    path = tmp_path / "c.csv"
    sec.to_csv(str(path))
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (sec.points.shape[0], 9)


def test_poincare_bad_arguments():
    with pytest.raises(ValueError):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, axis=3)
    with pytest.raises(ValueError):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, direction=2)
    with pytest.raises(ValueError):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, interpolation="cubic")
    with pytest.raises(ValueError):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, period=-1.0)
    for h in (0.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="h must be"):
            poincare_section(RK_ROT, np.zeros(3), h, 10)
    with pytest.raises(ValueError, match="n_steps"):
        poincare_section(RK_ROT, np.zeros(3), 0.1, -1)
    with pytest.raises(ValueError, match="value"):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, value=float("nan"))
    with pytest.raises(ValueError, match="t0"):
        poincare_section(RK_ROT, np.zeros(3), 0.1, 10, t0=float("inf"))


def test_log_det_bad_arguments_are_named_errors():
    # a NaN step size or start must not come back as a "volume error" of 0 with a status
    for h in (0.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="h must be"):
            log_det(RK_LIN, np.ones(3), h, 3)
    with pytest.raises(ValueError, match="NaN"):
        log_det(RK_LIN, np.array([np.nan, 0.0, 0.0]), 0.1, 3)
    with pytest.raises(ValueError, match="shape"):
        log_det(RK_LIN, np.zeros((2, 4)), 0.1, 3)
    with pytest.raises(ValueError, match="n_steps"):
        log_det(RK_LIN, np.zeros(3), 0.1, 2.5)


def test_log_det_reports_failed_particles():
    # x' = x² blows up: RK4 overflows after a few steps from x₁ = 1e100, not from x₁ = 0.1
    class Blowup:
        def __call__(self, x):
            return jnp.array([x[0] ** 2, 0.0, 0.0])

    x0 = np.array([[0.1, 0.0, 0.0], [1e100, 0.0, 0.0]])
    ld = log_det(RK4(Blowup()), x0, 0.1, 5)
    assert not ld.ok and ld.n_failed == 1
    assert ld.status[0] == 0 and ld.status[1] != 0
    assert np.all(np.isfinite(ld.accumulated))  # frozen, not NaN


def test_abc_field_helper_is_divergence_free():
    # the ABC helper used above is the field of the tests' SE+SE method
    import jax

    x = jnp.asarray(np.random.default_rng(0).uniform(0, 6, 3))
    assert abs(float(jnp.trace(jax.jacfwd(abc)(x)))) < 1e-15


def test_poincare_long_runs_flush_buffers_and_cap():
    # 2500 steps = 20 segments, buffers emptied after each: counts and points must agree with one
    # run per particle; max_crossings keeps the first crossings and reports the rest as dropped
    x0 = np.array([[1.0, 0.0, 0.0], [0.5, 0.5, 0.1]])
    h, n = 0.05, 2500  # t = 125: ~20 turns
    sec = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=1)
    th0 = np.arctan2(x0[:, 1], x0[:, 0])
    T = h * n
    np.testing.assert_array_equal(sec.counts, np.floor((T + th0) / (2 * np.pi)) - np.floor(th0 / (2 * np.pi)))
    assert sec.dropped == 0 and sec.points.shape[0] == sec.counts.sum()
    assert np.all(np.diff(sec.t[sec.particle == 0]) > 6.0)  # ordered, one per turn
    one = poincare_section(RK_ROT, x0[1:], h, n, axis=1, value=0.0, direction=1)
    np.testing.assert_allclose(one.points, sec.points[sec.particle == 1], rtol=0, atol=1e-15)
    capped = poincare_section(RK_ROT, x0, h, n, axis=1, value=0.0, direction=1, max_crossings=5)
    assert np.all(np.bincount(capped.particle) == 5)
    assert capped.dropped == sec.counts.sum() - 10
    np.testing.assert_allclose(capped.t, np.concatenate([sec.t[sec.particle == p][:5] for p in (0, 1)]),
                               rtol=0, atol=1e-12)


def test_poincare_freezes_a_nonfinite_step_reported_as_success():
    # a user method returning NaN with status 0 once x₃ > 1: the orbit stops with the nonfinite
    # code; its crossings before that are kept, none after
    class Sloppy:
        def step_with_status(self, x, h):
            X = RK_ROT.step(x, h) + jnp.array([0.0, 0.0, h])
            return jnp.where(x[2] > 1.0, jnp.nan, X), jnp.int32(0)

    x0 = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, -100.0]])
    sec = poincare_section(Sloppy(), x0, 0.05, 400, axis=1, value=0.0, direction=1)
    assert np.all(np.isfinite(sec.points))
    from vpforms import RESULTS

    assert sec.status[0] == RESULTS.nonfinite and sec.status[1] == 0
    assert np.all(sec.t[sec.particle == 0] <= 1.0 + 0.05 + 1e-12)  # x₃ = t: none after the failure
    assert sec.counts[1] == 3  # t = 2π k ≤ 20, k = 1, 2, 3: the healthy orbit is unaffected

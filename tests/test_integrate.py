"""vpforms.integrate: saved states = repeated steps, chunking is bitwise neutral, failures freeze.

The methods are built here directly on the one engine (GeneratingMap) so that these tests depend
only on issue #2: SE+SE on the ABC flow with the closed-form potentials of MATH.md §3/§4, and a
map whose Newton solve has no solution for |x₁| ≥ π/2 (a genuine Newton failure).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, Case, GeneratingMap
from vpforms import RK4, Solution, integrate

A, B, C = 1.0, math.sqrt(2 / 3), math.sqrt(1 / 3)


def F1(x1, x2, x3):
    return C * jnp.cos(x2) - B * x2 * jnp.cos(x1) + A * jnp.sin(x3)


def F3(x1, x2, x3):
    return A * x2 * jnp.sin(x3) + C * jnp.sin(x2) + B * jnp.cos(x1)


def abc(x):
    return jnp.stack([A * jnp.sin(x[2]) + C * jnp.cos(x[1]), B * jnp.sin(x[0]) + A * jnp.cos(x[2]),
                      C * jnp.sin(x[1]) + B * jnp.cos(x[0])])


class SESEonABC:
    """SE+SE (eq:case5), σ = (3,2,1), Σ = (1,2,3): φ = x₂X₃ + hF¹(x₁,x₂,X₃), Φ = x₁X₂ + hF³(x₁,X₂,X₃)."""

    case = Case((3, 2, 1), (1, 2, 3))
    order = 1
    field = staticmethod(abc)
    description = "test SE+SE on ABC"

    def step_with_status(self, x, h):
        # generic argument order: φ(X₃, x₂, x₁), Φ(X₃, X₂, x₁)
        phi = lambda X3, x2, x1: x2 * X3 + h * F1(x1, x2, X3)  # noqa: E731
        Phi = lambda X3, X2, x1: x1 * X2 + h * F3(x1, X2, X3)  # noqa: E731
        return GeneratingMap(phi, Phi, self.case).solve(x)


class AtanMap:
    """y ↦ Y with ∂₂φ = atan(Y₃) = y₁ (φ = y₂·atan Y₃): no solution, hence a failed Newton solve,
    whenever |x₁| ≥ π/2.  Φ = Y₂ y₃ gives Y₂ = −y₂/(1+Y₃²), Y₁ = y₃ (a rotation of coordinates)."""

    description = "atan test map"

    def __init__(self):
        self.map = GeneratingMap(lambda a, b, c: b * jnp.arctan(a), lambda a, b, c: b * c,
                                 Case((1, 2, 3), (1, 2, 3)), max_iter=40)

    def step_with_status(self, x, h):
        return self.map.solve(x)


SE = SESEonABC()
ATAN = AtanMap()
_step = jax.jit(jax.vmap(lambda x, h: SE.step_with_status(x, h)[0], in_axes=(0, None)))


def _x0(n, seed=0):
    return np.random.default_rng(seed).uniform(0.0, 2 * np.pi, (n, 3))


def test_test_method_is_a_consistent_volume_preserving_step():
    # the test-local method is what it claims: X = x + h a(x) + O(h²), det DX = 1
    x = jnp.asarray(_x0(5))
    errs = [float(jnp.max(jnp.abs((_step(x, h) - x) / h - jax.vmap(abc)(x)))) for h in (1e-2, 1e-3)]
    assert errs[1] < errs[0] / 5
    J = jax.vmap(jax.jacfwd(lambda z: SE.step_with_status(z, 0.1)[0]))(x)
    assert np.max(np.abs(np.linalg.det(np.asarray(J)) - 1)) < 1e-13


def test_saved_states_equal_repeated_steps():
    x0 = _x0(7)
    n, k, h = 23, 5, 0.1  # save_every does not divide n_steps: the last state is saved too
    sol = integrate(SE, x0, h, n, save_every=k, progress=False)
    assert isinstance(sol, Solution)
    traj = [x0]
    x = jnp.asarray(x0)
    for _ in range(n):
        x = _step(x, h)
        traj.append(np.asarray(x))
    traj = np.stack(traj, axis=1)  # (N, n+1, 3)
    expected_steps = sorted(set(range(0, n + 1, k)) | {n})
    np.testing.assert_array_equal(sol.steps, expected_steps)
    np.testing.assert_allclose(sol.ts, h * np.asarray(expected_steps), rtol=0, atol=1e-15)
    assert sol.xs.shape == (7, len(expected_steps), 3)
    # same arithmetic, differently compiled kernels: equal to a few ulps
    np.testing.assert_allclose(sol.xs, traj[:, expected_steps], rtol=0, atol=1e-13)
    assert sol.ok and np.all(sol.failed_step == -1)
    assert sol.method == "test SE+SE on ABC"
    np.testing.assert_array_equal(sol.x_final, sol.xs[:, -1])


def test_single_point_and_default_saves():
    x0 = _x0(1)[0]
    sol = integrate(SE, x0, 0.1, 40, progress=False)
    assert sol.xs.shape == (2, 3) and sol.status.shape == ()
    many = integrate(SE, x0[None], 0.1, 40, progress=False)
    np.testing.assert_array_equal(sol.xs, many.xs[0])
    np.testing.assert_array_equal(sol.steps, [0, 40])


def test_chunked_and_unchunked_runs_agree_bitwise():
    x0 = _x0(11, seed=3)
    full = integrate(SE, x0, 0.1, 37, save_every=4, progress=False)
    part = integrate(SE, x0, 0.1, 37, save_every=4, chunk_size=3, progress=False)  # 4 chunks, padded
    np.testing.assert_array_equal(part.xs, full.xs)
    np.testing.assert_array_equal(part.status, full.status)
    seg = integrate(SE, x0, 0.1, 37, save_every=4, segment_blocks=3, chunk_size=3, progress=False)
    np.testing.assert_array_equal(seg.xs, full.xs)


def test_failed_newton_particle_is_frozen_and_reported():
    # particle 2 has no solution at once (|x₁| ≥ π/2); particle 1 fails in its second step, where
    # Newton on atan from the guess X₃ = x₃ ≈ 2.57 diverges
    x0 = np.array([[0.1, 0.2, 0.3], [1.2, 0.2, 0.3], [2.0, 0.2, 0.3], [-0.3, 0.5, 0.2]])
    n = 6
    sol = integrate(ATAN, x0, 1.0, n, save_every=1, progress=False)
    # the truth, by stepping each particle until its first failure
    for i in range(4):
        x, fail = x0[i], -1
        states = [x]
        for k in range(n):
            X, st = ATAN.step_with_status(jnp.asarray(x), 1.0)
            if int(st) != RESULTS.successful:
                fail = k
                expected_status = int(st)
                break
            x = np.asarray(X)
            states.append(x)
        assert sol.failed_step[i] == fail
        if fail >= 0:
            assert sol.status[i] == expected_status != 0
            # frozen at its last good state for the rest of the run
            np.testing.assert_allclose(sol.xs[i, fail:], np.broadcast_to(states[-1], (n + 1 - fail, 3)),
                                       rtol=0, atol=1e-15)
        else:
            assert sol.status[i] == 0
    assert sol.failed_step[1] == 1 and sol.failed_step[2] == 0
    assert np.all(np.isfinite(sol.xs))  # never NaN
    assert sol.n_failed == 2 and not sol.ok
    with pytest.raises(vpforms.VPFormsError):
        sol.raise_for_status()
    # the failures do not touch the other particles
    good = integrate(ATAN, x0[[0, 3]], 1.0, n, save_every=1, progress=False)
    np.testing.assert_array_equal(good.xs, sol.xs[[0, 3]])


def test_rk4_baseline_and_save(tmp_path):
    x0 = _x0(3)
    sol = integrate(RK4(abc), x0, 0.05, 20, save_every=10, progress=False)
    x = jnp.asarray(x0)
    rk = RK4(abc)
    for _ in range(20):
        x = rk.step(x, 0.05)
    np.testing.assert_allclose(sol.x_final, np.asarray(x), rtol=0, atol=1e-13)
    path = tmp_path / "run.npz"
    sol.save(str(path))
    with np.load(path) as d:
        np.testing.assert_array_equal(d["xs"], sol.xs)
        assert int(d["n_steps"]) == 20 and str(d["method"]).startswith("RK4")
    s = sol.summary()
    assert s["particles"] == 3 and s["failed particles"] == 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(x0=np.zeros((2, 2))), "shape"),
        (dict(x0=np.array([np.nan, 0, 0])), "NaN"),
        (dict(h=0.0), "h must"),
        (dict(n_steps=-1), "n_steps"),
        (dict(save_every=0), "save_every"),
        (dict(chunk_size=0), "chunk_size"),
        (dict(t0=float("nan")), "t0"),
        (dict(n_steps=2.5), "n_steps"),
        (dict(h=float("inf")), "h must"),
    ],
)
def test_bad_arguments(kwargs, match):
    args = dict(x0=np.zeros(3), h=0.1, n_steps=3)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        integrate(SE, args.pop("x0"), args.pop("h"), args.pop("n_steps"), progress=False, **args)
    with pytest.raises(TypeError):
        integrate(object(), np.zeros(3), 0.1, 3)


def test_nonfinite_step_reported_as_success_still_freezes_the_particle():
    # a user method that returns NaN with status 0 (x₁ > 1): the particle must freeze with the
    # nonfinite code, not carry NaN through the run
    class Sloppy:
        def step_with_status(self, x, h):
            X = x + h * jnp.array([1.0, 0.0, 0.0])
            return jnp.where(x[0] > 1.0, jnp.nan, X), jnp.int32(0)

    x0 = np.array([[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0]])
    sol = integrate(Sloppy(), x0, 0.25, 12, save_every=1, progress=False)
    assert np.all(np.isfinite(sol.xs))
    assert sol.status[0] == RESULTS.nonfinite and sol.status[1] == 0
    # x₁ = 0.25 n: the step from x₁ = 1.25 (n = 5) is the first to give NaN
    assert sol.failed_step[0] == 5
    np.testing.assert_allclose(sol.xs[0, 5:, 0], 1.25)

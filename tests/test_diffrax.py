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
    # bare (recover=False): recovery through diffrax is tested below; a recovering method compiles
    # all its alternatives into the diffrax step (see the module docstring of vpforms.diffrax)
    return vpforms.scheme(vpforms.problems.get("abc").field, recover=False)


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


# --------------------------------------------------------------------------------------------
# issue #11 item 2: compositions, the generic engine, failures, recovery, events
# --------------------------------------------------------------------------------------------
from vpforms import RECOVERY, RESULTS  # noqa: E402
from vpforms._methods.recover import Recovering  # noqa: E402

ABC = vpforms.problems.get("abc").field


def _solve(m, y0, h, n, **kw):
    """diffeqsolve with VPSolver(m) on [0, n h], saving at every step time."""
    ts = jnp.arange(n + 1) * h
    return diffrax.diffeqsolve(field_term(m), VPSolver(m), 0.0, n * h, h, jnp.asarray(y0),
                               saveat=diffrax.SaveAt(ts=ts), **kw)


def test_order4_composition_same_numbers_as_integrate():
    m4 = vpforms.compose(vpforms.scheme(ABC, "SE+SE", recover=False), 4)
    y0, h, n = np.array([0.1, 0.2, 0.3]), 0.1, 20
    sol = _solve(m4, y0, h, n)
    assert VPSolver(m4).order(None) == 4
    assert sol.result == diffrax.RESULTS.successful
    for backend in ("jax", "auto"):  # "auto" may run the native C kernel: the same map
        ref = vpforms.integrate(m4, y0, h, n, save_every=1, backend=backend)
        assert ref.ok
        assert np.max(np.abs(np.asarray(sol.ys) - ref.xs)) <= 1e-13


@pytest.mark.parametrize("cls", ["DL+DL", "SE+DL"])
def test_generic_engine_methods_vmapped(cls):
    # two Newton solves per step through GeneratingMap (not the SE+SE closed form).  h = 1/8: the
    # step times are exact, so diffrax's t_{n+1} − t_n is exactly h (with h = 0.1 it differs from
    # h by rounding, and a Newton-solved step can then differ at its tolerance, ~1e-13 per step)
    m = vpforms.scheme(ABC, cls, recover=False)
    Y0 = np.array([[0.1, 0.2, 0.3], [1.0, -0.5, 2.0], [3.0, 1.0, 0.2]])
    h, n = 0.125, 10
    ts = jnp.arange(n + 1) * h
    sol = jax.jit(jax.vmap(lambda y0: diffrax.diffeqsolve(
        field_term(m), VPSolver(m), 0.0, n * h, h, y0, saveat=diffrax.SaveAt(ts=ts))))(jnp.asarray(Y0))
    ref = vpforms.integrate(m, Y0, h, n, save_every=1, backend="jax")
    assert ref.ok and np.all(np.asarray(sol.result._value) == diffrax.RESULTS.successful._value)
    assert np.max(np.abs(np.asarray(sol.ys) - ref.xs)) <= 1e-13


@pytest.fixture(scope="module")
def dl_failures():
    """Bare DL+DL (engine form) on ABC, h = 0.5 (exact step times): points of a fixed random cloud
    whose run fails (twist failure) at a step ≥ 2, and integrate's solution for them."""
    m, h, n = vpforms.scheme(ABC, "DL+DL", recover=False, fast=False), 0.5, 12
    x = np.random.default_rng(1).uniform(0.0, 2 * np.pi, (32, 3))
    ref = vpforms.integrate(m, x, h, n, save_every=1, backend="jax")
    idx = np.flatnonzero((ref.status != RESULTS.successful) & (ref.failed_step >= 2))
    assert idx.size >= 2, "the test needs bare failures after a few good steps"
    return m, h, n, x[idx], ref, idx


@pytest.mark.parametrize("kind", ["twist", "newton"])
def test_failure_maps_to_results_like_integrate(kind, dl_failures):
    if kind == "twist":  # bare DL+DL on ABC with a large step: twist failures (status 1)
        m, h, n, pts, ref, idx = dl_failures
        code, i = RESULTS.twist_failure, idx[0]
        y0, status, failed, xs = pts[0], ref.status[i], ref.failed_step[i], ref.xs[i]
    else:  # one Newton iteration cannot converge (status 2) on the first step
        m, h, n, code = vpforms.scheme(ABC, "SE+SE", recover=False, newton=dict(max_iter=1)), 0.1, 5, \
            RESULTS.not_converged
        y0 = np.array([0.1, 0.2, 0.3])
        r = vpforms.integrate(m, y0, h, n, save_every=1, backend="jax")
        status, failed, xs = r.status, r.failed_step, r.xs
    assert status == code
    sol = _solve(m, y0, h, n, throw=False)
    assert sol.result == diffrax.RESULTS.nonlinear_divergence
    assert int(sol.stats["num_steps"]) == failed + 1  # diffrax stops at the failed step
    ys = np.asarray(sol.ys)
    # the states up to and including the frozen one after the failed step are integrate's
    assert np.max(np.abs(ys[: failed + 2] - xs[: failed + 2])) <= 1e-13
    assert np.array_equal(ys[failed + 1], ys[failed]) and np.array_equal(xs[failed + 1], xs[failed])
    assert np.all(np.isinf(ys[failed + 2:]))  # diffrax's fill for save times never reached
    with pytest.raises(Exception, match="(?i)nonlinear solve diverged"):
        _solve(m, y0, h, n, throw=True)


class _NaNAfter:
    """A user method whose step becomes NaN after t ≥ 3 steps of x ↦ x + h but says 'success'."""

    order = 1

    def step_with_status(self, x, h):
        X = jnp.where(x[0] >= 0.3 - 1e-12, jnp.nan, x + h)
        return X, jnp.int32(0)


def test_nonfinite_success_is_nonfinite_like_integrate():
    m, y0, h, n = _NaNAfter(), np.zeros(3), 0.1, 6
    ref = vpforms.integrate(m, y0, h, n, save_every=1)
    assert ref.status == RESULTS.nonfinite and ref.failed_step == 3
    ts = jnp.arange(n + 1) * h
    sol = diffrax.diffeqsolve(diffrax.ODETerm(lambda t, y, a: jnp.ones(3)), VPSolver(m), 0.0, n * h, h,
                              jnp.asarray(y0), saveat=diffrax.SaveAt(ts=ts), throw=False)
    assert sol.result == diffrax.RESULTS.nonfinite
    ys = np.asarray(sol.ys)
    assert not np.any(np.isnan(ys))  # never NaN: frozen, then diffrax's inf fill
    assert np.max(np.abs(ys[:5] - ref.xs[:5])) <= 1e-13


def test_recovering_method_same_numbers_as_integrate(dl_failures):
    # the structure scheme(recover=True) builds (bare + alternatives), with one cheap alternative:
    # integrate recovers lazily on the host, VPSolver inside the jitted step; same numbers
    bare, h, n, pts, _, _ = dl_failures
    rec = Recovering(bare, [(vpforms.scheme(ABC, "SE+SE", recover=False), RECOVERY.other_class)])
    ref = vpforms.integrate(rec, pts[:2], h, n, save_every=1, backend="jax")
    assert ref.ok and np.all(ref.recovered > 0)  # every bare failure was recovered
    for y0, xs in zip(pts[:2], ref.xs):  # one compilation, two solves
        sol = _solve(rec, y0, h, n)
        assert sol.result == diffrax.RESULTS.successful
        assert np.max(np.abs(np.asarray(sol.ys) - xs)) <= 1e-13


@pytest.mark.slow
def test_default_recovering_scheme_same_numbers_as_integrate(dl_failures):
    # scheme()'s own recovery (recover=True; other classes skipped to bound the compile time)
    _, h, n, pts, _, _ = dl_failures
    rec = vpforms.scheme(ABC, "DL+DL", recover_classes=False, recover_substeps=1, fast=False)
    ref = vpforms.integrate(rec, pts[0], h, n, save_every=1, backend="jax")
    assert ref.ok and ref.recovered > 0
    sol = _solve(rec, pts[0], h, n)
    assert sol.result == diffrax.RESULTS.successful
    assert np.max(np.abs(np.asarray(sol.ys) - ref.xs)) <= 1e-13


def test_event_is_the_chord_crossing():
    optx = pytest.importorskip("optimistix")
    from vpforms.diagnostics import poincare_section

    m = vpforms.scheme(ABC, "SE+SE", recover=False)
    y0, h, level = np.array([0.1, 0.2, 0.3]), 0.1, 1.0
    sec = poincare_section(m, y0, h, 200, axis=2, value=level, direction=1, interpolation="linear")
    assert sec.t.size >= 1
    cond = lambda t, y, args, **kw: y[2] - level  # noqa: E731
    # with a root finder: the root on the linear dense output = the chord crossing
    ev = diffrax.Event(cond, root_finder=optx.Newton(rtol=1e-14, atol=1e-14), direction=True)
    sol = diffrax.diffeqsolve(field_term(m), VPSolver(m), 0.0, 20.0, h, jnp.asarray(y0), event=ev)
    assert sol.result == diffrax.RESULTS.event_occurred
    assert abs(float(sol.ts[-1]) - sec.t[0]) <= 1e-13
    assert np.max(np.abs(np.asarray(sol.ys[-1]) - sec.points[0])) <= 1e-13
    # without one: the solve ends at the end of the step in which the sign changed
    ev = diffrax.Event(lambda t, y, args, **kw: y[2] > level)
    sol = diffrax.diffeqsolve(field_term(m), VPSolver(m), 0.0, 20.0, h, jnp.asarray(y0), event=ev)
    n1 = int(sec.step[0]) + 1
    ref = vpforms.integrate(m, y0, h, n1, backend="jax")
    assert abs(float(sol.ts[-1]) - n1 * h) <= 1e-13
    assert np.max(np.abs(np.asarray(sol.ys[-1]) - ref.x_final)) <= 1e-13

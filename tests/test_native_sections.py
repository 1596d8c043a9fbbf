"""Native Poincaré sections (issue #21 item 1, native part): the kernel's ``vp_sections`` records the
steps where a line crosses the section surface, and only those steps are located on the method's
step family. The sections equal the JAX ones (same crossings, points ≤ 1e-10), frozen and recovered
lines included, and a full event buffer re-runs its segment instead of dropping crossings.

Every reference is the JAX section of the same method (or, for the recovered steps, the JAX
surface's crossing test on the native trajectory): nothing is pasted.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import vpforms as vp
from vpforms import RESULTS, problems
from vpforms.backends import NativeUnavailableError
from vpforms.backends.native import events as nevents
from vpforms.backends.native.events import run_events
from vpforms.diagnostics import poincare_section
from vpforms.diagnostics._native_section import _crossing, native_locator, surface_spec
from vpforms.diagnostics._surfaces import Plane
from vpforms.diagnostics.poincare import _located
from vpforms.fieldlines import toroidal_section

from .test_native import _Fake

_OK, _WHY = vp.native.available()
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


@pytest.fixture(scope="module", autouse=True)
def _cache(isolated_native_cache):
    return isolated_native_cache


@pytest.fixture(scope="module")
def abc():
    prob = problems.get("abc")
    return vp.compose(vp.scheme(prob.field, "SE+SE"), 2), prob.initial_conditions(60, seed=3)


@pytest.fixture(scope="module")
def tokamak():
    return problems.get("tokamak", coordinates="toroidal")


@pytest.fixture(scope="module")
def capped(tokamak):
    """SE+SE on the toroidal tokamak, Newton capped at 4 iterations, no recovery: every step
    converges at h = 0.05, lines fail at h = 0.5 (one kernel and one location compile for both)."""
    return vp.scheme(tokamak.field, "SE+SE", newton={"max_iter": 4}, recover=False)


def _same(a, b, tol=1e-10):
    """Native section a equals JAX section b: the same crossings (particle, step, counts, dropped,
    statuses), the points and θ to ``tol``."""
    assert a.backend == "native" and b.backend == "jax", (a.backend_reason, b.backend_reason)
    assert a.points.shape == b.points.shape and a.points.shape[0] > 0
    for f in ("particle", "step", "counts", "status", "fallback"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert a.dropped == b.dropped
    assert np.max(np.abs(a.points - b.points)) <= tol
    assert np.max(np.abs(a.theta - b.theta)) <= tol
    assert np.max(np.abs(a.t - b.t)) <= tol * (1 + np.max(np.abs(b.t)))


@pytest.mark.parametrize("kw", [
    {"axis": 2, "value": 0.3, "period": 2 * math.pi, "direction": 1},
    {"axis": 0, "value": 1.0, "direction": 0},  # one plane, both directions
    {"axis": 1, "value": 0.5, "period": 2 * math.pi, "direction": -1, "max_crossings": 2},
    {"axis": 2, "value": 0.3, "period": 2 * math.pi, "direction": 0, "interpolation": "linear"},
], ids=["x3-periodic-up", "x1-plane-both", "x2-down-capped", "linear"])
def test_abc_plane_section_native_equals_jax(abc, kw):
    m, x0 = abc
    a = poincare_section(m, x0, 0.1, 200, backend="native", progress=False, **kw)
    b = poincare_section(m, x0, 0.1, 200, backend="jax", progress=False, **kw)
    _same(a, b)
    if "max_crossings" in kw:
        assert a.dropped > 0 and np.all(np.bincount(a.particle) <= kw["max_crossings"])


def test_auto_picks_native_where_integrate_does(abc):
    m, x0 = abc
    a = poincare_section(m, x0[:4], 0.1, 20, progress=False)
    assert a.backend == "native" and a.backend_reason == "auto: native available"


@pytest.mark.parametrize("which", ["SE+SE", pytest.param("order 2", marks=pytest.mark.slow)])  # slow: ~15 s
def test_tokamak_phi_section_native_equals_jax(tokamak, capped, which):
    m = capped if which == "SE+SE" else vp.compose(vp.scheme(tokamak.field, "SE+SE"), 2)
    a = toroidal_section(m, tokamak.x0, 0.05, 600, phi=0.7, backend="native", progress=False)
    b = toroidal_section(m, tokamak.x0, 0.05, 600, phi=0.7, backend="jax", progress=False)
    _same(a.section, b.section)
    for f in ("R", "Z", "phi", "t"):
        assert np.max(np.abs(getattr(a, f) - getattr(b, f))) <= 1e-10, f
    np.testing.assert_array_equal(a.transit, b.transit)


@pytest.mark.slow  # ~10 s: another kernel and its JAX compiles
def test_cartesian_phi_half_planes_native_equal_jax():
    """The half-planes φ = atan2(x₂, x₁) = φ₀ (mod 2π/nfp) of Cartesian points: the lifted angle."""
    prob = problems.get("tokamak", eps=0)
    m = vp.compose(vp.scheme(prob.field, "SE+SE"), 2)
    a = toroidal_section(m, prob.x0, 0.05, 300, phi=0.7, nfp=2, backend="native", progress=False)
    b = toroidal_section(m, prob.x0, 0.05, 300, phi=0.7, nfp=2, backend="jax", progress=False)
    _same(a.section, b.section)


def test_frozen_lines_native_equal_jax(tokamak, capped):
    """Newton capped at 4 iterations, h = 0.5, no recovery: lines fail at different steps and are
    frozen; their crossings before the failure, and their statuses, are the JAX ones."""
    m = capped
    a = toroidal_section(m, tokamak.x0, 0.5, 150, phi=0.3, backend="native", progress=False)
    b = toroidal_section(m, tokamak.x0, 0.5, 150, phi=0.3, backend="jax", progress=False)
    assert np.any(b.status != RESULTS.successful) and np.any(b.status == RESULTS.successful)
    assert np.any(b.section.counts[b.status != RESULTS.successful] > 0)  # crossings before failing
    _same(a.section, b.section)


@pytest.mark.slow  # ~60 s: the JAX section compiles the recovering alternatives into its scan
def test_recovered_lines_native_equal_jax(tokamak):
    """The same run with recovery (sub-steps): the native runner recovers the failed steps through
    JAX and the section is the JAX recovering one (its crossings located on the recovering family)."""
    m = vp.scheme(tokamak.field, "SE+SE", newton={"max_iter": 4}, recover_classes=False, recover_substeps=2)
    sol = vp.integrate(m, tokamak.x0, 0.5, 150, backend="native", progress=False)
    assert np.sum(sol.recovered) > 0 and np.all(sol.status == 0)
    a = toroidal_section(m, tokamak.x0, 0.5, 150, phi=0.3, backend="native", progress=False)
    b = toroidal_section(m, tokamak.x0, 0.5, 150, phi=0.3, backend="jax", progress=False)
    _same(a.section, b.section)


def test_recovered_steps_are_checked_for_crossings():
    """The fake method's bare step fails from some step on; every later step is recovered through
    JAX (x₁ += h) and crosses a plane x₁ = 0.5 (mod 1). The recorded crossings are exactly those the
    JAX surface test finds on the native trajectory, step by step."""
    m, h, n = _Fake(), 1.0, 15
    x0 = np.array([[700.0, 0.2, 0.0], [0.0, 0.0, 0.0]])
    surface = Plane(0, 0.5, 1.0)
    c = run_events(m, x0, h, n, surface_spec(surface), 0, lambda x, X: _crossing(surface, 0, x, X)[0])
    assert c.recovered[0] > 0 and np.all(c.status == 0)
    traj = vp.integrate(m, x0, h, n, save_every=1, backend="native", progress=False).xs
    want = [(i, k) for i in range(2) for k in range(n) if _crossing(surface, 0, traj[i, k:k + 1], traj[i, k + 1:k + 2])[0][0]]
    assert [(int(i), int(k)) for i, k in zip(c.line, c.step)] == want
    assert any(k >= n - c.recovered[0] for i, k in want if i == 0)  # some on recovered steps
    np.testing.assert_array_equal(c.before, traj[c.line, c.step])
    np.testing.assert_array_equal(c.after, traj[c.line, c.step + 1])


def test_full_buffer_reruns_the_segment(abc, monkeypatch):
    """A buffer of one crossing overflows in every call: the kernel says how many it found, the
    segment is run again with room for them, and nothing is dropped — the same crossings, bit for
    bit, as with room to spare; through poincare_section too."""
    m, x0 = abc
    surface = Plane(2, 0.3, 2 * math.pi)
    spec = surface_spec(surface)
    roomy = run_events(m, x0, 0.1, 200, spec, 0, lambda x, X: _crossing(surface, 0, x, X)[0])
    tight = run_events(m, x0, 0.1, 200, spec, 0, lambda x, X: _crossing(surface, 0, x, X)[0], capacity=1)
    assert roomy.reruns == 0 and tight.reruns > 0 and roomy.line.size > 1
    for f in ("line", "step", "before", "after", "status", "x"):
        np.testing.assert_array_equal(getattr(tight, f), getattr(roomy, f), err_msg=f)

    seen = []
    orig = nevents.run_events

    def small(*a, **k):
        out = orig(*a, **{**k, "capacity": 1})
        seen.append(out.reruns)
        return out

    monkeypatch.setattr("vpforms.diagnostics._native_section.run_events", small)
    a = poincare_section(m, x0, 0.1, 200, axis=2, value=0.3, period=2 * math.pi, backend="native", progress=False)
    b = poincare_section(m, x0, 0.1, 200, axis=2, value=0.3, period=2 * math.pi, backend="jax", progress=False)
    assert seen and seen[0] > 0
    _same(a, b)


def test_unsupported_method_falls_back_with_the_reason():
    prob = problems.get("lotka_volterra")
    m = vp.scheme(prob.field, "DL+DL", recover=False, fast=False)  # the engine form: not generated natively
    a = poincare_section(m, prob.x0, 0.05, 20, axis=0, value=1.0, direction=0, progress=False)
    assert a.backend == "jax" and a.backend_reason.startswith("auto: native not used (")
    with pytest.raises(NativeUnavailableError, match="native backend cannot run"):
        poincare_section(m, prob.x0, 0.05, 20, axis=0, value=1.0, backend="native", progress=False)
    with pytest.raises(ValueError, match="backend must be one of"):
        poincare_section(m, prob.x0, 0.05, 20, backend="gpu", progress=False)


def test_no_compiler_falls_back_to_jax(abc, monkeypatch):
    m, x0 = abc
    monkeypatch.setenv("VPFORMS_NATIVE_DISABLE", "1")
    a = poincare_section(m, x0[:3], 0.1, 20, progress=False)
    assert a.backend == "jax" and "native not used" in a.backend_reason


def test_native_locator_leaves_failing_steps_to_the_jax_locator(tokamak, capped):
    """vp_locate flags a crossing whose step family fails somewhere as undecided; those go to the
    JAX locator, which owns the fallback rules, and the merged result is the all-JAX one: points, θ
    and fallback flags. Here (Newton capped at 4 iterations, h = 0.5) the sub-steps θh of line 4
    fail from θ = 0.9 on, and its level is put 95 % of the way along its step."""
    h = 0.5
    x = vp.integrate(capped, tokamak.x0, h, 1, save_every=1, backend="native", progress=False).xs[:, 1]
    X, st = (np.asarray(v) for v in capped.step_with_status(jnp.asarray(x), h))  # what the JAX locator takes
    s90 = np.asarray(capped.step_with_status(jnp.asarray(x), 0.9 * h)[1])
    assert s90[4] != 0 and np.all(st[:3] == 0) and np.all(np.isfinite(X))
    lvl = x[:, 1] + np.array([0.5, 0.5, 0.5, 0.5, 0.95]) * (X[:, 1] - x[:, 1])
    surface = Plane(1, 0.0, 2 * math.pi)
    Y, th, undecided = native_locator(capped, h, surface)(x, X, lvl)
    assert list(undecided[:3]) == [False] * 3 and undecided[4]
    args = (capped, surface, "step", 0, h, 0.0, {"axis": 1, "value": 0.0, "period": 2 * math.pi}, "native", "",
            capped, x, np.ones(5, np.int64), lvl, np.arange(5), np.ones(5, np.int64), np.ones(5, np.int64), st)
    a = _located(*args, native=(Y, th, undecided))
    b = _located(*args)
    assert np.max(np.abs(a.points - b.points)) <= 1e-10 and np.max(np.abs(a.theta - b.theta)) <= 1e-10
    np.testing.assert_array_equal(a.fallback, b.fallback)
    assert np.all(a.points[~undecided, 1] == lvl[~undecided])  # the decided ones: on the plane

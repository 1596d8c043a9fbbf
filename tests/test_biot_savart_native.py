"""The native Biot–Savart evaluator (``CoilSet.evaluate``, :mod:`vpforms.backends.native.biot_savart`;
issue #38 item 2): equal to the JAX segments (themselves checked against mpmath in test_coils.py)
near and far from the wires, B equal to the curl of the same A, exact on a 10⁵-sided polygon, and
clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import vpforms as vp
from vpforms.backends.native.biot_savart import evaluate as native_evaluate
from vpforms.coils import Coil, CoilSet, _coilset, device, l2_stellarator
from vpforms.coils._segments import segments_AB

from .test_coils import FAR_AND_NEAR, far_or_near_point

_OK, _WHY = vp.native.available()
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


def _l2_points(n, seed=0):
    rng = np.random.default_rng(seed)
    R, p, Z = rng.uniform(0.8, 1.2, n), rng.uniform(0, 2 * np.pi, n), rng.uniform(-0.2, 0.2, n)
    return np.c_[R * np.cos(p), R * np.sin(p), Z]


@pytest.mark.parametrize("what", ["A", "B"])
def test_native_equals_jax_on_the_l2_coils(what):
    coils = l2_stellarator()
    x = _l2_points(3000)
    got = coils.evaluate(x, what, backend="native")
    ref = coils.evaluate(x, what, backend="jax")
    scale = np.max(np.linalg.norm(ref, axis=1))
    assert got.shape == x.shape and got.dtype == np.float64
    assert np.max(np.abs(got - ref)) <= 1e-13 * scale
    # one point in, one point out
    np.testing.assert_allclose(coils.evaluate(x[7], what), got[7], rtol=0, atol=1e-15 * scale)


@pytest.mark.parametrize("where", FAR_AND_NEAR)
def test_native_keeps_the_cancellation_free_forms(where):
    # -ffast-math must not undo what the JAX forms do far from and near a segment (test_coils.py's
    # mpmath test for the JAX side): the native values equal them to the same 1e-10 / 1e-9
    x, xi, xf, e, n = far_or_near_point(where)
    # a triangle with that segment as one side; far away its three sides' fields cancel to a
    # dipole's, so the rounding is measured against the sides' own sizes (Σ_s |term_s|)
    coils = CoilSet([Coil(np.array([xi, xf, xi + 5 * n + 5 * e]), 2.5e3)])
    starts, ends, currents = (np.asarray(a) for a in coils.segments())
    terms = np.array([segments_AB(x, starts[s:s + 1], ends[s:s + 1], currents[s:s + 1]) for s in range(3)])
    tol = 1e-10 if where.startswith("far") else 1e-9
    for k, what in enumerate(("A", "B")):
        scale = np.abs(terms[:, k]).sum(axis=0)  # (3 sides, [A, B], 3)
        got, ref = coils.evaluate(x, what, backend="native"), coils.evaluate(x, what, backend="jax")
        assert np.all(np.abs(got - ref) <= tol * scale), (got, ref, scale)


def test_closed_form_B_is_the_curl_of_the_native_A():
    coils = l2_stellarator()
    x = _l2_points(500, seed=3)
    dA = native_evaluate(coils, x, "dA")  # [k, j] = ∂_j A_k, from the A loop's derivatives
    curl = np.stack([dA[:, 2, 1] - dA[:, 1, 2], dA[:, 0, 2] - dA[:, 2, 0], dA[:, 1, 0] - dA[:, 0, 1]], axis=-1)
    B = coils.evaluate(x, "B", backend="native")
    assert np.max(np.abs(curl - B)) <= 1e-12 * np.max(np.abs(B))
    # A = (μ0 I/4π) ∮ dl/|x − x'| over closed polylines: ∇·A = −(μ0 I/4π) ∮ d(1/|x − x'|) = 0
    div = dA[:, 0, 0] + dA[:, 1, 1] + dA[:, 2, 2]
    assert np.max(np.abs(div)) <= 1e-10 * np.max(np.abs(dA))


def test_a_polygon_of_1e5_sides_is_exact_at_its_centre_and_bounded_in_memory():
    # B at the centre of a regular n-gon of circumradius r: n sides at distance r cos(π/n), each
    # (μ0 I/4π) 2 sin(π/n)/(r cos(π/n)):  B_z = μ0 I n tan(π/n) / (2π r)
    n, r, current = 100_000, 1.3, 2.0e5
    ang = 2 * np.pi * np.arange(n) / n
    coils = CoilSet([Coil(np.c_[r * np.cos(ang), r * np.sin(ang), np.zeros(n)], current)])
    assert int(coils.segments()[0].shape[0]) == n
    B0 = coils.evaluate(np.zeros(3), "B")
    exact = 4e-7 * np.pi * current * n * np.tan(np.pi / n) / (2 * np.pi * r)
    np.testing.assert_allclose(B0, [0.0, 0.0, exact], rtol=1e-12, atol=1e-12 * exact)
    # 2000 points × 10⁵ segments = 2·10⁸ pairs: nothing stored per pair (the JAX path chunks them)
    x = np.c_[np.linspace(-0.5, 0.5, 2000), np.zeros(2000), np.linspace(-0.3, 0.3, 2000)]
    B = coils.evaluate(x, "B")
    assert np.isfinite(B).all()
    # on the axis of a circular loop: B_z = μ0 I r²/(2 (r² + z²)^{3/2}) (the polygon's O(1/n²) aside)
    z = 0.4
    Bz = coils.evaluate(np.array([0.0, 0.0, z]), "B")[2]
    assert abs(Bz - 4e-7 * np.pi * current * r**2 / (2 * (r**2 + z**2) ** 1.5)) <= 1e-9 * abs(Bz)


def test_bad_input_and_backends(monkeypatch):
    # `import vpforms` (which any `vpforms.coils` import runs first) registers the native path
    assert _coilset.NATIVE["evaluate"] is native_evaluate
    coils = l2_stellarator()
    with pytest.raises(ValueError, match="what must be 'A' or 'B'"):
        coils.evaluate(np.zeros(3), "C")
    with pytest.raises(ValueError, match="backend must be"):
        coils.evaluate(np.zeros(3), backend="gpu")
    with pytest.raises(ValueError, match=r"shape \(3,\) or \(N, 3\)"):
        coils.evaluate(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        coils.evaluate(np.array([1.0, np.nan, 0.0]))
    x = _l2_points(50)
    monkeypatch.setenv("VPFORMS_NATIVE_DISABLE", "1")
    with pytest.raises(RuntimeError, match="not available here: no C compiler"):
        coils.evaluate(x, backend="native")
    # "auto" without a compiler: the JAX evaluation, the same numbers to rounding
    monkeypatch.delenv("VPFORMS_NATIVE_DISABLE")
    native = coils.evaluate(x, "B")
    monkeypatch.setenv("VPFORMS_NATIVE_DISABLE", "1")
    np.testing.assert_allclose(coils.evaluate(x, "B"), native, rtol=0, atol=1e-14 * np.abs(native).max())


@pytest.mark.parametrize("what", ["A", "B"])
def test_current_elements_native_equal_jax(what):
    # W7-X by simsopt's own quadrature rule (QuadratureCoils): the element loop against JAX's
    coils = device("w7x", rule="quadrature")
    rng = np.random.default_rng(5)
    phi = rng.uniform(0, 2 * np.pi, 400)
    R, Z = 5.95 + rng.uniform(-0.4, 0.4, 400), rng.uniform(-0.4, 0.4, 400)
    x = np.c_[R * np.cos(phi), R * np.sin(phi), Z]
    got = coils.evaluate(x, what, backend="native")
    ref = coils.evaluate(x, what, backend="jax")
    assert np.max(np.abs(got - ref)) <= 1e-13 * np.max(np.abs(ref))


@pytest.mark.parametrize("backend", ["native", "jax"])
@pytest.mark.parametrize("what", ["A", "B"])
def test_a_point_on_a_wire_is_named_not_returned_as_inf(backend, what):
    coils = l2_stellarator()
    vertex = np.asarray(coils.segments()[1][0])  # the end of the first segment: on the wire
    x = np.stack([_l2_points(3)[0], vertex])
    with pytest.raises(ValueError, match=r"not finite at the point .* \(1 of 2 points\): it lies on a coil wire"):
        coils.evaluate(x, what, backend=backend)

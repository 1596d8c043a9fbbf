"""Vector potentials as objects (issue #20): the periodic-aware antiderivative, relabelling, and the
pairs of a field given by its vector potential."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vpforms import _config  # noqa: F401
from vpforms._perm import as_perm
from vpforms._vecpot import CallablePotential, VectorPotential, curl_of, periodic_line_integral
from vpforms.fields import Field

PERMS = [(1, 2, 3), (2, 1, 3), (1, 3, 2), (3, 2, 1), (2, 3, 1), (3, 1, 2)]
T = 2 * math.pi / 3


def _A():
    """A deliberately asymmetric potential, 2π/3-periodic in x2."""
    return CallablePotential((
        lambda x, y, z: jnp.sin(3 * y) * z + x * x,
        lambda x, y, z: jnp.cos(z) * x + 0.3 * jnp.sin(x * z),
        lambda x, y, z: x * jnp.cos(3 * y) + z * z * x,
    ), periods=(None, T, None))


@given(k=st.integers(-2000, 2000), r=st.floats(0.0, 1.0), c=st.floats(-3.0, 3.0))
@settings(max_examples=40, deadline=None)
def test_periodic_integral_is_exact_far_from_the_base_point(k, r, c):
    # ∫_c^x (1 + cos²s) ds = 1.5 (x − c) + (sin 2x − sin 2c)/4 for the π-periodic integrand
    f = lambda s: 1.0 + jnp.cos(s) ** 2  # noqa: E731
    x = c + k * math.pi + r * math.pi
    exact = 1.5 * (x - c) + (math.sin(2 * x) - math.sin(2 * c)) / 4
    got = float(periodic_line_integral(f, c, x, math.pi, 32))
    assert abs(got - exact) <= 1e-13 * max(1.0, abs(exact))
    d = float(jax.grad(lambda u: periodic_line_integral(f, c, u, math.pi, 32))(x))
    # the reduction r = x − c − kT is exact to the rounding of x itself (ulp(x) ≈ 2e-16 |x|)
    assert abs(d - (1.0 + math.cos(x) ** 2)) <= 1e-13 + 8 * np.finfo(float).eps * abs(x)


def test_periodic_integral_is_continuous_across_the_seams():
    f = lambda s: jnp.exp(jnp.sin(s))  # noqa: E731
    for k in (1, 7, 400):
        seam = 0.25 + k * T
        lo, hi = (float(periodic_line_integral(f, 0.25, x, T, 32)) for x in (np.nextafter(seam, -1), seam))
        assert abs(hi - lo) <= 1e-12 * abs(hi)


@pytest.mark.parametrize("perm", PERMS)
def test_relabelled_potential_is_the_potential_of_the_relabelled_field(perm):
    """curl Ã = ã with ã(x) = a(x·π⁻¹)·π (prop:trivperm), and its antiderivative along x_k is exact."""
    A, pi = _A(), as_perm(perm)
    curl = jax.jit(jax.vmap(curl_of(A.components())))
    At = A.relabel(pi)
    curl_t = jax.jit(jax.vmap(curl_of(At.components())))
    x = np.random.default_rng(1).uniform(-1, 1, (64, 3))
    idx, inv = list(pi.index), list(pi.inverse().index)
    expect = np.asarray(curl(x[:, inv]))[:, idx]
    np.testing.assert_allclose(np.asarray(curl_t(x)), expect, rtol=0, atol=1e-13)
    assert At.periods == tuple(A.periods[k] for k in idx)
    comps = At.components()
    for k in range(3):
        chi = At.antiderivative(k, 0.3, 32)
        d = jax.vmap(jax.grad(chi, argnums=k))(*x.T)
        np.testing.assert_allclose(np.asarray(d), np.asarray(jax.vmap(comps[k])(*x.T)), atol=1e-13)


@pytest.mark.parametrize("p, q", [((2, 1, 3), (1, 3, 2)), ((2, 3, 1), (2, 3, 1)), ((3, 2, 1), (3, 1, 2))])
def test_relabelling_twice_is_relabelling_the_field_twice(p, q):
    """Ã relabelled by ρ then π is the potential of ã(x) = a(x·π⁻¹)·π applied after ρ's."""
    A = _A()
    curl = jax.vmap(curl_of(A.components()))
    x = np.random.default_rng(2).uniform(-1, 1, (32, 3))

    def relabel(fn, perm):  # x ↦ fn(x·π⁻¹)·π on batches
        idx, inv = list(as_perm(perm).index), list(as_perm(perm).inverse().index)
        return lambda y: np.asarray(fn(y[:, inv]))[:, idx]

    expect = relabel(relabel(curl, p), q)(x)
    got = np.asarray(jax.vmap(curl_of(A.relabel(p).relabel(q).components()))(x))
    np.testing.assert_allclose(got, expect, atol=1e-13)


@pytest.mark.parametrize("splitting", ["se", "dl"])
def test_pairs_of_a_vector_potential_reproduce_the_field_far_along_the_periodic_axis(splitting):
    f = Field.from_vector_potential(_A(), box=((-1, 1), (0, T), (-1, 1)), name="asym")
    assert f.periods == (None, T, None)
    assert "vector potential" in f.potential_methods[splitting]
    assert f.reconstruction_error(splitting) <= 1e-13
    far = np.array([[0.3, 0.2 + 500 * T, -0.4], [-0.7, 1.1 - 3000 * T, 0.9]])
    np.testing.assert_allclose(np.asarray(f.reconstruct(far, splitting)), np.asarray(f(far)), atol=1e-12)


def test_vector_potential_contract_and_bad_input():
    with pytest.raises(NotImplementedError):
        VectorPotential().components()
    with pytest.raises(ValueError, match="three scalar callables"):
        CallablePotential((lambda x, y, z: x,))
    with pytest.raises(ValueError, match="period"):
        CallablePotential((lambda x, y, z: x,) * 3, periods=(None, -1.0, None))
    # a field that is the curl of A is divergence free by construction; its A gives both pairs
    f = Field.from_vector_potential((lambda x, y, z: y * z, lambda x, y, z: 0 * x, lambda x, y, z: x * y))
    assert f.reconstruction_error("se") <= 1e-14 and f.reconstruction_error("dl") <= 1e-14

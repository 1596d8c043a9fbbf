"""A tolerance in, a grid out (issue #39, item 1): vpforms.grids.refine_to_tol and its use by the
coil splines and the φ-time K — the chosen grid's error, measured independently at more points than
the estimate used, is ≤ 3·tol; bad tolerances and budgets are clear errors."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from vpforms.grids import SplinePotential
from vpforms.grids._tolerance import TOL_FLOOR, axis_indicators, check_tol, refine_to_tol, spline_nbytes

BOX = ((0.0, 1.0), (0.0, 2 * np.pi), (-0.5, 0.5))


def _A(x, y, z):
    """A smooth Cartesian-like potential (x, φ, z), 2π-periodic in φ, with its own scales per axis."""
    return jnp.stack([jnp.sin(3 * x) * jnp.cos(y) * jnp.exp(z), jnp.cos(2 * x + z) * jnp.sin(2 * y),
                      jnp.exp(-x) * jnp.cos(4 * z + y)])


def _curl(A):
    J = jax.jacfwd(lambda p: A(p[0], p[1], p[2]))

    def c(p):
        j = J(p)
        return jnp.stack([j[2, 1] - j[1, 2], j[0, 2] - j[2, 0], j[1, 0] - j[0, 1]])

    return jax.jit(jax.vmap(c))


EXACT = _curl(_A)


def _nodes(g):
    return (np.linspace(*BOX[0], g[0]), BOX[1][0] + 2 * np.pi * np.arange(g[1]) / g[1], np.linspace(*BOX[2], g[2]))


def _build(degree):
    def build(g):
        nodes = _nodes(g)
        mesh = np.meshgrid(*nodes, indexing="ij")
        samples = np.asarray(_A(*(jnp.asarray(m) for m in mesh)))
        pot = SplinePotential.from_samples(nodes, samples, periodic=(False, 2 * np.pi, False), degree=degree)
        return pot, samples, None

    return build


def _points(n, seed):
    lo, hi = np.array(BOX).T
    return np.random.default_rng(seed).uniform(lo + [0.05, 0, 0.05], hi - [0.05, 0, 0.05], (n, 3))


def _error(pot, pts):
    exact = np.asarray(EXACT(jnp.asarray(pts)))
    return float(np.max(np.abs(np.asarray(pot.curl(pts)) - exact)) / np.max(np.abs(exact)))


def _spacings(g):
    return (1.0 / (g[0] - 1), 2 * np.pi / g[1], 1.0 / (g[2] - 1))


def _refine(tol, degree=3, **kw):
    check = _points(300, 1)
    return refine_to_tol(_build(degree), lambda pot: _error(pot, check), (8, 8, 8), degree=degree, tol=tol,
                         spacings=_spacings, periodic=(False, True, False), memory=spline_nbytes,
                         n_check=len(check), region="the test box", **kw)


@pytest.mark.parametrize("tol,degree", [(1e-4, 3), (1e-6, 5)])
def test_the_chosen_grid_meets_the_tolerance_where_it_is_measured_independently(tol, degree):
    pot, choice = _refine(tol, degree)
    assert choice.estimate <= tol
    measured = _error(pot, _points(4000, 7))  # other points, more of them
    assert measured <= 3 * tol, (measured, str(choice))
    # every round is reported, the chosen one among them
    assert choice.rounds and choice.rounds[0].grid == (8, 8, 8)
    assert any(r.grid == choice.grid and r.estimate == choice.estimate for r in choice.rounds)
    assert choice.memory == spline_nbytes(pot) > 0
    assert "tol" in str(choice) and choice.table().count("\n") == len(choice.rounds) + 1


def test_a_tighter_tolerance_asks_for_more_nodes():
    _, loose = _refine(1e-3)
    _, tight = _refine(1e-5)
    assert math.prod(tight.grid) > math.prod(loose.grid)
    assert tight.estimate <= 1e-5 and loose.estimate <= 1e-3


def test_axis_indicators_see_which_axis_varies_and_scale_as_h_to_the_degree():
    k = 3
    for a in range(3):
        def f(n):
            x = np.linspace(0.0, 1.0, n)
            shape = [1, 1, 1]
            shape[a] = n
            s = np.broadcast_to(np.sin(5 * x).reshape(shape), tuple(n if i == a else 6 for i in range(3)))
            h = [1.0, 1.0, 1.0]
            h[a] = 1 / (n - 1)
            return axis_indicators(s, h, k, (False, False, False))
        I1, o1 = f(41)
        I2, _ = f(81)
        others = [b for b in range(3) if b != a]
        assert I1[a] > 0 and np.all(I1[others] == 0), I1
        assert o1[a] == k
        assert I1[a] / I2[a] == pytest.approx(2.0 ** k, rel=0.1)  # Δᵏ⁺¹f/h ∝ hᵏ
    # a polynomial of degree ≤ k has nothing to refine
    x = np.linspace(0, 1, 12)
    cubic = np.broadcast_to((x ** 3 - x)[:, None, None], (12, 5, 5))
    assert np.allclose(axis_indicators(cubic, (1 / 11, 1, 1), 3, (False, True, False))[0], 0, atol=1e-9)
    # an axis the field does not differentiate along has order k + 1 (the φ of the φ-time K)
    I, orders = axis_indicators(np.random.default_rng(0).normal(size=(9, 8, 9)), (0.1, 0.1, 0.1), 3,
                                (False, True, False), derivatives=(0, 2))
    assert list(orders) == [3, 4, 3] and np.all(I > 0)


@pytest.mark.parametrize("bad", [0, -1e-6, float("nan"), float("inf"), 1e-16, 1.5, "1e-6", True, None])
def test_a_bad_tolerance_is_one_clear_error(bad):
    with pytest.raises(ValueError, match="tol"):
        check_tol(bad)
    assert TOL_FLOOR <= 1e-12


def test_a_memory_budget_too_small_for_the_tolerance_is_a_clear_error():
    with pytest.raises(MemoryError, match="max_memory"):
        _refine(1e-9, max_memory=200_000)


def test_coil_spline_from_a_tolerance():
    """spline_coil_field(tol=): the l = 2 stellarator's A on a grid chosen for 1e-4 in B on a tube
    about its axis; measured at 4000 other points of the tube."""
    from vpforms.coils import l2_stellarator
    from vpforms.domains import ToroidalDomain
    from vpforms.problems.coil_fields import _spline_error, spline_coil_field

    coils = l2_stellarator()
    tube = ToroidalDomain.tube(lambda p: (np.full_like(p, 0.983112), np.zeros_like(p)), 0.12, nfp=5, name="tube")
    field, _ = spline_coil_field(coils, (0.80, 1.18), (-0.18, 0.18), degree=3, tol=1e-4, region=tube, n_check=400)
    choice = field.grid_choice
    assert choice.estimate <= 1e-4 and "tube" in choice.region
    measured = _spline_error(field, coils, None, None, None, 5, seed=11, n=4000, domain=tube)
    assert measured <= 3e-4, (measured, str(choice))
    with pytest.raises(ValueError, match="tol"):
        spline_coil_field(coils, (0.80, 1.18), (-0.18, 0.18), tol=-1.0)

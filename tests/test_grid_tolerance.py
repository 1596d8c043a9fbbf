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
from vpforms.grids._tolerance import TOL_FLOOR, check_tol, refine_to_tol, spline_nbytes

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


def _sample(A):
    def sample(g):
        nodes = _nodes(g)
        mesh = np.meshgrid(*nodes, indexing="ij")
        return nodes, np.asarray(A(*(jnp.asarray(m) for m in mesh)))

    return sample


def _fit(degree):
    def fit(data, sub):
        nodes, samples = data
        return SplinePotential.from_samples(tuple(x[s_] for x, s_ in zip(nodes, sub)),
                                            samples[(slice(None), *sub)], periodic=(False, 2 * np.pi, False),
                                            degree=degree)

    return fit


def _points(n, seed):
    lo, hi = np.array(BOX).T
    return np.random.default_rng(seed).uniform(lo + [0.05, 0, 0.05], hi - [0.05, 0, 0.05], (n, 3))


def _error(pot, pts, exact=EXACT):
    ex = np.asarray(exact(jnp.asarray(pts)))
    return float(np.max(np.abs(np.asarray(pot.curl(pts)) - ex)) / np.max(np.abs(ex)))


def _refine(tol, degree=3, A=_A, **kw):
    check = _points(300, 1)
    exact = EXACT if A is _A else _curl(A)
    return refine_to_tol(_sample(A), _fit(degree), lambda pot: _error(pot, check, exact), (9, 8, 9),
                         degree=degree, tol=tol, periodic=(False, True, False), memory=spline_nbytes,
                         n_check=len(check), region="the test box", **kw)


@pytest.mark.parametrize("tol,degree", [(1e-4, 3), (1e-6, 5)])
def test_the_chosen_grid_meets_the_tolerance_where_it_is_measured_independently(tol, degree):
    pot, choice = _refine(tol, degree)
    assert choice.estimate <= tol
    measured = _error(pot, _points(4000, 7))  # other points, more of them
    assert measured <= 3 * tol, (measured, str(choice))
    # every round is reported, the chosen one among them
    assert choice.rounds and all(a >= b for a, b in zip(choice.rounds[0].grid, (9, 8, 9)))
    assert any(r.grid == choice.grid and r.estimate == choice.estimate for r in choice.rounds)
    assert choice.memory == spline_nbytes(pot) > 0
    assert "tol" in str(choice) and choice.table().count("\n") == len(choice.rounds) + 1


def test_a_tighter_tolerance_asks_for_more_nodes():
    _, loose = _refine(1e-3)
    _, tight = _refine(1e-5)
    assert math.prod(tight.grid) > math.prod(loose.grid)
    assert tight.estimate <= 1e-5 and loose.estimate <= 1e-3


def test_the_axes_shares_are_measured_so_only_the_axis_that_varies_is_refined():
    """A potential that varies fast along z only: the coarser fits say z holds the error, and the
    chosen grid refines z, not x or φ."""

    def A_z(x, y, z):
        return jnp.stack([jnp.sin(9 * z) + 0 * x, jnp.cos(7 * z) + 0 * y, 0.1 * x + 0 * y])

    pot, choice = _refine(1e-6, 3, A=A_z)
    first = choice.rounds[0].grid
    assert choice.grid[2] > 2 * first[2] and choice.grid[0] <= first[0] + 2 and choice.grid[1] <= first[1] + 2, choice
    assert _error(pot, _points(4000, 3), _curl(A_z)) <= 3e-6


def test_node_counts_keep_a_coarser_grid_with_the_same_ends():
    from vpforms.grids._tolerance import _count, _every_other

    for x in (3.2, 10.0, 17.5):
        assert _count(x, False, 7) % 2 == 1 and _count(x, True, 6) % 2 == 0
        assert _count(x, False, 7) >= max(7, x) and _count(x, True, 6) >= max(6, x)
    assert _every_other(9, False) == slice(0, None, 2) and _every_other(8, False) is None
    assert _every_other(8, True) == slice(0, None, 2) and _every_other(9, True) is None


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


def test_steps_for_tol_meets_the_tolerance_on_the_true_error():
    """Step doubling picks n per period; the error of that n, measured against a run with 8× the
    steps (the true error to ~8⁻ᵖ), is ≤ tol per period; a tighter tol needs more steps."""
    import vpforms
    from vpforms import problems
    from vpforms.diagnostics import steps_for_tol

    prob = problems.get("abc")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    x0 = prob.initial_conditions(4, seed=1)
    T, K = 1.0, 3
    loose = steps_for_tol(m, x0, T, 1e-5, periods=K)
    tight = steps_for_tol(m, x0, T, 1e-8, periods=K)
    assert tight.n > loose.n and loose.estimate <= 1e-5 and tight.estimate <= 1e-8
    for c in (loose, tight):
        got = np.asarray(vpforms.integrate(m, x0, T / c.n, c.n * K, save_every=c.n, progress=False).xs)
        ref = np.asarray(vpforms.integrate(m, x0, T / (8 * c.n), 8 * c.n * K, save_every=8 * c.n,
                                           progress=False).xs)
        per = np.max(np.linalg.norm(got - ref, axis=-1)[:, 1:] / np.arange(1, K + 1))
        assert per <= c.tol, (per, str(c))
        assert per >= c.tol / 100  # not absurdly many steps either
    assert "steps per period" in str(tight)
    with pytest.raises(ValueError, match="tol"):
        steps_for_tol(m, x0, T, 0.0)
    with pytest.raises(ValueError, match="max_n"):
        steps_for_tol(m, x0, T, 1e-14, max_n=64)

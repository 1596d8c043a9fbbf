"""The local quasi-interpolant of vpforms.grids._quasi (issue #38): exact for polynomials of the
spline's degree, local, converging at the spline's order, NaN where a stencil meets a masked node."""

from __future__ import annotations

import numpy as np
import pytest

from vpforms.grids import TensorSpline
from vpforms.grids._quasi import knots_of, quasi_matrix, quasi_reach


def _grid(n=(14, 12, 10), seed=0):
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.0, 1.0, n[0]))
    x[0], x[-1] = 0.0, 1.0  # non-uniform nodes (as u = R²/2 is)
    return x, np.linspace(0.0, 2 * np.pi, n[1], endpoint=False), np.linspace(-1.0, 1.0, n[2])


def _at(s, q):
    return np.asarray(s(q[:, 0], q[:, 1], q[:, 2]))


@pytest.mark.parametrize("k", [3, 5])
def test_polynomials_of_the_degree_are_reproduced(k):
    x, y, z = _grid()
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")

    def f(a, b, c):  # degree k in the two open axes, constant along the periodic one
        return a ** k - 2 * a ** 2 * c + c ** k + 0.5 * a * c ** (k - 1)

    s = TensorSpline.interpolate((x, y, z), f(X, Y, Z), (False, True, False), k, fit="quasi")
    q = np.random.default_rng(1).uniform([0, 0, -1], [1, 2 * np.pi, 1], (300, 3))
    assert np.max(np.abs(_at(s, q) - f(q[:, 0], q[:, 1], q[:, 2]))) < 1e-12


@pytest.mark.parametrize("k", [3, 5])
def test_each_coefficient_uses_the_k_plus_1_nodes_nearest_it(k):
    for period in (None, 2 * np.pi):
        x = np.linspace(0.0, 2 * np.pi, 20, endpoint=period is None)
        t = knots_of(x, k, period)
        W = quasi_matrix(x, t, k, period)
        assert W.shape == (t.size - k - 1, x.size)
        assert np.all(np.count_nonzero(W, axis=1) <= k + 1)
        assert np.allclose(W.sum(axis=1), 1.0, atol=1e-12)  # constants reproduced
        spread = [np.ptp(np.flatnonzero(row)) for row in W[k:-k]] if period is None else []
        assert all(s_ <= k for s_ in spread)
        if period is not None:  # the wrapped coefficients c_{n+j} = c_j
            assert np.allclose(W[x.size:], W[:k], atol=1e-12)


def test_a_spike_stays_local_where_the_interpolant_spreads_it():
    """A value next to a 'wire' (a spike at one node) moves the quasi-interpolant only within its
    stencil; the interpolant moves everywhere along the line (the ringing issue #38 measured)."""
    x = np.linspace(0.0, 1.0, 41)
    y = np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    z = np.linspace(0.0, 1.0, 8)
    v = np.zeros((41, 8, 8))
    v[5] = 1e6  # a singular sample near one end
    q = np.c_[np.linspace(0.6, 0.95, 50), np.full(50, 1.0), np.full(50, 0.5)]  # far from it
    quasi = TensorSpline.interpolate((x, y, z), v, (False, True, False), 5, fit="quasi")
    interp = TensorSpline.interpolate((x, y, z), v, (False, True, False), 5)
    assert np.max(np.abs(_at(quasi, q))) == 0.0
    assert np.max(np.abs(_at(interp, q))) > 1e-6


@pytest.mark.parametrize("k", [3, 5])
def test_converges_at_the_spline_order(k):
    def f(a, b, c):
        return np.sin(3 * a + 0.5) * np.cos(b) * np.exp(0.7 * c)

    q = np.random.default_rng(2).uniform([0.1, 0, -0.9], [0.9, 2 * np.pi, 0.9], (400, 3))
    hs, errs = [], []
    for n in (12, 24, 48):
        x, y, z = np.linspace(0, 1, n), np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(-1, 1, n)
        X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
        s = TensorSpline.interpolate((x, y, z), f(X, Y, Z), (False, True, False), k, fit="quasi")
        hs.append(1.0 / n)
        errs.append(np.max(np.abs(_at(s, q) - f(q[:, 0], q[:, 1], q[:, 2]))))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert slope > k + 1 - 0.5, (slope, errs)


def test_a_masked_node_makes_the_coefficients_of_its_stencil_nan():
    x, y, z = _grid((16, 12, 12))
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
    keep = np.ones(X.shape, bool)
    keep[:3] = False  # the first three R nodes left out
    vals = np.where(keep, X + Z, np.nan)
    s = TensorSpline.interpolate((x, y, z), vals, (False, True, False), 3, mask=keep, fit="quasi")
    c = np.asarray(s.coefficients)
    assert np.all(np.isnan(c[:3])) and np.all(np.isfinite(c[6:]))
    q = np.c_[np.full(20, 0.5 * (x[8] + x[9])), np.linspace(0, 6, 20), np.linspace(-0.9, 0.9, 20)]
    assert np.allclose(_at(s, q), q[:, 0] + q[:, 2], atol=1e-12)  # linear: reproduced where defined
    with pytest.raises(ValueError, match="fit must be"):
        TensorSpline.interpolate((x, y, z), X, (False, True, False), 3, fit="least squares")


def test_w7x_quintic_of_a_on_the_whole_box_is_accurate_inside_the_plasma():
    """W7-X's box holds coil wires (issue #38). Inside the last closed surface the quintic
    quasi-interpolant of A on the whole box is far more accurate than the quintic interpolant
    (which carries the wires' errors along its grid lines) and than the cubic one."""
    from vpforms.coils import device
    from vpforms.problems.coil_fields import _spline_error, spline_coil_field
    from vpforms.problems.devices import divertor_wall, grid_box

    coils = device("w7x", rule="quadrature")
    R, Z = grid_box("w7x")
    plasma = divertor_wall("w7x", 0.29)  # the default domain moved onto the fitted last closed surface
    err = {}
    for degree, fit in ((5, "quasi"), (5, "interpolate"), (3, "interpolate")):
        field, _ = spline_coil_field(coils, R, Z, n_R=48, n_phi=96, n_Z=48, degree=degree, fit=fit, name="w7x")
        err[degree, fit] = _spline_error(field._vector_potentials[0].curl, coils, None, R, Z, 5, domain=plasma, n=1000)
    assert err[5, "quasi"] < err[5, "interpolate"] / 10
    assert err[5, "quasi"] < err[3, "interpolate"] / 2


@pytest.mark.parametrize("k, n, periodic", [(3, 20, False), (5, 48, False), (5, 24, True)])
def test_the_reach_is_how_far_one_sample_moves_the_spline(k, n, periodic):
    """quasi_reach, measured independently: the spline of a unit sample at node m (scipy's BSpline
    of W[:, m]) is non-zero on some cells; the largest distance in nodes from such a cell's nearer
    end to m, over all m, is the reach (periodically on a periodic axis)."""
    from scipy.interpolate import BSpline

    T = 2.0 if periodic else None
    x = T * np.arange(n) / n if periodic else np.sort(np.r_[0.0, 1.0, np.random.default_rng(n).uniform(0, 1, n - 2)])
    t = knots_of(x, k, T)
    W = quasi_matrix(x, t, k, T)
    ends = np.r_[x, x[0] + T] if periodic else x
    frac = np.linspace(0.05, 0.95, 7)
    reach = 0
    for m in range(n):
        s = BSpline(t, W[:, m], k)
        for c in range(ends.size - 1):
            if np.any(s(ends[c] + frac * (ends[c + 1] - ends[c])) != 0):
                d = min(abs(m - c), abs(m - (c + 1)))
                reach = max(reach, min(d, n - d) if periodic else d)
    assert quasi_reach(x, k, T) == reach


def test_w7x_quintic_of_a_on_a_domain_is_the_whole_boxs_there_and_nan_far_from_it():
    """With a domain the quasi-interpolant of A is sampled and fitted only within reach of the cells
    that meet it (plane by plane; quasi_reach nodes, a cube): on the domain its field equals the whole
    box's bit for bit, and far outside it is NaN (not the coils' field: not sampled)."""
    from vpforms.coils import device
    from vpforms.problems.coil_fields import spline_coil_field
    from vpforms.problems.devices import device_domain, grid_box

    coils = device("w7x", rule="quadrature")
    R, Z = grid_box("w7x")
    dom = device_domain("w7x")
    masked, _ = spline_coil_field(coils, R, Z, n_R=48, n_phi=96, n_Z=48, degree=5, fit="quasi", domain=dom, name="m")
    whole, _ = spline_coil_field(coils, R, Z, n_R=48, n_phi=96, n_Z=48, degree=5, fit="quasi", name="w")
    p = dom.sample_points(5000, seed=3)
    b_m, b_w = (np.asarray(f._vector_potentials[0].curl(p)) for f in (masked, whole))
    np.testing.assert_array_equal(b_m, b_w)
    corner = np.array([[0.5 * R[0] ** 2 * 1.0005, 0.3, Z[0] + 0.01]])  # the box's corner, far from the plasma
    assert np.all(np.isnan(np.asarray(masked._vector_potentials[0].curl(corner))))
    assert np.all(np.isfinite(np.asarray(whole._vector_potentials[0].curl(corner))))

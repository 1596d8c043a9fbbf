"""Coil fields traced exactly volume preserving (issue #20): the problems ``coil_stellarator`` and
``coil_tokamak`` (vpforms.problems.coil_fields) — coils → spline of A in (u = R²/2, φ, Z) → B = ∇×A —
stepped by the generating-form methods."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import vpforms
from vpforms import RESULTS, problems
from vpforms.diagnostics.volume import log_det


@pytest.fixture(scope="module")
def stellarator():
    return problems.get("coil_stellarator")


@pytest.fixture(scope="module")
def tokamak():
    return problems.get("coil_tokamak")


def _flow(field, x, h):
    return np.array([solve_ivp(lambda t, y: np.asarray(field(y)), (0, h), xi, method="DOP853",
                               rtol=1e-13, atol=1e-14).y[:, -1] for xi in x])


def _check_method(prob, case, **options):
    """|det J − 1| ≤ 1e-12 over two steps, and one-step error ∝ h² (ratio ≈ 4 as h halves)."""
    m = vpforms.scheme(prob.field, case, recover=False, **options)
    x0 = prob.x0[:3]
    ld = log_det(m, x0, 0.02, 2)
    assert ld.ok and ld.max_abs <= 1e-12, (case, ld.max_abs)
    errs = []
    for h in (0.02, 0.01):
        sol = vpforms.integrate(m, x0, h, 1, progress=False, backend="jax")
        assert np.all(np.asarray(sol.status) == RESULTS.successful)
        errs.append(np.abs(np.asarray(sol.xs)[:, -1] - _flow(prob.field, x0, h)).max())
    assert 3.5 <= errs[0] / errs[1] <= 4.5, (case, errs)


def test_coil_problems_are_registered_with_their_spline_error(stellarator):
    assert problems.coil_names()[:2] == ("coil_tokamak", "coil_stellarator")  # then the devices (#38)
    assert set(problems.coil_names()).isdisjoint(problems.names())
    p = stellarator
    assert p.params["spline_error"] < 1e-3  # the spline of A against the coils' own B
    assert p.field.periods == (None, 2 * np.pi / 5, None)
    assert "spline" in p.field.potential_methods["se"]
    # exact gauge: both pairs reproduce the spline field to rounding
    assert p.field.reconstruction_error("se") <= 1e-12 and p.field.reconstruction_error("dl") <= 1e-12


def test_a_starting_point_off_the_grid_is_refused_by_name(stellarator):
    m = vpforms.scheme(stellarator.field, "SE+SE", recover=False)
    bad = np.array([[0.5 * 1.5**2, 0.0, 0.0]])  # R = 1.5 m: outside the grid's R ≤ 1.18
    with pytest.raises(ValueError, match="outside the grid"):
        vpforms.integrate(m, bad, 0.01, 2, progress=False, backend="jax")


@pytest.mark.slow  # ~40 s: compiling the step, its Jacobian and two step sizes on the spline
def test_se_se_on_the_stellarator_spline_is_volume_preserving_and_consistent(stellarator):
    _check_method(stellarator, "SE+SE")


@pytest.mark.slow
@pytest.mark.parametrize("case", ["DL+DL", "SE+DL", vpforms.Case((2, 3, 1), (3, 1, 2)),
                                  vpforms.Case((1, 3, 2), (2, 1, 3))])
def test_other_classes_and_cases_on_the_stellarator(stellarator, case):
    _check_method(stellarator, case, **({"fast": True} if case in ("DL+DL", "SE+DL") else {}))


@pytest.mark.slow
@pytest.mark.parametrize("cls", ["S1", "S2"])
def test_quispel_correction_classes_on_the_stellarator_spline(stellarator, cls):
    """S1/S2 on a nonlinear field are Quispel's correction maps (their correction integral by
    quadrature here): exactly volume preserving on the spline field too."""
    m = vpforms.scheme(stellarator.field, cls, recover=False)
    ld = log_det(m, stellarator.x0[:2], 0.02, 1)  # one step: S1 measured 9.6e-13 over two
    assert ld.ok and ld.max_abs <= 1e-12, (cls, ld.max_abs)


@pytest.mark.slow  # ~4 GB while compiling (the ring's AGM inside the solves): SE+SE only; the DL
# classes are checked on the stellarator spline above
def test_the_tokamak_spline_plus_exact_ring(tokamak):
    assert tokamak.params["spline_error"] < 1e-3
    _check_method(tokamak, "SE+SE")


@pytest.mark.slow
def test_the_tokamak_problem_traces_the_lines_of_its_coils(tokamak):
    """TF coils → spline of A, + the exact ring → B = ∇×A traces the field lines of the coils
    themselves: RK4 on the problem's field in (u, φ, Z) against DOP853 on the TF coils' Biot–Savart B
    plus the ring's exact B (curl of its elliptic-integral A), in Cartesian coordinates, T = 20 (about
    three toroidal turns); and the same q (Δφ/Δθ about the ring). (The coil set's own 128-gon ring
    differs from the circle by 1.5e-3 in B at 0.2 m: not the reference.)"""
    from vpforms.coils import CoilSet, circular_tokamak
    from vpforms.coils._ring import CircularRingPotential
    from vpforms.problems.coil_fields import _ring_B
    from vpforms.toroidal import from_toroidal, to_toroidal

    coils = circular_tokamak()
    ring = next(c for c in coils if c.name == "plasma")
    tf = CoilSet([c for c in coils if c is not ring])
    ring_B = _ring_B(CircularRingPotential(1.0, float(ring.current)))
    start = np.array([1.2, 0.0, 0.0])
    T, h = 20.0, 0.01
    sol = vpforms.integrate(vpforms.RK4(tokamak.field), np.asarray(to_toroidal(start)), h, int(T / h),
                            save_every=10, progress=False, backend="jax")
    ours = np.asarray(from_toroidal(np.asarray(sol.xs)))
    ref = solve_ivp(lambda t, y: np.asarray(tf.B(y)) + ring_B(y[None])[0], (0, T), start, method="DOP853",
                    rtol=1e-11, atol=1e-12, t_eval=np.linspace(0, T, len(ours))).y.T
    assert np.abs(ours - ref).max() <= 2e-5  # measured 2.3e-6 (the spline's B error: 5.5e-5 of max|B|)

    def q(x):
        R, phi = np.hypot(x[:, 0], x[:, 1]), np.unwrap(np.arctan2(x[:, 1], x[:, 0]))
        theta = np.unwrap(np.arctan2(-x[:, 2], R - 1.0))
        return (phi[-1] - phi[0]) / (theta[-1] - theta[0])

    assert abs(q(ours) - q(ref)) <= 1e-5 * q(ref)


@pytest.mark.slow  # ~40 s: the tokamak problem's spline, one kernel with the ring's elliptic integrals
def test_the_coil_tokamak_with_its_exact_ring_runs_natively(tokamak):
    """The plasma-current ring is exact (elliptic integrals; SymPy's closed-form dK/dm, dE/dm in
    the generated C, the AGM of JAX's ``ellipke`` for the values): SE+SE native == JAX ≤ 1e-10
    after 100 steps, the same statuses — so every problem of the library runs natively."""
    from vpforms.backends.native.codegen.vecpot import vecpot_reason

    assert vecpot_reason(tokamak.field) is None
    m = vpforms.scheme(tokamak.field, "SE+SE", recover=False)
    x0 = tokamak.x0
    sols = [vpforms.integrate(m, x0, 0.02, 100, save_every=50, backend=b, progress=False)
            for b in ("jax", "native")]
    np.testing.assert_array_equal(sols[1].status, sols[0].status)
    assert np.all(sols[0].status == RESULTS.successful)
    np.testing.assert_allclose(sols[1].xs, sols[0].xs, rtol=0, atol=1e-10)
    assert sols[1].stats["backend"] == "native"

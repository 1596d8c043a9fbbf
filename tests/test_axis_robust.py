"""The bounded, robust axis search (issue #41 item 1): the guess refined by orbit averages, damped
Newton with a budget in iterations, and ``on_failure="guess"`` that lets a study go on.

Fast tests run the exactly solvable twist flow of :mod:`tests.test_fieldlines` (the step rotates
(R − R0, Z) along the ellipses (R − R0)²/E² + E²Z² = r² by ι(r)·h): every orbit of its return
map lies on an ellipse *centred at the axis* (R0, 0), so the Birkhoff average of an orbit is the
axis itself — the refinement's expected answer is known without running it. A variant whose
steps fail within a small disc about the axis (as a step beside a current filament does: the
coil tokamak's plasma ring) has no fixed point that Newton can reach: the search must fail
gracefully. The slow tests run real methods on the closed-form tokamak and the l = 2 stellarator's
coils from guesses 5 cm off."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, ConvergenceError, problems
from vpforms.fieldlines import axis_curve, birkhoff_weight, find_fixed_point, magnetic_axis, return_map
from vpforms.fieldlines._axis_search import HALVINGS, search_axis

from .test_fieldlines import R0, E, TwistMethod, iota_of, radius, twist

#: the radius (in the ellipse's r) of the disc about the axis where the "filament" method's steps fail
R_FAIL = 0.02


class FilamentMethod(TwistMethod):
    """The twist flow, but a step from within r < R_FAIL of the axis fails (status not_converged)."""

    def step_with_status(self, x, h):
        X, st = super().step_with_status(x, h)
        R = jnp.sqrt(2.0 * x[0])
        bad = radius(R - R0, x[2]) < R_FAIL
        return X, jnp.where(bad, jnp.int32(RESULTS.not_converged), st)


def _inside(z):
    return 0.5 < z[0] < 1.5 and -0.5 < z[1] < 0.5


def test_a_guess_5cm_off_is_refined_onto_the_axis_then_newton_needs_at_most_two_steps():
    m = TwistMethod()
    P = return_map(m, 0.05, guess=(1.05, 0.02))
    guess = np.array([R0 + 0.04, 0.03])  # 5 cm off
    s = search_axis(P, guess, inside=_inside, scale=1.0)
    # the orbit lies on an ellipse centred at the axis: its weighted mean is the axis
    assert s.rounds >= 1 and np.linalg.norm(s.refined - [R0, 0.0]) <= 1e-4 * np.linalg.norm(guess - [R0, 0.0])
    assert s.converged and s.iterations <= 2 and np.linalg.norm(s.z - [R0, 0.0]) <= 1e-11
    # the budget is in evaluations, not seconds: a second search repeats the first exactly
    s2 = search_axis(P, guess, inside=_inside, scale=1.0)
    assert (s2.evaluations, s2.iterations, s2.rounds) == (s.evaluations, s.iterations, s.rounds)
    assert np.array_equal(s2.z, s.z)
    ax = magnetic_axis(m, tuple(guess), 0.05)
    assert ax.converged and ax.note == "" and ax.kind == "O" and abs(ax.iota - iota_of(0.0)) <= 1e-9
    assert ax.evaluations == s.evaluations


def test_without_refinement_newton_alone_still_converges_within_its_bound():
    m = TwistMethod()
    ax = magnetic_axis(m, (R0 + 0.04, 0.03), 0.05, refine=0, max_iter=30)
    assert ax.converged and math.hypot(ax.R - R0, ax.Z) <= 1e-11 and ax.iterations <= 30


def test_a_failed_search_raises_one_line_or_goes_on_from_the_refined_guess():
    """Steps fail within r < R_FAIL of the axis: Newton cannot reach the fixed point; the refined
    guess (the orbit's centre, the axis to the Birkhoff average's accuracy) is the best point."""
    m = FilamentMethod()
    guess = (R0 + 0.05, 0.0)
    with pytest.raises(ConvergenceError) as err:
        magnetic_axis(m, guess, 0.05)
    msg = str(err.value)
    assert "\n" not in msg and "(1.05, 0)" in msg and "on_failure='guess'" in msg
    assert "fails" in msg or "residual" in msg
    ax = magnetic_axis(m, guess, 0.05, on_failure="guess")
    assert ax.converged is False and ax.kind == "unknown" and math.isnan(ax.iota)
    assert "not converged" in ax.note and "refined guess" in ax.note
    # the refined guess is the weighted mean of the guess's first 32 returns, each the exact
    # rotation by 2π ι(r) along the guess's ellipse (the second round, from there, fails)
    k = np.arange(1, 33)
    dR, Z = twist(guess[0] - R0, guess[1], 2 * np.pi * iota_of(radius(guess[0] - R0, guess[1])) * k)
    w = np.asarray(birkhoff_weight((k - 0.5) / 32))
    expect = np.array([R0 + np.sum(w * dR) / w.sum(), np.sum(w * Z) / w.sum()])
    assert np.linalg.norm([ax.R, ax.Z] - expect) <= 1e-12
    assert math.hypot(ax.R - R0, ax.Z) < 1e-3 * 0.05  # the centre of the ellipse, nearly
    # the work is bounded: ≤ 3 orbits of 32 transits, a Jacobian and (Newton, halvings) evaluations
    assert ax.evaluations <= 3 * 32 + 2 * (30 * (HALVINGS + 2) + 1)


def test_a_guess_where_the_map_fails_outright_is_the_answer_of_on_failure_guess():
    m = FilamentMethod()
    guess = (R0 + 0.5 * R_FAIL * E, 0.0)  # inside the failing disc: no orbit, no Newton
    with pytest.raises(ConvergenceError, match=r"the return map fails from the guess .*Newton iteration did not conv"):
        magnetic_axis(m, guess, 0.05)
    ax = magnetic_axis(m, guess, 0.05, on_failure="guess")
    assert not ax.converged and (ax.R, ax.Z) == guess and math.isnan(ax.residual)


def test_on_failure_is_checked_and_outside_guesses_still_say_outside():
    m = TwistMethod()
    with pytest.raises(ValueError, match="on_failure must be 'raise' or 'guess'"):
        magnetic_axis(m, (1.05, 0.0), 0.05, on_failure="warn")
    with pytest.raises(ValueError, match=r"axis guess.*outside the field's box"):
        magnetic_axis(m, (1.7, 0.0), 0.05, on_failure="guess")  # a usage error, never "not converged"
    with pytest.raises(ValueError, match="refine must be a non-negative integer"):
        magnetic_axis(m, (1.05, 0.0), 0.05, refine=-1)
    with pytest.raises(ValueError, match="transits must be an integer"):
        magnetic_axis(m, (1.05, 0.0), 0.05, transits=2)


def test_plain_newton_from_the_same_guess_converges_to_the_same_point():
    """The refinement changes the start, not the answer: find_fixed_point (Newton alone) agrees."""
    m = TwistMethod()
    P = return_map(m, 0.05, guess=(1.05, 0.0))
    fp = find_fixed_point(P, (R0 + 0.04, 0.03))
    ax = magnetic_axis(m, (R0 + 0.04, 0.03), 0.05)
    assert math.hypot(fp.R - ax.R, fp.Z - ax.Z) <= 1e-11


# ------------------------------------------------------------------ real methods (verification tier)
@pytest.mark.slow
@pytest.mark.parametrize("name", ["tokamak", "coil_stellarator"])
def test_real_fields_from_guesses_5cm_off_find_the_axis_of_the_exact_guess(name):
    """The closed-form tokamak (ε = 0.01) and the l = 2 stellarator's splined coils: the axis from
    guesses 5 cm off (outboard, and inboard-up) equals the axis from the problem's own guess."""
    prob = problems.get(name, **({"coordinates": "toroidal"} if name == "tokamak" else {}))
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    nfp = int(round(2 * math.pi / (prob.field.periods[1] or 2 * math.pi)))
    g = prob.axis_guess
    ref = magnetic_axis(m, g, 0.05, 0.0, nfp)
    assert ref.converged and ref.kind == "O"
    for dR, dZ in ((0.05, 0.0), (-0.035, 0.035)):
        ax = magnetic_axis(m, (g[0] + dR, g[1] + dZ), 0.05, 0.0, nfp)
        assert ax.converged and math.hypot(ax.R - ref.R, ax.Z - ref.Z) <= 1e-9
        assert abs(ax.iota - ref.iota) <= 1e-6
        assert ax.evaluations <= 3 * 32 + 5 * 10 + 30  # refinement + few Newton steps (native: 5 lines a Jacobian)


@pytest.mark.slow
def test_stellarator_axis_curve_passes_through_the_axis_of_every_plane():
    """axis_curve traces the l = 2 stellarator's axis line over one field period (its step count
    from B^φ, extended until the trace covers the period) and fits it in φ: at φ₀ it is the axis
    found there, and a quarter period on it is the axis that Newton finds in that plane from it."""
    prob = problems.get("coil_stellarator")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    nfp = int(round(2 * math.pi / prob.field.periods[1]))
    ax0 = magnetic_axis(m, prob.axis_guess, 0.05, 0.0, nfp)
    curve = axis_curve(m, ax0, 0.05, harmonics=16)
    R0_, Z0_ = (float(v) for v in curve(jnp.asarray(0.0)))
    assert math.hypot(R0_ - ax0.R, Z0_ - ax0.Z) <= 1e-6
    quarter = math.pi / (2 * nfp)  # where the axis is farthest from its φ₀ point (Z ≈ 1.4e-5 m)
    Rq, Zq = (float(v) for v in curve(jnp.asarray(quarter)))
    axq = magnetic_axis(m, (Rq, Zq), 0.05, quarter, nfp)
    assert axq.converged and math.hypot(axq.R - Rq, axq.Z - Zq) <= 1e-6, (axq.R - Rq, axq.Z - Zq)
    assert math.hypot(axq.R - ax0.R, axq.Z - ax0.Z) > 1e-5  # the axis moves more than the tolerance


@pytest.mark.slow
def test_coil_tokamak_whose_axis_is_its_plasma_filament_degrades_gracefully():
    """coil_tokamak's axis is the exact plasma-current ring at (R0, Z0) — a filament, where B and
    the map are singular: from 5 cm off the search cannot converge; on_failure='guess' answers the
    refined guess, much nearer the ring than the guess, and says so."""
    prob = problems.get("coil_tokamak")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    nfp = int(round(2 * math.pi / prob.field.periods[1]))
    ring = np.array(prob.axis_guess)
    ax = magnetic_axis(m, (ring[0] + 0.05, ring[1]), 0.05, 0.0, nfp, on_failure="guess")
    if ax.converged:  # then it must be the ring itself
        assert math.hypot(ax.R - ring[0], ax.Z - ring[1]) <= 1e-3
    else:
        assert "not converged" in ax.note
        assert math.hypot(ax.R - ring[0], ax.Z - ring[1]) <= 0.5 * 0.05

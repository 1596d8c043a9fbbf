"""Tests of the problem library vpforms.problems (issue #4).

Every fact is re-derived here from the problem's own SymPy expressions: exact divergence, closed-form
potentials for both splittings, zero Lie derivative of every invariant, tangency where claimed.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import vpforms.problems as P
from vpforms import Field
from vpforms.fields import SYMBOLS, vf1_expr, vf2_expr, vf3_expr
from vpforms.problems import abc as abc_mod
from vpforms.problems import tokamak as tok_mod

x1, x2, x3 = SYMBOLS
NAMES = P.names()


@pytest.fixture(scope="module", params=NAMES)
def prob(request):
    return P.get(request.param)


def _lie(I, exprs):
    return sp.expand(sum(sp.diff(I, s) * e for s, e in zip(SYMBOLS, exprs)))


def _zero(e):
    e = sp.expand(e)
    return e == 0 or sp.simplify(e) == 0


def test_registry():
    assert set(NAMES) == {"abc", "abc_gi", "linear", "lotka_volterra", "stokes_sphere", "tokamak", "rigid_body"}
    with pytest.raises(KeyError, match="unknown problem"):
        P.get("nope")
    assert P.get("abc") is P.get("abc")  # cached default
    for mod in (P.abc, P.linear, P.lotka_volterra, P.stokes_sphere, P.tokamak, P.rigid_body):
        assert callable(mod.make) and callable(mod.default) and mod.__doc__


def test_problem_record(prob):
    f = prob.field
    assert isinstance(f, Field) and f.exprs is not None
    assert prob.source and isinstance(prob.source, str)
    x0 = np.asarray(prob.x0)
    assert x0.ndim == 2 and x0.shape[1] == 3 and np.all(np.isfinite(x0))
    b = np.asarray(prob.box)
    assert b.shape == (3, 2) and np.all(b[:, 0] < b[:, 1])
    ic = prob.initial_conditions(20, seed=3)
    assert ic.shape == (20, 3)
    np.testing.assert_array_equal(ic, prob.initial_conditions(20, seed=3))
    assert not np.array_equal(ic, prob.initial_conditions(20, seed=4))
    assert np.all((ic >= b[:, 0] - 1e-12) & (ic <= b[:, 1] + 1e-12))
    assert np.all(np.isfinite(np.asarray(f(ic))))
    if prob.periodic is not None:
        assert len(prob.periodic) == 3


def test_divergence_is_exactly_zero(prob):
    div = sum(sp.diff(e, s) for e, s in zip(prob.field.exprs, SYMBOLS))
    assert _zero(div)
    assert prob.field.divergence_check == "symbolic"


@pytest.mark.parametrize("splitting", ["se", "dl"])
def test_closed_form_potentials_both_splittings(prob, splitting):
    f = prob.field
    assert f.potential_methods[splitting] == "closed form"
    Pp, Q = f.se_potential_exprs if splitting == "se" else f.dl_potential_exprs
    u = vf1_expr(Pp)
    v = vf3_expr(Q) if splitting == "se" else vf2_expr(Q)
    assert all(_zero(ui + vi - ai) for ui, vi, ai in zip(u, v, f.exprs))
    # the lambdified potentials, differentiated by JAX, reproduce the field numerically
    assert f.reconstruction_error(splitting, n_points=1000) <= 1e-12


@pytest.mark.parametrize("name", ["tokamak"])  # all problems: notes/issue-4.md
def test_quadrature_potentials_reproduce_problem(name):
    """The same field as a bare JAX callable: Gauss–Legendre potentials (no SymPy)."""
    prob = P.get(name)
    g = Field.from_callable(prob.field, box=prob.box, name=name + "_callable")
    assert g.potential_method.startswith("quadrature")
    for splitting in ("se", "dl"):
        assert g.reconstruction_error(splitting, n_points=1000) <= 1e-12


def test_invariants_have_zero_lie_derivative(prob):
    assert set(prob.invariants) == set(prob.invariant_exprs)
    pts = jnp.asarray(prob.initial_conditions(8, seed=1))
    for k, I in prob.invariant_exprs.items():
        assert _zero(_lie(I, prob.field.exprs)), k
        # the JAX callable is the same function
        fI = sp.lambdify(SYMBOLS, I, "numpy")
        got = np.asarray(jax.vmap(prob.invariants[k])(pts))
        want = np.broadcast_to(np.asarray(fI(*np.asarray(pts).T), dtype=float), (8,))
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)
        vals = prob.invariant_values(pts)[k]
        np.testing.assert_allclose(np.asarray(vals), want, rtol=1e-14, atol=1e-14)


def test_expected_invariants_present():
    assert set(P.get("lotka_volterra").invariant_exprs) == {"sum", "product"}
    assert set(P.get("rigid_body").invariant_exprs) == {"casimir", "energy"}
    assert P.get("abc").invariants == {}  # C ≠ 0: no known invariant
    assert set(P.get("stokes_sphere", eps=0).invariant_exprs) == {"psi"}
    assert set(P.get("tokamak", eps=0).invariant_exprs) == {"psi"}


def test_invariants_of_degenerate_cases_have_zero_lie_derivative():
    for prob in (P.get("abc", C=0), P.get("abc", A=0.5, B=2, C=0), P.get("stokes_sphere", eps=0, Omega=3),
                 P.get("tokamak", eps=0, B0=2)):
        assert prob.invariant_exprs
        for I in prob.invariant_exprs.values():
            assert _zero(_lie(I, prob.field.exprs))
    # and they are NOT invariant once the perturbation is on
    I = P.get("abc", C=0).invariant_exprs["I"]
    assert not _zero(_lie(I, P.get("abc").field.exprs))
    psi = tok_mod.flux_function(1)
    assert not _zero(_lie(psi, P.get("tokamak").field.exprs))


def test_abc_parameters_and_spec_potentials():
    p = P.get("abc")
    A, B, C = sp.Integer(1), sp.sqrt(sp.Rational(2, 3)), sp.sqrt(sp.Rational(1, 3))
    assert p.params == pytest.approx({"A": 1.0, "B": np.sqrt(2 / 3), "C": np.sqrt(1 / 3)}, abs=1e-15)
    want = (A * sp.sin(x3) + C * sp.cos(x2), B * sp.sin(x1) + A * sp.cos(x3), C * sp.sin(x2) + B * sp.cos(x1))
    assert all(sp.simplify(a - b) == 0 for a, b in zip(p.field.exprs, want))
    assert p.periodic == pytest.approx((2 * np.pi,) * 3)
    gi = P.get("abc_gi")
    assert gi.params == {"A": 0.5, "B": 1.0, "C": 1.0}
    # the closed forms printed in MATH.md §3 are valid SE potentials of the library's field
    F1, F3 = abc_mod.spec_se_potentials(A, B, C)
    u, v = vf1_expr(F1), vf3_expr(F3)
    assert all(_zero(ui + vi - ai) for ui, vi, ai in zip(u, v, p.field.exprs))
    # and differ from the computed ones by an SE gauge: curl(ΔF1, 0, ΔF3) = 0
    G1, G3 = p.field.se_potential_exprs
    d1, d3 = sp.expand(F1 - G1), sp.expand(F3 - G3)
    curl = (sp.diff(d3, x2), sp.diff(d1, x3) - sp.diff(d3, x1), -sp.diff(d1, x2))
    assert all(_zero(c) for c in curl)


def test_abc_periodicity():
    p = P.get("abc_gi")
    pts = p.initial_conditions(10, seed=2)
    for ax in range(3):
        shifted = pts.copy()
        shifted[:, ax] += 2 * np.pi
        np.testing.assert_allclose(np.asarray(p.field(shifted)), np.asarray(p.field(pts)), atol=1e-13)


def test_linear_problem():
    p = P.get("linear")
    A = p.field.linear_matrix
    assert A is not None and abs(np.trace(A)) <= 1e-15
    assert A[0, 1] != 0 and A[0, 2] != 0  # S1/S2 recipes need a12, a13 ≠ 0
    np.testing.assert_array_equal(P.get("linear", seed=0).field.linear_matrix, A)
    assert not np.array_equal(P.get("linear", seed=5).field.linear_matrix, A)
    M = np.array([[0.0, 1.0, 2.0], [-1.0, 1.0, 0.5], [0.3, 0.0, -1.0]])
    q = P.get("linear", A=M)
    np.testing.assert_array_equal(q.field.linear_matrix, M)
    pts = q.initial_conditions(5)
    np.testing.assert_allclose(np.asarray(q.field(pts)), pts @ M.T, atol=1e-15)
    with pytest.raises(ValueError, match="tr A"):
        P.get("linear", A=np.eye(3))


def test_stokes_flow_tangent_to_sphere_and_stokes():
    p = P.get("stokes_sphere")
    r2 = x1**2 + x2**2 + x3**2
    radial = sp.expand(sum(s * e for s, e in zip(SYMBOLS, p.field.exprs)))
    q, rem = sp.div(sp.Poly(radial, *SYMBOLS), sp.Poly(1 - r2, *SYMBOLS))
    assert rem.is_zero  # x·a vanishes on the unit sphere: the ball is invariant
    # every component is a quadratic polynomial, and the Stokes equations hold: Δa = ∇p with
    # Δa constant and curl(Δa) = 0
    lap = [sum(sp.diff(e, s, 2) for s in SYMBOLS) for e in p.field.exprs]
    assert all(sp.Poly(e, *SYMBOLS).total_degree() <= 2 for e in p.field.exprs)
    curl = (sp.diff(lap[2], x2) - sp.diff(lap[1], x3), sp.diff(lap[0], x3) - sp.diff(lap[2], x1),
            sp.diff(lap[1], x1) - sp.diff(lap[0], x2))
    assert all(c == 0 for c in curl)
    ic = p.initial_conditions(50)
    assert np.all(np.linalg.norm(ic, axis=1) < 1)


def test_tokamak_structure():
    p = P.get("tokamak")
    R0, B0 = (sp.nsimplify(p.params[k]) for k in ("R0", "B0"))
    B = tok_mod.make(eps=0).field.exprs
    # magnetic axis: on R = R0, x3 = 0 the poloidal field vanishes and B is toroidal, exactly
    phi = sp.Symbol("phi", real=True)
    axis = {x1: R0 * sp.cos(phi), x2: R0 * sp.sin(phi), x3: 0}
    tor = (-B0 * sp.sin(phi), B0 * sp.cos(phi), 0)
    assert all(sp.simplify(e.xreplace(axis) - t) == 0 for e, t in zip(B, tor))
    # axisymmetry of the unperturbed field: the Lie bracket with the rotation generator
    # ξ = (−x2, x1, 0) about the major axis vanishes identically, [ξ, B] = (ξ·∇)B − (B·∇)ξ = 0
    xi = (-x2, x1, sp.Integer(0))

    def bracket(F):
        return [sp.expand(sum(xi[j] * sp.diff(F[i], SYMBOLS[j]) - F[j] * sp.diff(xi[i], SYMBOLS[j])
                              for j in range(3))) for i in range(3)]

    assert bracket(B) == [0, 0, 0]
    assert bracket(p.field.exprs) != [0, 0, 0]  # the (m, n) = (2, 1) perturbation breaks it
    # the perturbation is a smooth polynomial: the field is defined on the axis R = 0
    assert all(e.is_polynomial(*SYMBOLS) for e in p.field.exprs)
    assert np.all(np.isfinite(np.asarray(p.field(np.array([0.0, 0.0, 0.3])))))


def test_rigid_body_problem():
    p = P.get("rigid_body")
    assert p.params == pytest.approx({"I1": 2.0, "I2": 1.0, "I3": 2 / 3})
    ic = p.initial_conditions(30)
    np.testing.assert_allclose(np.linalg.norm(ic, axis=1), 1.0, atol=1e-14)
    # m' = m × I⁻¹ m, re-derived
    I = [2, 1, sp.Rational(2, 3)]
    m = sp.Matrix(SYMBOLS)
    w = sp.Matrix([SYMBOLS[i] / I[i] for i in range(3)])
    want = m.cross(w)
    assert all(_zero(a - b) for a, b in zip(p.field.exprs, want))
    with pytest.raises(ValueError, match="positive"):
        P.get("rigid_body", I1=-1)


def test_bad_parameters():
    with pytest.raises(ValueError):
        P.get("abc", A=sp.Symbol("a"))
    with pytest.raises(ValueError):
        P.get("tokamak", m=0)
    with pytest.raises(ValueError):
        P.get("abc").initial_conditions(-1)


def test_quadrature_potentials_give_exactly_volume_preserving_se_map():
    """MATH.md §3: any potentials give det ≡ 1 if the map differentiates the same functions.

    SE+SE (eq:case5) — the library's one implementation, :class:`vpforms.SESE` on
    :class:`vpforms.GeneratingMap` — driven by the Gauss–Legendre potentials of the ABC flow given
    as a bare callable.
    """
    from vpforms import SESE

    p = P.get("abc")
    g = Field.from_callable(p.field, box=p.box)
    assert g.potential_method.startswith("quadrature")
    h = 0.1
    m = SESE(g).generating_map(h)
    x = jnp.asarray(p.initial_conditions(8, seed=5))
    X = np.asarray(m(x))
    assert np.max(np.abs(np.asarray(m.det(x)) - 1)) <= 1e-13
    # consistent: (X − x)/h = a(x) + O(h)
    a = np.asarray(p.field(x))
    assert np.max(np.abs((X - np.asarray(x)) / h - a)) <= 2 * h * 1.8**2


def test_tokamak_safety_factor_closed_form_matches_a_traced_line():
    """q = 2B0 K(m)/(π R0 a) (problems.tokamak.safety_factor) against the field line traced by
    SciPy: q = Δφ over one poloidal turn / 2π, the turn found as the next upward crossing of x3 = 0
    on the outboard side."""
    from scipy.integrate import solve_ivp

    from vpforms.problems import tokamak

    P = tokamak.make(eps=0)
    f = P.field

    def rhs(t, y):  # the line and its toroidal angle: φ' = (x y' − y x')/(x² + y²)
        a = np.asarray(f(y[:3]))
        return [*a, (y[0] * a[1] - y[1] * a[0]) / (y[0] ** 2 + y[1] ** 2)]

    def up(t, y):
        return y[2]

    up.direction, up.terminal = 1.0, True
    for rho in (0.05, 0.3, 0.4):
        x0 = np.array([1.0 + rho, 0.0, 0.0, 0.0])
        # it leaves x3 = 0 upwards at t = 0 (B_pol·ẑ > 0 outboard): a short first leg, then the
        # next upward crossing ends the turn
        opts = dict(method="DOP853", rtol=1e-11, atol=1e-12)
        y1 = solve_ivp(rhs, (0, 1e-3), x0, **opts).y[:, -1]
        sol = solve_ivp(rhs, (1e-3, 200), y1, events=up, **opts)
        y = sol.y_events[0][0]
        assert abs(np.hypot(y[0], y[1]) - (1 + rho)) < 1e-6  # back on the outboard midplane
        q = y[3] / (2 * np.pi)
        assert abs(q - float(tokamak.safety_factor(rho))) < 1e-6 * q
    with pytest.raises(ValueError, match="0 < ρ"):
        tokamak.safety_factor(0.5)

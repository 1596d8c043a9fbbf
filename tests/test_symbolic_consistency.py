"""Consistency of the recipes, symbolically: M(0) = I, M'(0) = A, order 1, det ≡ 1 — on the generic
traceless matrix, on random integer matrices (hypothesis), for all 36 cases from the five
representatives (prop:trivperm + prop:switchperm), and by series for a nonlinear field."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vpforms import Case, Perm, cases

sym = pytest.importorskip("vpforms.symbolic")
from vpforms.symbolic import recipes as R  # noqa: E402
from vpforms.symbolic._symbols import A as A_SYM  # noqa: E402
from vpforms.symbolic._symbols import X, Y, h, x, y  # noqa: E402
from vpforms.symbolic.errata import correction_map_matrix  # noqa: E402

G = sym.generic_traceless_matrix()


def _recipe(cls: str, M, **kw):
    """The corrected representative recipe of a class for the linear field M x."""
    M = sp.Matrix(M)
    if cls == "S1":
        return R.s1_potentials(kw.get("variant", "quispel"))
    if cls == "S2":
        return R.s2_potentials()
    if cls == "SE+SE":
        return R.se_se_potentials(*R.se_field_potentials(M))
    if cls == "SE+DL":
        return R.se_dl_potentials(*R.dl_field_potentials(M))
    return R.dl_dl_potentials(*R.dl_field_potentials(M), **kw)


GENERIC = [("S1", {"variant": "quispel"}), ("S1", {"variant": "az"}), ("S2", {}), ("SE+SE", {}),
           ("SE+DL", {}), ("DL+DL", {}),
           ("DL+DL", {"theta1": sp.Rational(1, 2), "theta2": sp.Rational(1, 2)})]


@pytest.mark.parametrize("cls,kw", GENERIC, ids=[f"{c}-{k}" for c, k in GENERIC])
def test_corrected_recipes_are_consistent_order_one_det_one_on_generic_A(cls, kw):
    rec = _recipe(cls, G, **kw)
    r = sym.consistency(rec.case, rec.phi, rec.Phi, G, n_terms=2)
    assert r.linear and r.identity_at_0 and r.consistent
    assert r.order == 1  # exactly: the h² coefficient differs from A²/2
    assert r.det_is_one and sp.cancel(r.det - 1) == 0
    assert r.M0 == sp.eye(3)
    assert all(sp.cancel(e) == 0 for e in (r.M1 - G))
    # the opposite sign in volpot2: det = −1, never consistent (the sign rule)
    q = sym.consistency(rec.case, rec.phi, rec.Phi, G, sign=-rec.case.sign)
    assert sp.cancel(q.det + 1) == 0 and not q.consistent


@pytest.mark.parametrize("cls", ["S1", "S2"])
def test_corrected_S1_and_S2_maps_equal_quispels_correction_maps(cls):
    rec = _recipe(cls, G)
    M = sym.consistency(rec.case, rec.phi, rec.Phi, G).M.matrix
    assert all(sp.cancel(e) == 0 for e in (M - correction_map_matrix(cls, G)))


def _traceless_int_matrices(nonzero=((0, 1), (0, 2), (1, 2), (2, 0))):
    ints = st.integers(-4, 4)

    def build(v):
        a = np.array(v[:8] + [0]).reshape(3, 3)
        a[2, 2] = -a[0, 0] - a[1, 1]
        return sp.Matrix(a.tolist())

    return st.lists(ints, min_size=8, max_size=8).map(build).filter(
        lambda M: all(M[i, j] != 0 for i, j in nonzero)
    )


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(M=_traceless_int_matrices())
def test_random_integer_matrices(M):
    for cls, kw in GENERIC:
        rec = _recipe(cls, M, **kw)
        r = sym.consistency(rec.case, rec.phi, rec.Phi, M)
        assert r.consistent and r.det_is_one, (cls, kw, M)


# -- all 36 cases from the five representatives ----------------------------------------------------
def _P(pi: Perm) -> sp.Matrix:
    """x·π = P_π x: the columns of P_π are e_j·π (Perm.act), i.e. (P_π)_{ij} = δ_{j, π(i)}."""
    P = sp.Matrix(pi.act(np.eye(3, dtype=int)).T)
    assert P == sp.Matrix(3, 3, lambda i, j: 1 if j == pi(i + 1) - 1 else 0)
    return P


def _potentials_for(case: Case, A: sp.Matrix):
    """LM potentials for ``case`` and field A x from a class representative, via prop:trivperm
    (φ̃(a) = φ((π⁻¹,π⁻¹)·a)) and prop:switchperm (φ̃(a) = Φ(−a)·p, Φ̃(a) = φ(−a)·p)."""
    for rep in R.REPRESENTATIVES.values():
        for switched in (False, True):
            base = rep.switched() if switched else rep
            for pi in Perm.all():
                if base.relabel(pi) != case:
                    continue
                B = _P(pi) * A * _P(pi.inverse())  # the field (π⁻¹, π⁻¹)·a
                field = -B if switched else B
                rec = _recipe(rep.cls, field)
                sub = {A_SYM[i, j]: field[i, j] for i in range(3) for j in range(3)}
                g = R.to_generic(rep, rec.phi.xreplace(sub), rec.Phi.xreplace(sub))
                phi_g, Phi_g = (R.flip_generic(g.phi, g.Phi) if switched else (g.phi, g.Phi))
                return R.from_generic(case, phi_g, Phi_g)
    raise AssertionError(f"no representative reaches {case}")


A_INT = sp.Matrix([[1, 2, -3], [-1, 2, 1], [2, -2, -3]])


@pytest.mark.parametrize("case", cases(), ids=[f"{c.sigma}-{c.Sigma}" for c in cases()])
def test_every_case_has_a_consistent_solution_from_a_representative(case):
    phi, Phi = _potentials_for(case, A_INT)
    r = sym.consistency(case, phi, Phi, A_INT)
    assert r.consistent and r.det_is_one and r.order == 1


# -- polynomial (nonlinear) fields, by series --------------------------------------------------------
NONLINEAR = (x[1] ** 2 + x[2], x[2] + x[0] ** 2, x[0] + x[1] ** 2)  # div = 0, G¹, −G² quadratic in x3


@pytest.mark.parametrize("printed", [False, True])
def test_nonlinear_field_by_series(printed):
    G1, G2 = R.dl_field_potentials(NONLINEAR)
    for rec in (R.se_dl_potentials(G1, G2, printed=printed),
                R.dl_dl_potentials(G1, G2, printed=printed)):
        r = sym.consistency(rec.case, rec.phi, rec.Phi, NONLINEAR, n_terms=2)
        assert not r.linear
        assert r.det_is_one  # det DX = 1 + O(h³): volume preserving either way
        assert r.consistent is (not printed)
        assert r.order == (0 if printed else 1)
    F1, F3 = R.se_field_potentials(NONLINEAR)
    rec = R.se_se_potentials(F1, F3)
    r = sym.consistency(rec.case, rec.phi, rec.Phi, NONLINEAR, n_terms=2)
    assert r.consistent and r.order == 1 and r.det_is_one


def test_dl_dl_with_theta_zero_is_the_se_dl_map():
    """MATH.md §4: θ = 0 in both DL stages gives the same map as SE+DL; θ = ½ a different one."""
    G1, G2 = R.dl_field_potentials(G)
    se_dl, dl_dl = R.se_dl_potentials(G1, G2), R.dl_dl_potentials(G1, G2)
    mid = R.dl_dl_potentials(G1, G2, theta1=sp.Rational(1, 2), theta2=sp.Rational(1, 2))
    M1, M2, M3 = (sym.consistency(r.case, r.phi, r.Phi, G).M.matrix for r in (se_dl, dl_dl, mid))
    assert all(sp.cancel(e) == 0 for e in (M1 - M2))
    assert any(sp.cancel(e) != 0 for e in (M1 - M3))
    G1, G2 = R.dl_field_potentials(NONLINEAR)
    X1 = sym.consistency((se := R.se_dl_potentials(G1, G2)).case, se.phi, se.Phi, NONLINEAR).X
    X2 = sym.consistency((dd := R.dl_dl_potentials(G1, G2)).case, dd.phi, dd.Phi, NONLINEAR).X
    assert all(sp.expand(a - b) == 0 for a, b in zip(X1, X2))


def test_field_potentials_reconstruct_the_field():
    for a in (NONLINEAR, R.linear_field(G)):
        F1, F3 = R.se_field_potentials(a)
        G1, G2 = R.dl_field_potentials(a)
        vf = lambda F, i: [  # noqa: E731 - eq:vf1–vf3
            (0, sp.diff(F, x[2]), -sp.diff(F, x[1])),
            (-sp.diff(F, x[2]), 0, sp.diff(F, x[0])),
            (sp.diff(F, x[1]), -sp.diff(F, x[0]), 0),
        ][i - 1]
        for (P, i), (Q, j) in (((F1, 1), (F3, 3)), ((G1, 1), (G2, 2))):
            assert all(sp.expand(u + v - w) == 0 for u, v, w in zip(vf(P, i), vf(Q, j), a))


# -- the generic-order helper ---------------------------------------------------------------------
def test_to_generic_roundtrip_and_generic_equations_for_all_cases():
    f, F = sp.Function("f"), sp.Function("F")
    for c in cases():
        cf = sym.case_forms(c)
        phi, Phi = f(*cf.phi_args), F(*cf.Phi_args)
        g = R.to_generic(c, phi, Phi)
        assert g.sign == c.sign
        back = R.from_generic(c, g.phi, g.Phi)
        assert back == (phi, Phi)
        # the generic equations with these potentials are the LM equations (up to sign)
        to_call = lambda e, args: (lambda *u: e.xreplace(dict(zip(args, u))))  # noqa: E731
        E = sym.generic_equations(c, to_call(g.phi, g.phi_args), to_call(g.Phi, g.Phi_args))
        L = sym.lm_equations(c, phi, Phi)
        for eq, e in zip(L, E):
            assert any(sp.expand(eq.lhs - eq.rhs + k * e) == 0 for k in (1, -1))


@pytest.mark.parametrize("case", [Case((3, 2, 1), (3, 2, 1)), Case((1, 2, 3), (2, 3, 1)),
                                  Case((2, 3, 1), (1, 3, 2))], ids=str)
def test_generic_potentials_drive_the_numerical_engine(case):
    """LM potentials through to_generic + lambdify + GeneratingMap give M(h) x (the exact map),
    for cases with c_φ = +1 and −1 (σ odd / even) — the helper issue #5 relies on."""
    jnp = pytest.importorskip("jax.numpy")
    from vpforms import GeneratingMap

    phi_e, Phi_e = _potentials_for(case, A_INT)
    hv = sp.Rational(1, 10)
    g = R.to_generic(case, phi_e.subs(h, hv), Phi_e.subs(h, hv))
    assert g.params == () and g.sign == case.sign
    phi, Phi = g.lambdify()
    m = GeneratingMap(phi, Phi, case)
    x0 = np.array([0.3, -0.2, 0.5])
    X_num = np.asarray(m(jnp.asarray(x0)))
    M = sym.consistency(case, phi_e, Phi_e, A_INT).M.matrix.subs(h, hv)
    X_exact = np.array((M * sp.Matrix(x0.tolist())).evalf(), dtype=float).ravel()
    assert np.allclose(X_num, X_exact, rtol=0, atol=1e-12)


def test_printed_s1_defects_are_classified():
    """Printed eq:S1_quispel: M(h) has a 1/h pole; without the AZ 'Phi_denominator' fix M(0) is
    finite but ≠ I; without the 'k3' fix M(0) = I but M'(0) ≠ A — and det ≡ 1 in all three."""
    r = sym.consistency((q := R.s1_potentials(printed=True)).case, q.phi, q.Phi, G)
    assert r.pole_at_0 and r.M0 is None and r.det_is_one
    az = R.s1_potentials("az", fixes=set(R.S1_AZ_FIXES) - {"Phi_denominator"})
    r = sym.consistency(az.case, az.phi, az.Phi, G)
    assert not r.pole_at_0 and r.M0 is not None and r.M0 != sp.eye(3) and r.det_is_one
    k3 = R.s1_potentials(fixes={"parentheses"})
    r = sym.consistency(k3.case, k3.phi, k3.Phi, G)
    assert r.identity_at_0 and not r.consistent and r.order == 0 and r.det_is_one
    assert r.defects == ("inconsistent (M'(0) ≠ A)",)


# -- bad input ------------------------------------------------------------------------------------
def test_bad_input_raises_value_error_naming_the_problem():
    rec = R.s1_potentials()
    with pytest.raises(ValueError, match="not traceless"):
        sym.consistency(rec.case, rec.phi, rec.Phi, [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(ValueError, match="malformed"):
        sym.consistency(rec.case, rec.phi, rec.Phi, [[1, 0], [0, -1]])
    with pytest.raises(ValueError, match="malformed"):
        sym.consistency(rec.case, rec.phi, rec.Phi, [[1, 0, 0], [0, -1, 0], [0, 0, sp.nan]])
    with pytest.raises(ValueError, match="X3"):  # φ of S1 may not depend on X3
        sym.consistency(rec.case, rec.phi + X[2], rec.Phi, G)
    with pytest.raises(ValueError, match="x3"):
        R.to_generic(rec.case, rec.phi, rec.Phi + x[2])
    with pytest.raises(ValueError, match="divergence"):
        sym.consistency(rec.case, rec.phi, rec.Phi, (x[0], 0, 0))
    with pytest.raises(ValueError, match="variant"):
        R.s1_potentials("bogus")
    with pytest.raises(ValueError, match="unknown fix"):
        R.s1_potentials("az", fixes={"nope"})
    with pytest.raises(ValueError, match="not explicit"):
        R.discrete_lagrangian(x[2] ** 3, x[1], x[2], x[1], X[1])
    with pytest.raises(ValueError, match="Y1|y1"):
        R.from_generic(rec.case, y[0], Y[1])


def test_division_by_zero_and_identically_failing_twist_raise_instead_of_nan():
    """A recipe that divides by a vanishing a_ij, or potentials that violate a twist condition
    identically, are errors (they used to come back as a result with det = X = nan)."""
    rec = R.s1_potentials()
    no_a13 = [[1, 1, 0], [1, -1, 1], [1, 1, 0]]
    with pytest.raises(ValueError, match="a13"):
        sym.consistency(rec.case, rec.phi, rec.Phi, no_a13)
    se = R.REPRESENTATIVES["SE+SE"]
    # φ = x2²/2 does not depend on X₋ = X3: ∂²φ/∂x2∂X3 = 0, volpot1 does not determine X3
    for field in ([[0, 1, 0], [0, 0, 1], [1, 0, 0]], (x[1], x[2], x[0])):
        with pytest.raises(ValueError, match="twist"):
            sym.consistency(se, x[1] ** 2 / 2, x[0] * X[1], field)


def test_field_potentials_accept_any_matrix_form_and_use_one_implementation():
    from vpforms.fields import potential_exprs

    M = [[0, 1, 0], [0, 1, 1], [1, 0, -1]]
    want_se, want_dl = R.se_field_potentials(sp.Matrix(M)), R.dl_field_potentials(sp.Matrix(M))
    for form in (M, np.array(M), sp.Matrix(M)):
        assert R.se_field_potentials(form) == want_se
        assert R.dl_field_potentials(form) == want_dl
    a = R.linear_field(M)
    assert potential_exprs(a, x, "se") == want_se and potential_exprs(a, x, "dl") == want_dl
    with pytest.raises(ValueError, match="traceless"):
        R.se_field_potentials(np.eye(3))
    with pytest.raises(ValueError, match="three SymPy expressions"):
        R.dl_field_potentials((x[1], x[2]))


def test_to_generic_rejects_potentials_already_in_generic_symbols():
    se = R.REPRESENTATIVES["SE+SE"]
    with pytest.raises(ValueError, match="generic symbols y1"):
        R.to_generic(se, x[1] * X[2] + y[0], x[0] * X[1])


def test_a_sign_other_than_plus_or_minus_one_is_rejected():
    rec = R.s1_potentials()
    for bad in (2, 0, 0.5, True):
        with pytest.raises(ValueError, match="sign"):
            sym.consistency(rec.case, rec.phi, rec.Phi, G, sign=bad)
        with pytest.raises(ValueError, match="sign"):
            sym.prove_case(rec.case, sign=bad)


def test_disallowed_variables_are_caught_everywhere_potentials_enter():
    rec = R.s1_potentials()  # φ(x1, x2, X1), Φ(x1, X1, X2)
    with pytest.raises(ValueError, match="x3"):
        rec.subs({A_SYM[0, 0]: x[2]})
    with pytest.raises(ValueError, match="X3"):
        sym.lm_equations(rec.case, rec.phi + X[2], rec.Phi)
    with pytest.raises(ValueError, match="x2"):
        sym.lm_equations(rec.case, rec.phi, rec.Phi + x[1])


def test_lambdify_needs_every_free_parameter():
    g = R.s1_potentials().generic()
    assert h in g.params
    with pytest.raises(ValueError, match="missing h"):
        g.lambdify(params=tuple(p for p in g.params if p != h))
    phi, Phi = g.lambdify()  # all parameters: callables returning numbers
    vals = [float(v) for v in (1.0, 0.5, 0.25)] + [0.1 if p == h else 1.0 for p in g.params]
    assert np.isfinite(float(phi(*vals))) and np.isfinite(float(Phi(*vals)))

"""The 36 generating one-forms: f*ν̃ − ν = dλ, det Df and twist, and the reduction propositions,
proved symbolically on undefined potentials (exact expansion to 0)."""

from __future__ import annotations

import pytest
import sympy as sp

from vpforms import Case, Perm, cases

sym = pytest.importorskip("vpforms.symbolic")
from vpforms.symbolic import exterior as ext  # noqa: E402
from vpforms.symbolic._symbols import COORDS, X, x  # noqa: E402

CASES = cases()
IDS = [f"{c.sigma}-{c.Sigma}" for c in CASES]


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_generating_form_identity_det_and_twist(case):
    p = sym.prove_case(case)
    assert p.one_form_holds, p.residual
    assert p.det_holds and p.det == 1
    assert p.twist_holds
    assert p.lm_equivalent


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_opposite_sign_breaks_the_identity_and_reverses_orientation(case):
    p = sym.prove_case(case, sign=-case.sign)
    assert not p.one_form_holds
    assert p.det_holds and p.det == -1


def test_primitives_are_primitives_of_the_volume_form():
    vol_x = ext.wedge_all([ext.dvar(v) for v in x])
    vol_X = ext.wedge_all([ext.dvar(v) for v in X])
    for c in CASES:
        cf = sym.case_forms(c)
        assert (ext.d(cf.nu_form()) - vol_x).is_zero()
        assert (ext.d(cf.nu_tilde_form()) - vol_X).is_zero()
        # c = x₊, C = X₊: the coefficient of ν is the role x₊ (LM: the determined variable)
        assert x[cf.nu[2] - 1] == cf.x_roles[0] and X[cf.nu_tilde[2] - 1] == cf.X_roles[0]


def test_lm_normalisation_constants_and_the_sign_rule():
    for c in CASES:
        cf = sym.case_forms(c)
        assert cf.sign == c.sigma.sign * c.Sigma.sign == c.tau.sign
        assert cf.c_phi in (1, -1) and cf.c_Phi in (1, -1)
        assert cf.c_phi * cf.c_Phi == -cf.sign  # volpot2 becomes ∂_{X₋}φ = ∂_{x₋}Φ
        assert (cf.l, cf.m) == (c.sigma(3), c.Sigma(3))


def test_compatibility_condition_always_reads_dXm_phi_equals_dxm_Phi():
    """volpot2 with the sign rule, written for the LM potentials φ = c_φ φ_g, Φ = c_Φ Φ_g, is
    exactly ∂_{X₋}φ = ∂_{x₋}Φ in every case (derived from generic_equations, not from the
    displayed lm_equations, which are then checked to say the same)."""
    for c in CASES:
        cf = sym.case_forms(c)
        phi, Phi = cf.undefined_potentials()
        xm, Xc, Xm = cf.x_roles[2], cf.X_roles[1], cf.X_roles[2]
        xc = cf.x_roles[1]
        # φ_g(Y3, y2, y3) = c_φ φ(x₋ = y3, x∘ = y2, X₋ = Y3) (c_φ = ±1 is its own inverse)
        phi_g = lambda a, b, d, cf=cf, phi=phi: cf.c_phi * phi.xreplace(  # noqa: E731
            {xm: d, xc: b, Xm: a})
        Phi_g = lambda a, b, d, cf=cf, Phi=Phi: cf.c_Phi * Phi.xreplace(  # noqa: E731
            {xm: d, Xc: b, Xm: a})
        _, E2, _ = sym.generic_equations(c, phi_g, Phi_g)
        compat = sp.diff(phi, Xm) - sp.diff(Phi, xm)
        assert sp.expand(cf.c_Phi * E2 + compat) == 0
        _, shown, _ = sym.lm_equations(c)
        assert shown.lhs - shown.rhs == compat


def test_class_counts_and_tab123123_block():
    counts = {}
    for c in CASES:
        counts[c.cls] = counts.get(c.cls, 0) + 1
    assert counts == {"S1": 6, "S2": 6, "SE+SE": 6, "DL+DL": 6, "SE+DL": 12}
    block = {sym.case_forms(c).cell: c.cls for c in CASES
             if (sym.case_forms(c).k, sym.case_forms(c).K) == (0, 0)}
    assert block == {"AC": "S1", "BD": "S1", "AD": "DL+DL", "BC": "DL+DL"}


def test_exterior_algebra_basics():
    f = sp.Function("f")(*COORDS)
    assert ext.d(ext.d(f)).is_zero()
    a, b = ext.dvar(x[0]), ext.dvar(X[1])
    assert (ext.wedge(a, b) + ext.wedge(b, a)).is_zero()
    assert ext.wedge(a, a).is_zero()
    g = sp.Function("g")(*COORDS)
    one = g * ext.dvar(x[1])
    # Leibniz: d(f·α) = df∧α + f dα
    assert (ext.d(f * one) - (ext.wedge(ext.d(f), one) + f * ext.d(one))).is_zero()


def test_twist_potentials_are_the_mixed_second_derivatives():
    cf = sym.case_forms(Case((3, 2, 1), (3, 2, 1)))
    phi, Phi = cf.undefined_potentials()
    t1, t2 = cf.twist_potentials(phi, Phi)
    assert t1 == sp.diff(phi, x[1], X[0]) and t2 == sp.diff(Phi, x[0], X[1])
    assert cf.twist_conditions() == ("∂X1/∂x3 ≠ 0", "∂x1/∂X3 ≠ 0")


# -- the reduction propositions -------------------------------------------------------------------
@pytest.mark.parametrize("sign", [1, -1])
def test_volpotinv_same_sign_only(sign):
    assert sym.check_volpotinv(sign).holds
    assert not sym.check_volpotinv(sign, same_sign=False).holds


def test_permactalg_for_all_triples():
    assert sym.check_permactalg().holds


def test_trivperm_and_switchperm_all_cases():
    for c in CASES:
        for pi in Perm.all():
            assert sym.check_trivperm(c, pi).holds
        assert sym.check_switchperm(c).holds
        # negative controls: without time reversal, or with the opposite sign, it fails
        assert not sym.check_switchperm(c, reverse_time=False).holds
        assert not sym.check_switchperm(c, sign=-c.sign).holds


def test_generic_equations_reject_a_bad_sign():
    with pytest.raises(ValueError, match="sign"):
        sym.generic_equations(CASES[0], sign=0)


def test_identify_case_inverts_case_forms():
    for c in CASES:
        cf = sym.case_forms(c)
        phi, Phi = cf.undefined_potentials()
        assert sym.identify_case(phi, Phi, cf.l, cf.m) == c
    # the paper's S1 one-form φ(x1, x2, X1) dx1 + Φ(x1, X1, X2) dX1 (eq:S1)
    f, F = sp.Function("f"), sp.Function("F")
    assert sym.identify_case(f(x[0], x[1], X[0]), F(x[0], X[0], X[1]), 1, 1) == Case(
        (3, 2, 1), (3, 2, 1))
    with pytest.raises(ValueError, match="fits no case"):
        sym.identify_case(f(x[0], x[1], x[2]), F(x[0], X[0], X[1]), 1, 1)
    with pytest.raises(ValueError, match="not allowed"):
        sym.identify_case(f(x[0], x[1], X[2]), F(x[0], X[0], X[1]), 1, 1)

"""Further facts of the spec (MATH.md §1, §2, §4), each computed two independent ways."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from vpforms import Case, Perm

sym = pytest.importorskip("vpforms.symbolic")
from vpforms.symbolic import recipes as R  # noqa: E402
from vpforms.symbolic._symbols import A as A_SYM  # noqa: E402
from vpforms.symbolic._symbols import X, h, x  # noqa: E402

G = sym.generic_traceless_matrix()
A_INT = sp.Matrix([[2, 1, -1], [3, -1, 2], [1, -2, -1]])


def _M(case, phi, Phi, A, sign=None):
    return sym.consistency(case, phi, Phi, A, sign=sign).M.matrix


@pytest.mark.parametrize("same_sign", [True, False])
def test_inverse_map_with_same_sign_and_off_by_O1_with_the_opposite(same_sign):
    """prop:permactvolpotinv on a concrete S1 map: (Σ,σ)·f_{Φ·p, φ·p} ∘ (σ,Σ)·f_{φ,Φ} = id exactly
    with the same sign; with the opposite sign the composition differs from id already at h = 0."""
    rec = R.s1_potentials().subs({A_SYM[i, j]: A_INT[i, j] for i in range(3) for j in range(3)})
    g = rec.generic()
    inv_case = rec.case.switched()
    phi_i, Phi_i = R.from_generic(inv_case, *R.flip_generic(g.phi, g.Phi))
    M = _M(rec.case, rec.phi, rec.Phi, A_INT)
    sign = inv_case.sign if same_sign else -inv_case.sign
    res = sym.consistency(inv_case, phi_i, Phi_i, A_INT, sign=sign)
    P, Q = res.M.P, res.M.Q  # the inverse map: P X' + Q X = 0
    comp = (-(P.adjugate() * Q) / P.det()) * M
    D = (comp - sp.eye(3)).applyfunc(sp.cancel)
    if same_sign:
        assert D == sp.zeros(3, 3)
    else:
        assert D.applyfunc(lambda e: sp.limit(e, h, 0)) != sp.zeros(3, 3)


def test_the_nine_tables_are_cyclic_relabellings_of_tab123123():
    """table36.md: the other 32 rows are the cyclic relabellings of the k = K = 0 block."""
    rho = Perm((2, 3, 1))  # x_i ↦ x_{ρ(i)} shifts ν = x3 dx1∧dx2 to x1 dx2∧dx3
    powers = [Perm((1, 2, 3)), rho, rho * rho]
    base = sym.lm_table_cases(0, 0)
    for k in range(3):
        for K in range(3):
            cells = sym.lm_table_cases(k, K)
            for cell, c0 in base.items():
                ck = Case(powers[k] * c0.sigma, powers[K] * c0.Sigma)
                assert cells[cell] == ck
                ren = {x[i - 1]: x[powers[k](i) - 1] for i in (1, 2, 3)}
                ren.update({X[i - 1]: X[powers[K](i) - 1] for i in (1, 2, 3)})
                f, F = sp.Function("f"), sp.Function("F")
                cf0, cfk = sym.case_forms(c0), sym.case_forms(ck)
                e0 = sym.lm_equations(c0, f(*cf0.phi_args), F(*cf0.Phi_args))
                ek = sym.lm_equations(ck, f(*cfk.phi_args), F(*cfk.Phi_args))
                assert [e.xreplace(ren) for e in e0] == list(ek)


def test_se_dl_recipe_is_the_explicit_left_point_scheme():
    """MATH.md §4: x̃3 = x3 − h∂₂G¹(x1,x2,x̃3); X2 = x2 + h∂₃G¹(x1,x2,x̃3);
    X3 = x̃3 + h∂₁G²(x1,X2,X3); X1 = x1 − h∂₃G²(x1,X2,X3) — solved here directly."""
    G1, G2 = R.dl_field_potentials(G)
    t = sp.Symbol("xt3")
    d = lambda F, i, args: sp.diff(F, x[i - 1]).xreplace(dict(zip(x, args)))  # noqa: E731
    eqs = [
        t - (x[2] - h * d(G1, 2, (x[0], x[1], t))),
        X[1] - (x[1] + h * d(G1, 3, (x[0], x[1], t))),
        X[2] - (t + h * d(G2, 1, (x[0], X[1], X[2]))),
        X[0] - (x[0] - h * d(G2, 3, (x[0], X[1], X[2]))),
    ]
    sol = sp.solve(eqs, [t, *X], dict=True)[0]
    M_scheme = sp.Matrix(3, 3, lambda i, j: sp.diff(sol[X[i]], x[j]))
    rec = R.se_dl_potentials(G1, G2)
    M = _M(rec.case, rec.phi, rec.Phi, G)
    assert (M - M_scheme).applyfunc(sp.cancel) == sp.zeros(3, 3)


def test_right_action_composes():
    """(x·π)·σ = x·(π∘σ) with (x·σ)_i = x_{σ(i)} (MATH.md §2), symbolically."""
    xs = np.array(x, dtype=object)  # the library's Perm.act, on symbols
    for pi in Perm.all():
        assert tuple(pi.act(xs)) == tuple(x[pi(i) - 1] for i in (1, 2, 3))
        for s in Perm.all():
            assert tuple(s.act(pi.act(xs))) == tuple((pi * s).act(xs))

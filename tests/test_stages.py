"""Stages as data (issue #19, item 1): one stage list per method, the operations act on it.

* a composition is the concatenation of its methods' stages, each coefficient times its own;
* the adjoint reverses the list and adjoins each stage (prop:switchperm), and is the inverse at −h;
* the relabelling (π, π)·Ψ relabels each stage (prop:trivperm): X = Ψ(x·π)·π⁻¹, case (π∘σ, π∘Σ),
  a consistent VP method for the relabelled field;
* every consumer folds over the list: the native plan has the same coefficients, in the same
  order, as the stages; the spec of an adjoined or relabelled method rebuilds it bit for bit.
"""

import jax.numpy as jnp
import numpy as np
import pytest

from vpforms import Case, compose, method_from_spec, scheme
from vpforms._methods import Composition, Stage
from vpforms._methods._compose import COMPOSITIONS, DEFAULT
from vpforms._perm import Perm
from vpforms.backends.native.codegen.plan import plan
from vpforms.problems import get

from .test_methods_helpers import step_det

X0 = np.array([[0.5, 0.7, 0.9], [1.0, 0.6, 0.8], [0.2, 1.1, 0.4]])


def _abc():
    return get("abc").field


def test_a_bare_method_is_one_stage_of_itself_in_normal_form():
    field = _abc()
    for case in (Case((3, 2, 1), (1, 2, 3)), Case((1, 2, 3), (2, 3, 1)), Case((1, 3, 2), (3, 1, 2))):
        m = scheme(field, case, recover=False)
        (st,) = m.stages
        assert isinstance(st, Stage) and st.method is m and st.coefficient == 1.0
        # the normal form rebuilds the case: ((π, π)·recipe)^(*adjoint)
        c = st.recipe.case.relabel(st.pi)
        assert (c.switched() if st.adjoint else c) == case


def test_compositions_concatenate_and_scale_their_stages():
    m = scheme(_abc(), "SE+SE", recover=False)
    two = compose(m, 2)
    four = compose(two, 4)  # a symmetric order-2 method composed: S_{γh}, each γ times (½, ½)
    gam = COMPOSITIONS[(4, DEFAULT[4])]
    assert four.coefficients == tuple(0.5 * g for g in gam for _ in (0, 1))
    assert [s.method for s in four.stages] == [m, m.adjoint()] * len(gam)
    assert four.stages == tuple(s for s in four.stages)  # a tuple: immutable data
    # compose(m, 4) builds the same list from the order-1 method
    assert compose(m, 4).coefficients == four.coefficients
    x = jnp.asarray(X0)
    assert np.array_equal(np.asarray(compose(m, 4).step(x, 0.1)), np.asarray(four.step(x, 0.1)))


@pytest.mark.parametrize("order,name", [(2, None), (4, None), (4, "blanes_moan")])
def test_the_adjoint_reverses_and_adjoins_the_stages(order, name):
    m = compose(scheme(get("lotka_volterra").field, Case((1, 3, 2), (3, 1, 2)), recover=False),
                order, name)
    adj = m.adjoint()
    assert isinstance(adj, Composition) and adj.adjoint_of is m and adj.case == m.case.switched()
    n = len(m.stages)
    for k, s in enumerate(adj.stages):
        r = m.stages[n - 1 - k]
        assert s.coefficient == r.coefficient and s.method is r.method.adjoint()
        assert (s.recipe, s.pi, s.adjoint) == (r.recipe, r.pi, not r.adjoint)
    x = jnp.asarray(np.random.default_rng(1).uniform(0.6, 1.6, (5, 3)))
    Y = adj.step(x, 0.05)  # Ψ*_h = (Ψ_{−h})⁻¹
    assert float(jnp.max(jnp.abs(m.step(Y, -0.05) - x))) <= 1e-13
    assert float(jnp.max(jnp.abs(adj.inverse_step(Y, 0.05) - x))) <= 1e-13


@pytest.mark.parametrize("pi", [(2, 1, 3), (2, 3, 1), (3, 2, 1)])
def test_relabelling_relabels_each_stage(pi):
    field = _abc()
    base = scheme(field, Case((1, 2, 3), (2, 3, 1)), recover=False)  # SE+DL, itself relabelled
    m = compose(base, 4, "blanes_moan")
    P = Perm(pi)
    r = m.relabel(P)
    assert r.case == m.case.relabel(P) and r.coefficients == m.coefficients
    for s, t in zip(r.stages, m.stages):
        assert s.recipe is t.recipe and s.pi == P * t.pi and s.adjoint == t.adjoint
    x = jnp.asarray(X0)
    h = 0.05
    # (π, π)·Ψ: X = Ψ(x·π)·π⁻¹
    want = P.inverse().act(np.asarray(m.step(P.act(x), h)))
    got = np.asarray(r.step(x, h))
    assert np.max(np.abs(got - want)) <= 1e-14
    # a VP method for the relabelled field (π, π)·a: det 1, consistent with ã(x) = a(x·π)·π⁻¹
    _, det, status = step_det(r)(x, h)
    assert np.all(np.asarray(status) == 0) and float(jnp.max(jnp.abs(det - 1.0))) <= 1e-12
    a_tilde = P.inverse().act(np.asarray(field(P.act(x))))
    for hh in (1e-3, 5e-4):
        slope = (np.asarray(r.step(x, hh)) - np.asarray(x)) / hh
        assert np.max(np.abs(slope - a_tilde)) <= 50 * hh
    # relabelling back is the identity map: (π⁻¹, π⁻¹)·(π, π)·Ψ = Ψ
    back = r.relabel(P.inverse())
    assert np.max(np.abs(np.asarray(back.step(x, h)) - np.asarray(m.step(x, h)))) <= 1e-14


def test_specs_of_adjoined_and_relabelled_methods_rebuild_them_bit_for_bit():
    m = compose(scheme(_abc(), "SE+SE", recover=False), 4, "blanes_moan")
    x = jnp.asarray(X0)
    for built in (m.adjoint(), m.relabel((3, 1, 2)), scheme(_abc(), "DL+DL", recover=False).relabel((2, 1, 3))):
        spec = built.spec()
        again = method_from_spec(spec)
        assert again.spec() == spec
        assert np.array_equal(np.asarray(again.step(x, 0.07)), np.asarray(built.step(x, 0.07)))


def test_the_native_plan_is_a_fold_over_the_stages():
    field = _abc()
    for m in (compose(scheme(field, Case((1, 3, 2), (3, 1, 2)), recover=False), 4, "blanes_moan"),
              compose(scheme(field, "SE+SE"), 6).adjoint(),
              compose(scheme(field, "DL+DL", recover=False), 2).relabel((2, 3, 1))):
        p = plan(m)
        assert not isinstance(p, str), p
        bare = m.without_recovery()
        assert [c for _, c in p] == list(bare.coefficients)
        for (gen, _), s in zip(p, bare.stages):
            want = s.recipe.case.relabel(s.pi)
            want = want.switched() if s.adjoint else want
            if hasattr(gen, "case"):
                assert gen.case == want


def test_adjoint_and_relabel_are_memoised_so_stages_share_their_maps():
    m = compose(scheme(_abc(), "SE+SE", recover=False), 4, "blanes_moan")
    adj = m.adjoint()
    assert m.adjoint() is adj and adj.adjoint() is m  # (Ψ*)* = Ψ, the same object
    assert m.relabel((2, 3, 1)) is m.relabel(Perm((2, 3, 1))) and m.relabel((1, 2, 3)) is m
    r = m.relabel((2, 3, 1))
    psi, psi_adj = r.stages[0].method, r.stages[1].method
    assert psi_adj is psi.adjoint()  # Ψ*.relabel(π) is Ψ.relabel(π).adjoint(): one map, compiled once
    assert len({id(s.method) for s in r.stages}) == 2

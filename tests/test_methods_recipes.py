"""The five class recipes (issue #5, items 1, 2, 5): each computed fact is derived here.

* SE+SE on ABC is the explicit composition of three shears (eq:case5), also with the spec's
  closed-form potentials; its fast path equals the engine;
* the DL potentials (numerical discrete Lagrangian, envelope derivatives) realise exactly the
  symbolic recipes of the symbolic layer (printed and corrected, θ = 0 and ½) on linear fields;
* SE+DL and DL+DL with θ = 0 are the same map; θ = ½ is a different one;
* the printed SE+DL / DL+DL / S1 variants are volume preserving but not consistent;
* S1/S2 on random traceless A: X = M(h) x, det M = 1, M = I + hA + O(h²); S1 Quispel = t5vp,
  S2 = t5vps2 exactly; zero coefficients and non-linear fields are clear errors;
* the correction maps on nonlinear fields: closed form = quadrature, and they keep stepping where
  the S1 twist fails.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from vpforms import Case, Field, GeneratingMap, Perm, RecipeError, scheme
from vpforms._methods import DLDL, S1, S2, SEDL, SESE, QuispelCorrection, SESEFast
from vpforms._methods._relabel import relabelled_field
from vpforms._methods._representatives import REPRESENTATIVES
from vpforms.fields import SYMBOLS, vf1, vf3
from vpforms.problems import get
from vpforms.problems.linear import random_traceless
from vpforms.symbolic import recipes

from .test_methods_helpers import step_det, step_jac

x1, x2, x3 = SYMBOLS


def pts(n=8, lo=0.45, hi=1.1, seed=0):
    return jnp.asarray(np.random.default_rng(seed).uniform(lo, hi, (n, 3)))


def test_representatives_are_their_class():
    for cls, case in REPRESENTATIVES.items():
        assert case.cls == cls and case.sigma == Perm((3, 2, 1))


# -- SE+SE --------------------------------------------------------------------------------------
def test_se_se_abc_is_three_shears():
    field = get("abc").field
    a1, a2, a3 = field.components
    e1, e2, _ = field.exprs  # a = (A sin x3 + C cos x2, B sin x1 + A cos x3, C sin x2 + B cos x1)
    A, B, C = e1.coeff(sp.sin(x3)), e2.coeff(sp.sin(x1)), e1.coeff(sp.cos(x2))
    # the spec's closed-form potentials (MATH.md §3), given to the Field and verified by it
    F1 = C * sp.cos(x2) - B * x2 * sp.cos(x1) + A * sp.sin(x3)
    F3 = A * x2 * sp.sin(x3) + C * sp.sin(x2) + B * sp.cos(x1)
    spec_field = Field.from_sympy(field.exprs, SYMBOLS, potentials={"se": (F1, F3)})
    x = pts(16, 0.0, 2 * np.pi)
    for h in (0.1, 0.031):
        # X₃ = x₃ + h a₃(x);  X₂ = x₂ + h a₂(x₁, ·, X₃);  X₁ = x₁ + h a₁(·, X₂, X₃)
        X3 = x[:, 2] + h * a3(x[:, 0], x[:, 1], x[:, 2])
        X2 = x[:, 1] + h * a2(x[:, 0], x[:, 1], X3)
        X1 = x[:, 0] + h * a1(x[:, 0], X2, X3)
        shears = jnp.stack([X1, X2, X3], -1)
        for f in (field, spec_field):
            for m in (SESE(f), SESEFast(f)):
                assert float(jnp.max(jnp.abs(m.step(x, h) - shears))) <= 1e-14
    assert SESEFast(field).explicit == (True, True)


def test_se_se_fast_path_equals_engine_when_implicit():
    field = get("lotka_volterra").field
    fast = scheme(field, "SE+SE", fast=True)
    assert not all(fast.explicit)  # implicit equations: the scalar Newton path is exercised
    x = pts(8, 0.5, 2.0)
    for c in (REPRESENTATIVES["SE+SE"], Case((1, 2, 3), (3, 2, 1))):
        X_engine = scheme(field, c).step(x, 0.05)
        X_fast = scheme(field, c, fast=True).step(x, 0.05)
        assert float(jnp.max(jnp.abs(X_engine - X_fast))) <= 1e-14


# -- DL classes ---------------------------------------------------------------------------------
def symbolic_dl_map(field, cls, printed, theta):
    """The map of the symbolic layer's DL recipe (closed-form L_d for a linear field)."""
    G1, G2 = field.dl_potential_exprs
    if cls == "SE+DL":
        rec = recipes.se_dl_potentials(G1, G2, printed=printed, theta=theta)
    else:
        rec = recipes.dl_dl_potentials(G1, G2, printed=printed, theta1=theta, theta2=theta)
    phi, Phi = rec.generic().lambdify(params=(recipes.SYMBOLS["h"],))

    def step(x, h):
        m = GeneratingMap(lambda a, b, c: phi(a, b, c, h), lambda a, b, c: Phi(a, b, c, h), rec.case)
        return m(x)

    return step


@pytest.mark.parametrize("theta", [0.0, 0.5])
def test_dl_potentials_are_the_symbolic_recipes(theta):
    field = Field.linear(random_traceless(3), name="A3")
    x = pts(6, -1, 1)
    h = 0.05
    for cls, M in (("SE+DL", SEDL), ("DL+DL", DLDL)):
        for printed in (False, True):
            if cls == "SE+DL" and theta:  # its θ-stage is DL+DL's first stage
                continue
            X = M(field, theta=theta, printed=printed).step(x, h)
            X_sym = symbolic_dl_map(field, cls, printed, theta)(x, h)
            assert float(jnp.max(jnp.abs(X - X_sym))) <= 1e-12, (cls, printed, theta)


def test_dl_theta0_same_map_theta_half_differs():
    field = get("lotka_volterra").field
    x = pts(8, 0.5, 2.0)
    X_sedl = SEDL(field).step(x, 0.05)
    X_half = DLDL(field, theta=0.5).step(x, 0.05)
    assert float(jnp.max(jnp.abs(DLDL(field).step(x, 0.05) - X_sedl))) <= 1e-13
    assert float(jnp.max(jnp.abs(X_half - X_sedl))) >= 1e-5
    # the direct stage form (fast=True) is the same map as the engine, and exactly VP
    X, det, status = step_det(DLDL(field, theta=0.5, fast=True))(x, 0.05)
    assert np.all(np.asarray(status) == 0)
    assert float(jnp.max(jnp.abs(X - X_half))) <= 1e-13
    assert float(jnp.max(jnp.abs(det - 1))) <= 1e-13


# -- printed variants ---------------------------------------------------------------------------
def consistency_errors(m, field, x, hs):
    a = field(x)
    return np.array([float(jnp.max(jnp.abs((m.step(x, h) - x) / h - a))) for h in hs])


def test_printed_variants_volume_preserving_but_inconsistent():
    # (the corrected SE+DL, DL+DL and S1-Quispel are consistent in test_methods_cases_linear.py;
    # the corrected S1-AZ is checked here)
    field = Field.linear(random_traceless(5), name="A5")
    x = pts(6, -1, 1, seed=2)
    a = np.asarray(field(x))
    scale = float(np.max(np.abs(a)))
    methods = [SEDL(field, printed=True), DLDL(field, printed=True), S1(field, printed=True),
               S1(field, variant="az", printed=True), S1(field, variant="az")]
    for m in methods:
        G = step_det(m)
        errs = []
        for h in (1e-2, 1e-3):
            X, det, status = G(x, h)
            assert np.all(np.asarray(status) == 0), m.name
            assert float(jnp.max(jnp.abs(det - 1))) <= 1e-12, m.name  # volume preserving
            errs.append(float(np.max(np.abs((np.asarray(X) - np.asarray(x)) / h - a))))
        if m.printed:  # ‖(X − x)/h − a‖ = O(1): not consistent
            assert errs[1] >= 0.5 * errs[0] and errs[1] >= 0.05 * scale, (m.name, errs)
        else:  # O(h)
            assert errs[1] <= 0.2 * errs[0], (m.name, errs)


# -- S1 / S2 for linear fields ------------------------------------------------------------------
@given(seed=st.integers(0, 10_000))
@settings(max_examples=2, deadline=None)
def test_s1_s2_linear_step_is_a_unimodular_matrix(seed):
    A = random_traceless(seed)
    field = Field.linear(A, name=f"A{seed}")
    x = pts(5, -1, 1, seed=seed)
    for m in (S1(field), S1(field, variant="az"), S2(field)):
        G = step_jac(m)
        hs = (8e-3, 4e-3, 2e-3, 1e-3)  # ≥ 4 step sizes for the log–log slope
        Ms = []
        for h in hs:
            X, J, status = G(x, h)
            M = np.asarray(J[0])
            np.testing.assert_allclose(np.asarray(J), np.broadcast_to(M, J.shape), atol=1e-13)
            np.testing.assert_allclose(np.asarray(X), np.asarray(x) @ M.T, atol=1e-12)  # X = M x
            assert abs(np.linalg.det(M) - 1) <= 1e-13
            Ms.append(M)
        errs = [np.max(np.abs((M - np.eye(3)) / h - A)) for h, M in zip(hs, Ms)]
        slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
        assert abs(slope - 1) <= 0.1, (m.name, errs)


def test_quispel_recipes_equal_the_correction_maps():
    field = Field.linear(random_traceless(11), name="A11")
    x = pts(8, -1, 1)
    for c in (REPRESENTATIVES["S1"], REPRESENTATIVES["S2"], Case((1, 2, 3), (2, 1, 3))):
        gen = scheme(field, c, recover=False)  # linear field: the generating recipe (eq:S1_quispel / eq:S2_quispel)
        cor = scheme(field, c, recipe="correction")  # t5vp / t5vps2
        assert type(gen.base if hasattr(gen, "base") else gen) in (S1, S2)
        for h in (0.1, 0.01):
            assert float(jnp.max(jnp.abs(gen.step(x, h) - cor.step(x, h)))) <= 5e-13


def test_linear_recipe_errors():
    A = np.array([[0.5, 1.0, 0.0], [0.3, -0.2, 0.7], [0.1, 0.4, -0.3]])  # a13 = 0
    with pytest.raises(RecipeError, match="a13"):
        S1(Field.linear(A))
    with pytest.raises(RecipeError, match="a13"):
        S2(Field.linear(A))
    B = np.array([[0.5, 0.0, 1.0], [0.3, -0.2, 0.7], [0.1, 0.4, -0.3]])  # a12 = 0
    S1(Field.linear(B))
    with pytest.raises(RecipeError, match="a12"):
        S2(Field.linear(B))
    # a relabelled case reads another entry: S1 case (π∘σ₀, π∘Σ₀) needs ã13 = a_{π(1)π(3)}
    with pytest.raises(RecipeError, match="relabelling"):
        scheme(Field.linear(B), Case((2, 3, 1), (2, 3, 1)))  # π = (1,3,2): ã13 = a12 = 0
    with pytest.raises(RecipeError, match="linear"):
        S1(get("abc").field)
    with pytest.raises(RecipeError, match="linear"):
        scheme(get("abc").field, "S2", recipe="generating")
    with pytest.raises(ValueError, match="unknown class"):
        scheme(get("abc").field, "SE+XX")
    with pytest.raises(ValueError, match="do not apply"):
        scheme(get("abc").field, "SE+SE", theta=0.5)
    for cls in ("SE+DL", "DL+DL"):
        with pytest.raises(ValueError, match="theta must be a finite"):
            scheme(get("abc").field, cls, theta=float("nan"))
    with pytest.raises(ValueError, match="variant"):
        S1(Field.linear(B), variant="other")


# -- correction maps beyond linear fields -------------------------------------------------------
def test_correction_map_closed_form_equals_quadrature():
    lv = get("lotka_volterra").field
    x = pts(8, 0.5, 2.0)
    for kind in ("S1", "S2"):
        closed = QuispelCorrection(lv, kind)
        quad = QuispelCorrection(lv, kind, integral="quadrature")
        assert closed.integral == "closed form" and quad.integral.startswith("quadrature")
        Xq, det, status = step_det(quad)(x, 0.05)
        assert float(jnp.max(jnp.abs(closed.step(x, 0.05) - Xq))) <= 1e-13
        assert float(jnp.max(jnp.abs(det - 1))) <= 1e-13
    # a field given only as a JAX callable: quadrature, exactly volume preserving
    def a(p):
        return jnp.stack([jnp.sin(p[1]) * p[2], jnp.cos(p[2]) + p[0] ** 2, jnp.exp(-p[0] * p[1])])

    cf = Field.from_callable(a, name="callable")
    m = scheme(cf, "S1", recover=False)
    assert isinstance(m, QuispelCorrection) and m.integral.startswith("quadrature")
    x = pts(8, -1, 1)
    G = step_det(m)
    _, det, status = G(x, 0.05)
    assert np.all(np.asarray(status) == 0)
    assert float(jnp.max(jnp.abs(det - 1))) <= 1e-12
    a = np.asarray(cf(x))
    errs = [float(np.max(np.abs((np.asarray(G(x, h)[0]) - np.asarray(x)) / h - a))) for h in (1e-2, 5e-3)]
    assert errs[1] <= 0.6 * errs[0]
    with pytest.raises(ValueError, match="closed form"):
        QuispelCorrection(cf, "S1", integral="closed")


def test_correction_map_steps_where_the_s1_twist_fails():
    # a₁ ≡ 0: ∂a₁/∂x₃ = 0 everywhere, so the S1 generating form does not exist (a13 = 0)
    A = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    field = Field.linear(A)
    with pytest.raises(RecipeError, match="a13"):
        scheme(field, "S1")
    m = scheme(field, "S1", recipe="correction")
    x = pts(6, -1, 1)
    X, status = m.step_with_status(x, 0.1)
    assert np.all(np.asarray(status) == 0)
    assert float(jnp.max(jnp.abs(m.det(x, 0.1) - 1))) <= 1e-14
    twist = np.asarray(m.twist(x, 0.1))
    assert np.all(twist[:, 0] == 0.0)  # ∂X₁/∂x₃ = 0: the twist diagnostic reports the failure
    errs = consistency_errors(m, field, x, (1e-2, 1e-3))
    assert errs[1] <= 0.2 * errs[0] + 1e-12


# -- relabelled fields --------------------------------------------------------------------------
@given(pi=st.sampled_from(Perm.all()), seed=st.integers(0, 1000))
@settings(max_examples=12, deadline=None)
def test_relabelled_field_is_the_relabelling(pi, seed):
    field = get("abc").field
    x = pts(8, 0.0, 2 * np.pi, seed=seed)
    ft = relabelled_field(field, pi)
    assert relabelled_field(field, pi) is ft  # cached per (field, π)
    inv = list(pi.inverse().index)
    expect = field(x[:, inv])[:, list(pi.index)]  # ã(x) = a(x·π⁻¹)·π
    assert float(jnp.max(jnp.abs(ft(x) - expect))) <= 1e-14
    # its own potentials (Field machinery, closed form) reproduce it
    assert float(jnp.max(jnp.abs(ft.reconstruct(x, "se") - expect))) <= 1e-13
    assert float(jnp.max(jnp.abs(ft.reconstruct(x, "dl") - expect))) <= 1e-13


def test_permuted_potentials_carry_the_sign_of_pi():
    # vf_k(F) relabels to sgn π · vf_{π⁻¹(k)}(F∘π⁻¹): for the odd π = (3,2,1) the permuted SE
    # potentials of a give −ã, not ã — so the relabelled field's potentials are built anew
    field = get("abc").field
    x = pts(8, 0.0, 2 * np.pi)
    p = Perm((3, 2, 1))
    F1, F3 = field.se_potentials
    naive = lambda y: vf1(lambda a, b, c: F3(c, b, a))(y) + vf3(lambda a, b, c: F1(c, b, a))(y)  # noqa: E731
    ft = relabelled_field(field, p)
    np.testing.assert_allclose(np.asarray(jax.vmap(naive)(x)), -np.asarray(ft(x)), atol=1e-13)

"""Tests of vpforms.Field and the differentiable quadrature (issue #4).

Truth is computed here: symbolic identities are re-derived with SymPy from the field's own
expressions, numerical checks compare against the field itself or against independent formulas.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from vpforms import Field, NotDivergenceFreeError
from vpforms._quadrature import gauss_legendre_01, gl_error_bound, line_integral
from vpforms.fields import (
    SYMBOLS,
    PotentialError,
    vf1,
    vf1_expr,
    vf2,
    vf2_expr,
    vf3,
    vf3_expr,
)

x1, x2, x3 = SYMBOLS
TWO_PI = 2 * np.pi
A_, B_, C_ = sp.Integer(1), sp.sqrt(sp.Rational(2, 3)), sp.sqrt(sp.Rational(1, 3))
ABC = (A_ * sp.sin(x3) + C_ * sp.cos(x2), B_ * sp.sin(x1) + A_ * sp.cos(x3), C_ * sp.sin(x2) + B_ * sp.cos(x1))
ABC_BOX = ((0.0, TWO_PI),) * 3
HYP = settings(max_examples=25, deadline=None, derandomize=True)


@pytest.fixture(scope="module")
def abc():
    return Field.from_sympy(ABC, SYMBOLS, name="abc", box=ABC_BOX)


@pytest.fixture(scope="module")
def abc_callable(abc):
    # only JAX code, no SymPy: the vector function written out by hand
    def a(x):
        A, B, C = 1.0, np.sqrt(2 / 3), np.sqrt(1 / 3)
        return jnp.stack(
            [
                A * jnp.sin(x[2]) + C * jnp.cos(x[1]),
                B * jnp.sin(x[0]) + A * jnp.cos(x[2]),
                C * jnp.sin(x[1]) + B * jnp.cos(x[0]),
            ]
        )

    return Field.from_callable(a, box=ABC_BOX, name="abc_callable")


def _residual(exprs, pair, splitting):
    P, Q = pair
    u = vf1_expr(P)
    v = vf3_expr(Q) if splitting == "se" else vf2_expr(Q)
    return [sp.simplify(ui + vi - ai) for ui, vi, ai in zip(u, v, exprs)]


def _pts(box, n, seed):
    b = np.asarray(box, dtype=float)
    return b[:, 0] + (b[:, 1] - b[:, 0]) * np.random.default_rng(seed).random((n, 3))


# -- construction, evaluation ------------------------------------------------------------------
def test_from_sympy_divergence_exact_and_evaluation(abc):
    assert sp.simplify(sum(sp.diff(e, s) for e, s in zip(abc.exprs, SYMBOLS))) == 0
    assert abc.divergence_check == "symbolic"
    assert abc.symbols == SYMBOLS and abc.exprs == ABC and abc.name == "abc"
    pts = _pts(ABC_BOX, 64, 0)
    f = [sp.lambdify(SYMBOLS, e, "numpy") for e in ABC]
    want = np.stack([np.broadcast_to(g(*pts.T), (64,)) for g in f], axis=1)
    got = np.asarray(abc(pts))
    assert got.shape == (64, 3)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.asarray(abc(pts[0])), want[0], rtol=0, atol=1e-14)
    J = np.asarray(abc.jacobian(pts))
    Jexpr = sp.Matrix(ABC).jacobian(sp.Matrix(SYMBOLS))
    Jf = sp.lambdify(SYMBOLS, Jexpr, "numpy")
    for k in range(5):
        np.testing.assert_allclose(J[k], np.asarray(Jf(*pts[k]), dtype=float), atol=1e-14)
    assert np.max(np.abs(np.asarray(abc.divergence(pts)))) <= 1e-14
    assert abc.divergence(pts[0]).shape == ()
    assert abc.linear_matrix is None
    # components are JAX scalar callables, differentiable
    g = jax.grad(abc.components[0], argnums=2)(0.3, 0.2, 0.1)
    assert abs(float(g) - np.cos(0.1)) < 1e-14


def test_components_work_under_jit_and_vmap(abc):
    pts = jnp.asarray(_pts(ABC_BOX, 8, 3))
    out = jax.jit(abc.__call__)(pts)
    np.testing.assert_allclose(np.asarray(out), np.asarray(abc(pts)), atol=0)
    v = jax.vmap(lambda p: abc.components[1](p[0], p[1], p[2]))(pts)
    np.testing.assert_allclose(np.asarray(v), np.asarray(abc(pts))[:, 1], atol=1e-15)


@HYP
@given(st.integers(0, 2**31 - 1))
def test_from_callable_divergence_at_random_points(abc_callable, seed):
    pts = _pts(ABC_BOX, 64, seed)
    assert np.max(np.abs(np.asarray(abc_callable.divergence(pts)))) <= 1e-12
    assert abc_callable.exprs is None and abc_callable.symbols is None
    assert abc_callable.potential_method == "quadrature(n=32)"


def test_from_callable_scalar_components():
    comps = (lambda a, b, c: jnp.sin(b * c), lambda a, b, c: a * c, lambda a, b, c: jnp.cos(a) + b**2)
    f = Field.from_callable(comps, box=((-1, 1),) * 3)
    pts = _pts(f.box, 50, 2)
    want = np.stack([np.sin(pts[:, 1] * pts[:, 2]), pts[:, 0] * pts[:, 2], np.cos(pts[:, 0]) + pts[:, 1] ** 2], 1)
    np.testing.assert_allclose(np.asarray(f(pts)), want, atol=1e-15)
    assert f.reconstruction_error("se") <= 1e-12
    assert f.reconstruction_error("dl") <= 1e-12


# -- potentials --------------------------------------------------------------------------------
@pytest.mark.parametrize("splitting", ["se", "dl"])
def test_closed_form_potentials_reproduce_abc(abc, splitting):
    assert abc.potential_methods[splitting] == "closed form"
    pair = abc.se_potential_exprs if splitting == "se" else abc.dl_potential_exprs
    assert all(r == 0 for r in _residual(ABC, pair, splitting))
    pts = _pts(ABC_BOX, 400, 5)
    a = np.asarray(abc(pts))
    r = np.asarray(abc.reconstruct(pts, splitting))
    assert np.max(np.abs(r - a)) / np.max(np.abs(a)) <= 1e-12
    assert abc.reconstruction_error(splitting) <= 1e-12


@pytest.mark.parametrize("splitting", ["se", "dl"])
def test_quadrature_potentials_reproduce_abc(abc_callable, abc, splitting):
    # a callable field: Gauss–Legendre potentials, derivatives through the quadrature
    assert abc_callable.reconstruction_error(splitting, n_points=2000) <= 1e-12
    # and they agree with the closed forms up to a gauge: compare potential *vector fields*
    pts = _pts(ABC_BOX, 100, 8)
    np.testing.assert_allclose(
        np.asarray(abc_callable.reconstruct(pts, splitting)),
        np.asarray(abc.reconstruct(pts, splitting)),
        atol=1e-12,
    )


def test_quadrature_potentials_values_match_formula(abc_callable, abc):
    # with origin 0 both the closed form and the quadrature are the SAME functions (MATH.md §3)
    pts = jnp.asarray(_pts(ABC_BOX, 30, 9))
    pots = abc_callable.se_potentials + abc_callable.dl_potentials + abc.se_potentials + abc.dl_potentials
    vals = jax.jit(jax.vmap(lambda p: jnp.stack([P(p[0], p[1], p[2]) for P in pots])))(pts)
    vals = np.asarray(vals)
    np.testing.assert_allclose(vals[:, :4], vals[:, 4:], atol=1e-12)


def test_spec_abc_potentials_are_accepted_and_wrong_ones_rejected():
    F1 = C_ * sp.cos(x2) - B_ * x2 * sp.cos(x1) + A_ * sp.sin(x3)
    F3 = A_ * x2 * sp.sin(x3) + C_ * sp.sin(x2) + B_ * sp.cos(x1)
    f = Field.from_sympy(ABC, SYMBOLS, potentials={"se": (F1, F3)}, box=ABC_BOX)
    assert f.potential_methods["se"] == "user-supplied"
    assert f.se_potential_exprs == (F1, F3)
    assert f.reconstruction_error("se") <= 1e-12
    with pytest.raises(PotentialError, match="SE potentials"):
        Field.from_sympy(ABC, SYMBOLS, potentials={"se": (F1 + x2 * x3, F3)})


def test_quadrature_fallback_when_sympy_cannot_integrate():
    # ∫ sin(sin s) ds has no elementary antiderivative (SymPy gives up quickly)
    ex = (sp.sin(sp.sin(x2)), sp.sin(sp.sin(x3)), sp.sin(sp.sin(x1)))
    f = Field.from_sympy(ex, SYMBOLS, name="hard")
    assert f.potential_methods["se"].startswith("quadrature")
    assert f.se_potential_exprs is None
    assert f.reconstruction_error("se") <= 1e-12
    assert f.reconstruction_error("dl") <= 1e-12


def test_forced_quadrature_on_sympy_field_and_base_point():
    ex = (x2 * x3, x1**2 * x3, sp.exp(x1) * x2)
    f = Field.from_sympy(ex, SYMBOLS, closed_form=False, origin=(0.5, -0.25, 0.3), quadrature_n=12)
    assert f.potential_method == "quadrature(n=12)"
    # polynomial integrands of low degree: n = 12 is exact to rounding; exp(x1) is entire
    assert f.reconstruction_error("se") <= 1e-12
    assert f.reconstruction_error("dl") <= 1e-12


def test_user_callable_potentials_checked(abc_callable):
    A, B, C = 1.0, np.sqrt(2 / 3), np.sqrt(1 / 3)
    F1 = lambda a, b, c: C * jnp.cos(b) - B * b * jnp.cos(a) + A * jnp.sin(c)  # noqa: E731
    F3 = lambda a, b, c: A * b * jnp.sin(c) + C * jnp.sin(b) + B * jnp.cos(a)  # noqa: E731

    def a(x):
        return jnp.stack(
            [A * jnp.sin(x[2]) + C * jnp.cos(x[1]), B * jnp.sin(x[0]) + A * jnp.cos(x[2]),
             C * jnp.sin(x[1]) + B * jnp.cos(x[0])]
        )

    f = Field.from_callable(a, box=ABC_BOX, potentials={"se": (F1, F3)})
    assert f.se_potentials == (F1, F3)
    # issue #23: the missing pair is derived from the supplied one (its gauge), not from the field
    assert f.potential_methods == {"se": "user-supplied",
                                   "dl": "from the supplied potentials (gauge by quadrature, n=32)"}
    bad = lambda a_, b, c: F1(a_, b, c) + 0.1 * b * c  # noqa: E731
    with pytest.raises(PotentialError, match="do not reproduce"):
        Field.from_callable(a, box=ABC_BOX, potentials={"se": (bad, F3)})


# -- gauge invariance --------------------------------------------------------------------------
_coef = st.integers(-3, 3)


def _gauge_expr(c, u, v):
    """A random smooth function of two variables u, v (polynomial + trigonometric)."""
    return (
        c[0] * u * v + c[1] * u**2 + c[2] * v**3 + c[3] * sp.sin(u + c[4] * v) + c[5] * sp.cos(u) * v
    )


@settings(max_examples=10, deadline=None, derandomize=True)
@given(st.lists(_coef, min_size=6, max_size=6), st.sampled_from(["se", "dl"]))
def test_gauge_symbolic(c, splitting):
    # SE: a = curl(F1, 0, F3); adding ∇χ with χ = χ(x1, x3) keeps vf1(F1) + vf3(F3).
    # DL: a = curl(G1, G2, 0); adding ∇χ with χ = χ(x1, x2) keeps vf1(G1) + vf2(G2).
    base = Field.from_sympy(ABC, SYMBOLS, box=ABC_BOX)
    if splitting == "se":
        chi = _gauge_expr(c, x1, x3)
        P, Q = base.se_potential_exprs
        pair = (P + sp.diff(chi, x1), Q + sp.diff(chi, x3))
    else:
        chi = _gauge_expr(c, x1, x2)
        P, Q = base.dl_potential_exprs
        pair = (P + sp.diff(chi, x1), Q + sp.diff(chi, x2))
    assert all(r == 0 for r in _residual(ABC, pair, splitting))
    f = Field.from_sympy(ABC, SYMBOLS, potentials={splitting: pair}, box=ABC_BOX)
    assert f.potential_methods[splitting] == "user-supplied"


@pytest.fixture(scope="module")
def gauge_kernels(abc):
    """Jitted once: vf1(P + ∂χ) + vf(Q + ∂χ) at x for coefficient vector c (χ as in _gauge_expr)."""

    def chi(c, u, v):
        return c[0] * u * v + c[1] * u**2 + c[2] * v**3 + c[3] * jnp.sin(u + c[4] * v) + c[5] * jnp.cos(u) * v

    F1, F3 = abc.se_potentials
    G1, G2 = abc.dl_potentials
    d_u = jax.grad(chi, argnums=1)
    d_v = jax.grad(chi, argnums=2)

    def se(c, x):
        P = lambda a, b, d: F1(a, b, d) + d_u(c, a, d)  # noqa: E731
        Q = lambda a, b, d: F3(a, b, d) + d_v(c, a, d)  # noqa: E731
        return vf1(P)(x) + vf3(Q)(x)

    def dl(c, x):
        P = lambda a, b, d: G1(a, b, d) + d_u(c, a, b)  # noqa: E731
        Q = lambda a, b, d: G2(a, b, d) + d_v(c, a, b)  # noqa: E731
        return vf1(P)(x) + vf2(Q)(x)

    return {"se": jax.jit(jax.vmap(se, (None, 0))), "dl": jax.jit(jax.vmap(dl, (None, 0)))}


@HYP
@given(
    st.lists(st.floats(-3, 3, allow_nan=False), min_size=6, max_size=6),
    st.integers(0, 2**31 - 1),
    st.sampled_from(["se", "dl"]),
)
def test_gauge_numeric(gauge_kernels, abc, c, seed, splitting):
    pts = jnp.asarray(_pts(ABC_BOX, 16, seed))
    got = np.asarray(gauge_kernels[splitting](jnp.asarray(c), pts))
    want = np.asarray(abc(pts))
    assert np.max(np.abs(got - want)) <= 1e-11 * (1 + max(abs(v) for v in c))


def test_non_gauge_change_is_detected():
    base = Field.from_sympy(ABC, SYMBOLS, box=ABC_BOX)
    P, Q = base.se_potential_exprs
    chi = x1 * x2 * x3  # depends on x2: ∇χ is not an SE gauge
    with pytest.raises(PotentialError):
        Field.from_sympy(ABC, SYMBOLS, potentials={"se": (P + sp.diff(chi, x1), Q + sp.diff(chi, x3))})


# -- linear fields -----------------------------------------------------------------------------
def test_linear_field():
    A = np.array([[0.5, 2.0, -1.0], [0.3, -1.5, 0.7], [1.1, 0.2, 1.0]])
    f = Field.linear(A)
    np.testing.assert_array_equal(f.linear_matrix, A)
    pts = _pts(f.box, 40, 4)
    np.testing.assert_allclose(np.asarray(f(pts)), pts @ A.T, atol=1e-15)
    np.testing.assert_allclose(np.asarray(f.jacobian(pts[0])), A, atol=1e-15)
    assert f.potential_method == "closed form"
    for pair in (f.se_potential_exprs, f.dl_potential_exprs):
        for p in pair:  # quadratic forms
            assert sp.Poly(p, *SYMBOLS).total_degree() == 2
    assert f.reconstruction_error("se") <= 1e-12 and f.reconstruction_error("dl") <= 1e-12


def test_linear_detected_for_sympy_fields():
    a, b = sp.Rational(1, 3), sp.Integer(2)
    f = Field.from_sympy((a * x1 + b * x3, x1 - a * x2, 5 * x2), SYMBOLS)
    np.testing.assert_allclose(f.linear_matrix, [[1 / 3, 0, 2], [1, -1 / 3, 0], [0, 5, 0]], atol=1e-16)
    assert Field.from_sympy((x2**2, x3, x1), SYMBOLS).linear_matrix is None
    assert Field.from_sympy((x2 + 1, x3, x1), SYMBOLS).linear_matrix is None  # affine, not linear


def test_linear_trace_error_names_trace():
    with pytest.raises(ValueError, match=r"tr A = 0.75"):
        Field.linear(np.diag([1.0, -0.5, 0.25]))
    with pytest.raises(ValueError, match="3×3"):
        Field.linear(np.zeros((2, 2)))


# -- errors --------------------------------------------------------------------------------------
def test_not_divergence_free_sympy_reports_largest_and_where():
    box = ((-1, 1), (-2, 2), (0, 1))
    with pytest.raises(NotDivergenceFreeError) as info:
        Field.from_sympy((x1**3, x3, x2), SYMBOLS, box=box)
    err = info.value
    assert "not divergence free" in str(err) and "at x =" in str(err)
    # the reported value is the divergence 3 x1² at the reported point, close to the max 3
    assert abs(err.max_divergence - 3 * err.where[0] ** 2) <= 1e-12
    assert err.max_divergence > 2.7


def test_not_divergence_free_callable_reports_largest_and_where():
    with pytest.raises(NotDivergenceFreeError) as info:
        Field.from_callable(lambda x: jnp.stack([x[0] * x[1], x[2], x[0]]), box=((-1, 1), (-3, 3), (-1, 1)))
    err = info.value
    assert abs(err.max_divergence - abs(err.where[1])) <= 1e-12  # div = x2
    assert err.max_divergence > 2.5
    # a tiny divergence passes only if below the tolerance
    with pytest.raises(NotDivergenceFreeError):
        Field.from_callable(lambda x: jnp.stack([1e-6 * x[0], x[2], x[0]]), tol=1e-10)
    Field.from_callable(lambda x: jnp.stack([1e-13 * x[0], x[2], x[0]]), tol=1e-10)


@pytest.mark.parametrize(
    "exprs, symbols, match",
    [
        ((x1, x2), SYMBOLS, "three"),
        ((x2, x3, x1, x1), SYMBOLS, "three"),
        ((x2, x3, x1), (x1, x2), "three"),
        ((x2, x3, x1), (x1, x1, x2), "distinct"),
        ((x2 + sp.Symbol("k"), x3, x1), SYMBOLS, "free symbols"),
        ((True, x3, x1), SYMBOLS, "scalar SymPy expression"),
        (([x2], x3, x1), SYMBOLS, "scalar SymPy expression"),
        ((sp.Eq(x2, 1), x3, x1), SYMBOLS, "scalar SymPy expression"),
    ],
)
def test_malformed_sympy_input(exprs, symbols, match):
    with pytest.raises(ValueError, match=match):
        Field.from_sympy(exprs, symbols)


def test_params_are_substituted():
    k = sp.Symbol("k")
    f = Field.from_sympy((k * x2, x3, x1), SYMBOLS, params={"k": 2.5})
    assert f.params == {"k": 2.5}
    np.testing.assert_allclose(np.asarray(f(jnp.array([0.0, 2.0, 0.0]))), [5.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="number"):
        Field.from_sympy((k * x2, x3, x1), SYMBOLS, params={k: x1})


def test_malformed_shapes_and_callables(abc):
    for bad in (np.zeros(2), np.zeros((4, 2)), np.float64(1.0), np.zeros((3, 4))):
        with pytest.raises(ValueError, match=r"shape \(3,\) or \(N, 3\)"):
            abc(bad)
        with pytest.raises(ValueError):
            abc.jacobian(bad)
    with pytest.raises(ValueError, match="shape"):
        Field.from_callable(lambda x: x[:2])
    with pytest.raises(ValueError, match="three"):
        Field.from_callable((lambda a, b, c: a, lambda a, b, c: b))
    with pytest.raises(ValueError, match="scalar"):
        Field.from_callable((lambda a, b, c: jnp.stack([a, b]), lambda a, b, c: a, lambda a, b, c: b))
    with pytest.raises(ValueError, match="box"):
        Field.from_callable(lambda x: x[::-1], box=((0, 1), (0, 1)))
    with pytest.raises(ValueError, match="splitting"):
        abc.potentials("xx")
    with pytest.raises(ValueError, match="pair"):
        Field.from_sympy(ABC, SYMBOLS, potentials={"se": (x1,)})
    with pytest.raises(ValueError, match="scalar SymPy expressions"):
        Field.from_sympy(ABC, SYMBOLS, potentials={"se": ([x1], x2)})
    with pytest.raises(ValueError, match="not finite"):
        Field.from_sympy(ABC, SYMBOLS, potentials={"se": (sp.nan, x2)})


# -- quadrature ----------------------------------------------------------------------------------
def test_gauss_legendre_nodes():
    t, w = gauss_legendre_01(7)
    assert abs(w.sum() - 1) < 1e-15 and np.all((t > 0) & (t < 1))
    for k in range(14):  # exact for degree ≤ 2n − 1
        assert abs(np.dot(w, t**k) - 1 / (k + 1)) < 1e-15
    with pytest.raises(ValueError):
        gauss_legendre_01(0)


@HYP
@given(st.floats(-4, 4), st.floats(-4, 4), st.floats(0.1, 3))
def test_line_integral_and_its_derivatives(lo, up, k):
    f = lambda s: jnp.cos(k * s)  # noqa: E731
    exact = (np.sin(k * up) - np.sin(k * lo)) / k
    val = float(line_integral(f, lo, up, 32))
    assert abs(val - exact) <= 1e-13
    # the derivative in the upper limit is the integrand (through the quadrature)
    d = float(jax.grad(lambda u: line_integral(f, lo, u, 32))(up))
    assert abs(d - np.cos(k * up)) <= 1e-13
    d_lo = float(jax.grad(lambda u: line_integral(f, u, up, 32))(lo))
    assert abs(d_lo + np.cos(k * lo)) <= 1e-13


def test_gl_error_bound_is_a_bound():
    # ∫₀¹ e^{s} ds with n = 3: |E| ≤ bound with max |f^{(6)}| = e
    t, w = gauss_legendre_01(3)
    err = abs(np.dot(w, np.exp(t)) - (np.e - 1))
    bound = gl_error_bound(3, np.e, 1.0)
    assert err <= bound and bound < 1e-5


# -- review: exact divergence is decided exactly; bad input is a clear ValueError --------------------
def test_an_exactly_nonzero_divergence_is_never_accepted_numerically():
    # div a = 1/10⁷ exactly, tiny next to max|∂a_i/∂x_j| = 10⁶: a relative numerical tolerance
    # would pass it, but SymPy *decides* it is not 0
    big = 10**6
    for extra in (x1 / 10**7, sp.sin(x1) / 10**7):
        with pytest.raises(NotDivergenceFreeError, match="is not 0"):
            Field.from_sympy((big * sp.sin(x2) + extra, x3, x1), SYMBOLS)
    # rounding in Float coefficients is still judged with a tolerance
    A = np.array([[1.0, 2.0, 0.0], [0.0, -1.0, 1.0], [1.0, 0.0, 5e-13]])
    assert Field.linear(A).divergence_check.startswith(("symbolic", "numerical ("))


@pytest.mark.parametrize("bad, match", [
    ((sp.nan, x3, x1), "not finite"),
    ((sp.zoo, x3, x1), "not finite"),
    ((sp.I * x2, x3, x1), "not real"),
])
def test_non_finite_or_complex_components_are_rejected(bad, match):
    with pytest.raises(ValueError, match=match):
        Field.from_sympy(bad, SYMBOLS)


def test_params_must_name_parameters_of_the_field():
    k = sp.Symbol("k")
    with pytest.raises(ValueError, match="unknown parameter 'kk'"):
        Field.from_sympy((k * x2, x3, x1), SYMBOLS, params={"k": 1.0, "kk": 2.0})
    with pytest.raises(ValueError, match="coordinate"):
        Field.from_sympy((k * x2, x3, x1), SYMBOLS, params={"k": 1.0, "x1": 0.0})
    with pytest.raises(ValueError, match="finite"):
        Field.from_sympy((k * x2, x3, x1), SYMBOLS, params={"k": sp.oo})


def test_non_traceable_callables_and_bad_matrices_raise_value_error():
    with pytest.raises(ValueError, match="JAX-traceable"):
        Field.from_callable(lambda v: np.array([np.sin(v[1]), v[2], v[0]]))
    with pytest.raises(ValueError, match="JAX-traceable"):
        Field.from_callable((lambda a, b, c: float(b), lambda a, b, c: c, lambda a, b, c: a))
    with pytest.raises(ValueError, match="3×3 matrix of numbers"):
        Field.linear([["a", 0, 0], [0, 0, 0], [0, 0, 0]])
    # the trace tolerance is relative to the matrix: a tiny non-traceless matrix is not accepted
    with pytest.raises(ValueError, match="tr A"):
        Field.linear(np.diag([1e-14, 1e-14, 1e-14]))


def test_components_jax_cannot_evaluate_are_rejected_at_construction():
    with pytest.raises(ValueError, match="undefined functions"):
        Field.from_sympy((sp.Function("g")(x2), x3, x1), SYMBOLS)
    with pytest.raises(ValueError, match="cannot be evaluated with JAX"):
        Field.from_sympy((sp.besselj(0, x2), x3, x1), SYMBOLS)

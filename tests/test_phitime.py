"""φ as the independent variable, still exactly volume preserving (issue #24 item 1, vpforms.phitime).

The fields are the Solov'ev tokamak of tests/test_toroidal.py (B_φ = g/R, Cartesian A): the
perturbed one (ε = 0.02, 3 field periods; U(v, φ, Z) by Newton) and the axisymmetric one (ε = 0,
where v = g ln R gives the closed form U = e^{2v/g}/2). Every expected value is computed here: the
field-line flow from the Cartesian A by autodiff, section references by DOP853 in φ, orders by
least-squares fits.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from jax import lax
from scipy.integrate import solve_ivp

import vpforms
from vpforms import RESULTS
from vpforms._vecpot import CallablePotential, curl_of
from vpforms.phitime import (
    PhiTimeCoordinates,
    PhiTimeError,
    PhiTimePotential,
    advances_phi_exactly,
    from_phi_time,
    phi_exact_cases,
    phi_time_field,
    phi_time_scheme,
    to_phi_time,
)
from vpforms.toroidal import ToroidalPotential, box_from_cylindrical

from .test_methods_helpers import fit_order
from .test_toroidal import EPS, KAP, NFP, PERIOD, A_cart, C, G

BOX = box_from_cylindrical((0.7, 1.3), (0, PERIOD), (-0.4, 0.4))
RZ0 = np.array([[1.1, 0.0], [1.2, 0.05], [0.9, -0.1]])  # (R, Z) of the traced lines at φ = 0


def A_axi(x):
    """The axisymmetric Solov'ev field: A_cart of tests/test_toroidal.py with ε = 0."""
    X, Y, Z = x[0], x[1], x[2]
    R2 = X * X + Y * Y
    p = psi(jnp.sqrt(R2), Z)
    return jnp.stack([-p * Y / R2, p * X / R2, -0.5 * G * jnp.log(R2)])


@pytest.mark.slow  # ~2 s; a sanity identity of the test fields
def test_the_axisymmetric_field_is_the_perturbed_one_at_eps_0():
    x = uniform(((0.5, 1.5), (-1, 1), (-0.5, 0.5)), 16, 0)
    pert = np.asarray(jax.vmap(A_cart)(jnp.asarray(x)))
    perturbation = EPS * x[:, 2] * (x[:, 0] ** 3 - 3 * x[:, 0] * x[:, 1] ** 2)
    np.testing.assert_allclose(np.asarray(jax.vmap(A_axi)(jnp.asarray(x))), pert - np.outer(perturbation, [0, 0, 1]),
                               rtol=0, atol=1e-15)


def A_reversed(x):
    """The perturbed field with B_φ reversed (g → −g): B^φ < 0 on the whole box."""
    X, Y = x[0], x[1]
    return A_cart(x) + jnp.stack([0.0 * X, 0.0 * X, G * jnp.log(X * X + Y * Y)])


def A_turning(x):
    """B_φ = g(R − 1): B^φ changes sign on R = 1, inside the box."""
    X, Y = x[0], x[1]
    R = jnp.sqrt(X * X + Y * Y)
    return A_axi(x) + jnp.stack([0.0 * X, 0.0 * X, 0.5 * G * jnp.log(X * X + Y * Y) - 0.5 * G * (R - 1.0) ** 2])


def A_gauged(x):
    """A_cart + ∇λ: the same field, with A_u ≠ 0 (so φ-time needs χ = ∫A_u du by quadrature)."""
    lam = lambda p: 0.1 * p[0] * p[1] * p[2] + 0.05 * jnp.sin(p[0]) + 0.02 * p[2] ** 2 * p[0]
    return A_cart(x) + jax.grad(lam)(x)


def U_axi(v, phi, Z):
    """The closed-form inverse for B_φ = g/R: v = −A_Z = g ln R = (g/2) ln 2u."""
    return 0.5 * jnp.exp(2.0 * v / G)


def psi(R, Z):
    return C / 2 * (R**2 * Z**2 + KAP**2 / 4 * (R**2 - 1) ** 2)


def cartesian_B(A):
    return jax.jit(jax.vmap(curl_of([lambda x, y, z, i=i: A(jnp.stack([x, y, z]))[i] for i in range(3)])))


def toroidal_flow(A):
    """x ↦ a(x) in (u, φ, Z), the curl of the covariant A (vpforms.toroidal), batched."""
    return jax.jit(jax.vmap(curl_of(ToroidalPotential(A, NFP).components())))


@pytest.fixture(scope="module")
def pert_coords():
    """The perturbed field's (u, φ, Z) ↔ (v, φ, Z) (U by Newton), without building the Field (whose
    divergence check compiles second derivatives of K: the fast tests need first ones only)."""
    return PhiTimeCoordinates(ToroidalPotential(A_cart, NFP), BOX)


@pytest.fixture(scope="module")
def pert():
    return phi_time_field(ToroidalPotential(A_cart, NFP), BOX, name="solovev-3 phi-time")


@pytest.fixture(scope="module")
def axi():
    return phi_time_field(A_axi, BOX, nfp=NFP, inverse=U_axi, name="solovev phi-time")  # a Cartesian A


@pytest.fixture(scope="module")
def axi_se(axi):
    return phi_time_scheme(axi, "SE+SE")


def uniform(box, n, seed):
    lo, hi = np.array(box, float).T
    return np.random.default_rng(seed).uniform(lo, hi, (n, 3))


_KERNELS: dict = {}


def step_and_jacobian(method):
    """One compile per method: (y (N, 3), h) → (Y, status, ∂Y/∂y) of one step of size h."""
    if method not in _KERNELS:
        def one(y, h):
            def f(z):
                Y, s = method.step_with_status(z, h)
                return Y, (Y, s)

            J, (Y, s) = jax.jacfwd(f, has_aux=True)(y)
            return Y, s, J

        _KERNELS[method] = jax.jit(jax.vmap(one, in_axes=(0, None)))
    return _KERNELS[method]


def assert_phi_exact_and_volume_preserving(method, y, h):
    Y, status, J = (np.asarray(t) for t in step_and_jacobian(method)(jnp.asarray(y), h))
    assert np.all(status == RESULTS.successful)
    np.testing.assert_allclose(np.linalg.det(J), 1.0, rtol=0, atol=1e-12)
    # φ' = 1: the step's φ is φ + h to rounding (a composition adds its stages' γ_i h)
    ulp = np.spacing(np.abs(y[:, 1]) + abs(h))
    assert np.all(np.abs(Y[:, 1] - (y[:, 1] + h)) <= 16 * ulp), Y[:, 1] - y[:, 1] - h
    return Y


# ------------------------------------------------------------------------------------------------
# the coordinates (u, φ, Z) ↔ (v, φ, Z) and the field
# ------------------------------------------------------------------------------------------------
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_coordinates_round_trip(pert_coords, seed):
    c = pert_coords
    x = uniform(BOX, 16, seed)
    y = np.asarray(to_phi_time(c, x))
    np.testing.assert_allclose(np.asarray(from_phi_time(c, y)), x, rtol=0, atol=1e-13)
    yb = uniform(c.ybox, 16, seed + 1)  # the (v, φ, Z) box lies in the image of the (u, φ, Z) box
    xb = np.asarray(from_phi_time(c, yb))
    assert np.all((xb[:, 0] >= BOX[0][0]) & (xb[:, 0] <= BOX[0][1]))
    np.testing.assert_allclose(np.asarray(to_phi_time(c, xb)), yb, rtol=0, atol=1e-13)
    # traceable: vmap and jit of the point maps agree with the batched call; any leading shape
    per_point = jax.jit(jax.vmap(lambda p: to_phi_time(c, p)))(jnp.asarray(x))
    np.testing.assert_array_equal(np.asarray(per_point), y)
    np.testing.assert_array_equal(np.asarray(to_phi_time(c, x.reshape(4, 4, 3))), y.reshape(4, 4, 3))


@pytest.mark.slow  # builds two φ-time Fields (divergence check: second derivatives of K through U), ~20 s
def test_the_field_and_its_metadata(axi, axi_se, pert_coords):
    assert axi.coordinates.startswith("phi-time")
    assert axi.periods == (None, PERIOD, None)
    assert axi.phi_time.sign == 1 and axi.phi_time.inverse == "closed form"
    assert pert_coords.sign == 1 and pert_coords.inverse == "newton"
    assert "A_u = 0" in pert_coords.gauge  # the covariant A_u = A_R/R of this A vanishes
    y = uniform(axi.box, 4, 2)  # field, method and coordinates convert alike
    for obj in (axi, axi_se, axi.phi_time):
        np.testing.assert_array_equal(np.asarray(from_phi_time(obj, y)), np.asarray(from_phi_time(axi, y)))
    # v is increasing in u; outside the image of the u interval U is NaN and `inside` is false
    c = pert_coords
    (v0, v1), _, _ = c.ybox
    assert float(c.V(BOX[0][0], 0.3, 0.1)) < v0 < v1 < float(c.V(BOX[0][1], 0.3, 0.1))
    far = jnp.array([float(c.V(BOX[0][1], 0.3, 0.1)) + 0.1, 0.3, 0.1])
    assert np.isnan(float(c.to_x(far)[0])) and not bool(c.inside(far))
    assert bool(c.inside(jnp.array([0.5 * (v0 + v1), 0.3, 0.1])))
    with pytest.raises(TypeError, match="phi-time"):
        to_phi_time(object(), np.zeros(3))
    with pytest.raises(ValueError, match="nfp"):
        phi_time_field(ToroidalPotential(A_axi, NFP), BOX, nfp=NFP)
    with pytest.raises(ValueError, match="not the inverse"):
        PhiTimeCoordinates(ToroidalPotential(A_axi, NFP), BOX, inverse=lambda v, p, z: jnp.exp(v / G))


@pytest.mark.slow  # ~8 s each (the Newton inverse under jvp)
@pytest.mark.parametrize("which", ["perturbed", "reversed B_φ", "gauge A + ∇λ"])
def test_b_is_the_field_line_flow_with_phi_as_time(pert_coords, which):
    """The flow of b = ∇_y×(0, K, −v) pushed to (u, φ, Z) is a/a²: (dU/dφ, 1, dZ/dφ) = a/B^φ,
    with a = ∇×A of the Cartesian A (tests/test_toroidal.py), to 1e-12 relative. For B^φ < 0 the
    orientation is φ' = +1 still (the lines are followed against B)."""
    if which == "perturbed":
        A, coords = A_cart, pert_coords
    elif which == "reversed B_φ":
        A = A_reversed
        coords = PhiTimeCoordinates(ToroidalPotential(A, NFP), BOX)
        assert coords.sign == -1
    else:  # the field of A_cart from another potential: the gauge A_u = 0 by quadrature
        A = A_cart
        coords = PhiTimeCoordinates(ToroidalPotential(A_gauged, 1), BOX)  # λ is not 3-periodic
        assert coords.gauge.startswith("A_u removed by χ") and coords.sign == 1
    b = curl_of(PhiTimePotential(coords).components())  # what the Field evaluates
    a = curl_of(ToroidalPotential(A, NFP).components())

    def one(x):  # one compile: y, b(y), the push-forward of b, a(x), ∇K(y)
        y = coords.to_y(x)
        by = b(y)
        dK = jax.grad(lambda q: coords.K(q[0], q[1], q[2]))(y)
        return by, jax.jvp(coords.to_x, (y,), (by,))[1], a(x), dK

    bx, dx, ax, dK = (np.asarray(t) for t in jax.jit(jax.vmap(one))(jnp.asarray(uniform(BOX, 64, 3))))
    np.testing.assert_array_equal(bx[:, 1], 1.0)  # ∂_Z(0) − ∂_v(−v)
    expect = ax / ax[:, 1:2]
    np.testing.assert_allclose(dx, expect, rtol=0, atol=1e-12 * np.abs(expect).max())
    # Hamilton's equations with H = K: dv/dφ = −∂_Z K, dZ/dφ = ∂_v K
    np.testing.assert_allclose(bx[:, [0, 2]], np.stack([-dK[:, 2], dK[:, 0]], -1), rtol=0, atol=1e-14)


DERIVATIVES = {0: lambda f: f, 1: jax.grad, 2: jax.hessian, 3: lambda f: jax.jacfwd(jax.hessian(f))}


@pytest.mark.slow  # 5 s (order 2), ~10 s (order 3); the fast push-forward test checks first derivatives
@pytest.mark.parametrize("order", [2, 3])
def test_newton_inverse_has_exact_derivatives(pert_coords, order):
    """U by Newton (a custom_jvp by the implicit function theorem) against the closed form
    U = e^{2v/g}/2 of the axisymmetric field: value and derivatives (to the third order a step's
    Jacobian takes of K) agree to rounding; ∂U/∂v = 1/B^φ on the perturbed field."""
    newton = PhiTimeCoordinates(ToroidalPotential(A_axi, NFP), BOX)
    assert newton.inverse == "newton"
    fn = lambda q: newton.U(q[0], q[1], q[2])
    fc = lambda q: U_axi(q[0], q[1], q[2])
    y = jnp.asarray(uniform(newton.ybox, 4, 5))
    ks = (0, order) if order < 3 else (3,)
    got = jax.jit(jax.vmap(lambda q: [DERIVATIVES[k](fn)(q) for k in ks]))(y)  # one compile
    for k, g in zip(ks, got):
        want = np.asarray(jax.vmap(DERIVATIVES[k](fc))(y))
        np.testing.assert_allclose(np.asarray(g), want, rtol=0, atol=1e-13 * np.abs(want).max(), err_msg=f"order {k}")
    if order == 2:
        c = pert_coords

        def one(x):
            return jax.grad(lambda q: c.U(q[0], q[1], q[2]))(c.to_y(x))[0] * c.B_phi(x[0], x[1], x[2])

        np.testing.assert_allclose(np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(uniform(BOX, 8, 6)))), 1.0, rtol=1e-13)


def test_b_phi_changing_sign_is_a_clear_error():
    """B_φ = g(R − 1) vanishes inside the box: the error names a point of B^φ = 0 (R = 1)."""
    with pytest.raises(PhiTimeError, match=r"changes sign.*turns back toroidally.*time stepping") as err:
        phi_time_field(ToroidalPotential(A_turning, NFP), BOX)
    p = err.value.point
    assert abs(np.sqrt(2 * p[0]) - 1.0) <= 1e-12
    a = np.asarray(toroidal_flow(A_turning)(jnp.asarray(p[None])))[0]
    assert abs(a[1]) <= 1e-12 * np.abs(a).max()


# ------------------------------------------------------------------------------------------------
# the methods: exactly volume preserving, φ advanced by exactly h
# ------------------------------------------------------------------------------------------------
@pytest.mark.slow  # ~20 s (the closed-form field's Jacobian); the model-field test below is the fast one
def test_phi_exact_se_se_step_preserves_volume(axi, axi_se):
    assert advances_phi_exactly(axi_se.case) and axi_se.case in phi_exact_cases("SE+SE")
    y = uniform(axi.box, 6, 7)
    assert_phi_exact_and_volume_preserving(axi_se, y, PERIOD / 32)


def test_which_cases_advance_phi_exactly():
    """The rule of advances_phi_exactly against the steps, for SE+SE's representative (its pair is
    gauged along φ: not exact) and its φ-exact cases, on a cheap field of the same form
    C = (0, K, −v) (closed-form K). All 36 cases: the slow test below."""
    field = model_field()
    y = jnp.asarray(uniform(field.box, 4, 8))
    h = 0.05
    rep = vpforms.scheme(field, "SE+SE", recover=False)
    assert not advances_phi_exactly(rep.case)
    Y, s = jax.vmap(lambda q: rep.step_with_status(q, h))(y)
    assert np.all(np.asarray(s) == 0) and np.abs(np.asarray(Y[:, 1] - y[:, 1] - h)).min() > 1e-8
    exact = phi_exact_cases("SE+SE")
    assert exact and rep.case not in exact
    assert_phi_exact_and_volume_preserving(vpforms.scheme(field, exact[-1], recover=False), np.asarray(y), h)


def model_field():
    def K(v, p, z):
        return 0.5 * v * v + 0.3 * jnp.cos(z) + 0.1 * v * jnp.sin(p) * jnp.cos(z)

    Cp = CallablePotential([0, K, lambda v, p, z: -v + 0 * p], periods=(None, 2 * np.pi, None))
    return vpforms.Field.from_vector_potential(Cp, box=((-1, 1), (0, 2 * np.pi), (-1, 1)))


def model_field_sympy():
    """The model field b = ∇×(0, K, −v) = (−∂_Z K, 1, ∂_v K) of :func:`model_field` as SymPy
    expressions: the same flow, with closed-form potentials (a step compiles in ~1 s where the
    quadrature potentials of the callable take 1.5–12 s)."""
    v, p, z = sp.symbols("x1 x2 x3")
    K = sp.Rational(1, 2) * v**2 + sp.Rational(3, 10) * sp.cos(z) + sp.Rational(1, 10) * v * sp.sin(p) * sp.cos(z)
    return vpforms.Field.from_sympy([-sp.diff(K, z), sp.Integer(1), sp.diff(K, v)],
                                    box=((-1, 1), (0, 2 * np.pi), (-1, 1)))


def test_the_model_fields_are_one_flow():
    """The callable model field (quadrature potentials) and its SymPy form are the same b."""
    y = jnp.asarray(uniform(((-1, 1), (0, 2 * np.pi), (-1, 1)), 8, 3))
    a, b = model_field(), model_field_sympy()
    np.testing.assert_allclose(np.asarray(a(y)), np.asarray(b(y)), rtol=0, atol=1e-14)


@pytest.mark.slow  # one step per case, no Jacobian (volume: the tests above and the 36-case matrices)
@pytest.mark.parametrize("c", vpforms.cases(), ids=lambda c: f"{c.cls}-{c}")  # one case per test (xdist)
def test_all_36_cases_advance_phi_exactly_where_the_rule_says(c):
    """The rule of advances_phi_exactly against one step of every case: φ advanced by h to 16 ulp
    where it says so, by more than 1e-8 away from h where it does not.  On the SymPy form of the
    model field (closed-form potentials, as every formula field's φ-time field has); the fast test
    above checks the rule on the callable form too."""
    field = model_field_sympy()
    y = jnp.asarray(uniform(field.box, 3, 9))
    h = 0.05
    ulp = np.spacing(np.abs(np.asarray(y[:, 1])) + h)
    opts = {"fast": True} if c.cls in ("DL+DL", "SE+DL") else {}
    m = vpforms.scheme(field, c, recover=False, **opts)
    Y, s = m.step_with_status(y, h)  # the method's own batched jit (one compile)
    assert np.all(np.asarray(s) == RESULTS.successful), c
    off = np.abs(np.asarray(Y[:, 1] - y[:, 1]) - h)
    if advances_phi_exactly(c):
        assert np.all(off <= 16 * ulp), (c, off)
    else:
        assert off.max() > 1e-8, c


@pytest.mark.slow  # 18–70 s each, ≤ 1.9 GB (the DL classes on the Newton inverse: ~4 min each, not run here)
@pytest.mark.parametrize("field_name,cls", [("axi", "DL+DL"), ("axi", "SE+DL"), ("pert", "SE+SE")])
def test_phi_exact_methods_preserve_volume(request, field_name, cls):
    """One step of each φ-exact method (compositions of them: the section tests, which check φ of
    every section point to 1e-11)."""
    field = request.getfixturevalue(field_name)
    m = phi_time_scheme(field, cls)
    assert_phi_exact_and_volume_preserving(m, uniform(field.box, 4, 10), PERIOD / 32)


# ------------------------------------------------------------------------------------------------
# the same section points as the field lines
# ------------------------------------------------------------------------------------------------
def reference_sections(A, transits):
    """(R, Z) at φ = 2πk/nfp, k = 0…transits, of dR/dφ = R B_R/B_φ, dZ/dφ = R B_Z/B_φ (B from the
    Cartesian A by autodiff), DOP853 at rtol 1e-12."""
    B = cartesian_B(A)

    def rhs(phi, s):
        R, Z = s.reshape(-1, 2).T
        c, sn = np.cos(phi), np.sin(phi)
        b = np.asarray(B(np.stack([R * c, R * sn, Z], -1)))
        BR, Bp = b[:, 0] * c + b[:, 1] * sn, -b[:, 0] * sn + b[:, 1] * c
        return np.stack([R * BR / Bp, R * b[:, 2] / Bp], -1).ravel()

    phis = PERIOD * np.arange(transits + 1)
    sol = solve_ivp(rhs, (0, phis[-1]), RZ0.ravel(), method="DOP853", rtol=1e-12, atol=1e-14, t_eval=phis)
    assert sol.success
    return sol.y.T.reshape(transits + 1, -1, 2)


_RUNNERS: dict = {}


def runner(method):
    """(y (N, 3), h, k) → k steps of size h: one compile per method for every n."""
    if method not in _RUNNERS:
        step = jax.vmap(lambda y, h: method.step_with_status(y, h)[0], in_axes=(0, None))
        _RUNNERS[method] = jax.jit(lambda y, h, k: lax.fori_loop(0, k, lambda i, q: step(q, h), y))
    return _RUNNERS[method]


def traced_sections(field, method, n, transits, reuse_kernel=False):
    """(R, Z) and φ at the end of every n steps of size 2π/(nfp n): the section points.
    ``reuse_kernel``: step by the (already compiled) step-and-Jacobian kernel, for short runs."""
    if reuse_kernel:
        kern = step_and_jacobian(method)

        def run(y, h, k):
            for _ in range(k):
                y = kern(y, h)[0]
            return y
    else:
        run = runner(method)
    x0 = np.stack([0.5 * RZ0[:, 0] ** 2, 0 * RZ0[:, 0], RZ0[:, 1]], -1)
    y = to_phi_time(field, x0)
    ys = [np.asarray(y)]
    for _ in range(transits):
        y = run(y, PERIOD / n, n)
        ys.append(np.asarray(y))
    ys = np.stack(ys)
    x = np.asarray(from_phi_time(field, ys))
    return np.stack([np.sqrt(2 * x[..., 0]), x[..., 2]], -1), ys[..., 1]


def section_errors(field, A, order, ns, transits=20, method=None):
    ref = reference_sections(A, transits)
    m = phi_time_scheme(field, "SE+SE", order=order) if method is None else method
    errs = []
    for n in ns:
        RZ, phi = traced_sections(field, m, n, transits, reuse_kernel=method is not None)
        # the k-th section point is at φ = 2πk/nfp up to the rounding of the sums of h
        want = np.broadcast_to(PERIOD * np.arange(transits + 1)[:, None], phi.shape)
        np.testing.assert_allclose(phi, want, rtol=0, atol=1e-11)
        errs.append(float(np.abs(RZ - ref).max()))
    return np.asarray(errs)


@pytest.mark.slow  # ~12 s
def test_sections_converge_at_the_method_order_axisymmetric(axi, axi_se):
    """The φ-exact SE+SE (order 1; its kernel compiled once for the volume test above) gives the
    section points of the field lines (10 transits), converging at order 1 (orders 2 and 4, 20
    transits, both fields: slow tier)."""
    ns = (16, 32, 64)
    errs = section_errors(axi, A_axi, 1, ns, transits=10, method=axi_se)
    slope = fit_order(PERIOD / np.array(ns), errs)
    assert np.all(np.diff(errs) < 0) and abs(slope - 1) <= 0.2, (errs, slope)


@pytest.mark.slow  # 9–13 s (axi), 33–38 s (pert: the Newton inverse compiles slowly); ≤ 1.6 GB
@pytest.mark.parametrize("field_name,order", [("axi", 4), ("pert", 1), ("pert", 2), ("pert", 4)])
def test_sections_converge_at_the_method_order(request, field_name, order):
    field = request.getfixturevalue(field_name)
    A = A_axi if field_name == "axi" else A_cart
    ns = (16, 32, 64)
    errs = section_errors(field, A, None if order == 1 else order, ns)
    slope = fit_order(PERIOD / np.array(ns), errs)
    print(f"{field_name} order {order}: n = {ns}, errors {errs}, slope {slope:.3f}")
    assert np.all(np.diff(errs) < 0) and abs(slope - order) <= 0.2, (errs, slope)


@pytest.mark.slow  # ~1 min: 10⁴ transits × 32 steps × 3 lines
def test_invariant_circles_stay_thin(axi):
    """ψ is conserved by the exact flow of the axisymmetric field; the section points of a φ-exact
    order-4 SE+SE (32 steps per transit, 10⁴ transits) lie on one smooth closed curve: the
    residual of a Fourier fit of ψ(θ) (θ the poloidal angle about the axis R = 1, Z = 0) is the
    thickness of the numerical surface, ≤ 1e-9 in ψ (in metres: ÷|∇ψ|) and the spread of ψ does
    not grow from the first 100 transits to the last."""
    transits, n = 10_000, 32
    m = phi_time_scheme(axi, "SE+SE", order=4)
    RZ, _ = traced_sections(axi, m, n, transits)
    assert np.all(np.isfinite(RZ))
    R, Z = RZ[..., 0], RZ[..., 1]
    p = psi(R, Z)
    theta = np.arctan2(Z, R - 1.0)
    gradpsi = np.hypot(C * (R * Z * Z + KAP**2 / 2 * (R**2 - 1) * R), C * R * R * Z)
    for j in range(RZ.shape[1]):
        modes = np.arange(1, 25)
        basis = np.column_stack([np.ones(len(theta))] + [f(k * theta[:, j]) for k in modes for f in (np.cos, np.sin)])
        coef, *_ = np.linalg.lstsq(basis, p[:, j], rcond=None)
        thick = np.abs(basis @ coef - p[:, j]).max()
        spread_first = np.ptp(p[:100, j])
        spread_all = np.ptp(p[:, j])
        metres = thick / gradpsi[:, j].min()
        print(f"line {j}: ψ spread {spread_all:.3e} (first 100 transits {spread_first:.3e}), "
              f"thickness {thick:.3e} in ψ = {metres:.3e} m")
        assert metres <= 1e-9
        assert spread_all <= 1.5 * spread_first + 1e-14

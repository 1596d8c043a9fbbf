"""The generic generating map (eq:volpot) for all 36 cases: volume, inverse, relabelling, errors.

Every expected value is computed here, independently of the library's own code paths: the
defining equations are re-derived from the case roles with ``jax.grad``, and the Jacobian is
re-derived by the implicit function theorem from that residual.
"""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vpforms import (
    RESULTS,
    Case,
    ConvergenceError,
    GeneratingMap,
    NonFiniteError,
    Perm,
    TwistConditionError,
    VPFormsError,
    cases,
)

MONOMIALS = [m for m in itertools.product(range(4), repeat=3) if 0 < sum(m) <= 3]


def random_potentials(picks, weights, kind, eps=0.05):
    """φ(a,b,c) = ab + ε p(a,b,c), Φ(a,b,c) = bc + ε q(a,b,c): twist holds near the origin.

    p, q are sums of a few random monomials of degree ≤ 3 ("poly") or of sines of random
    linear forms ("trig"); ``picks`` chooses the monomials / frequencies, ``weights`` their sizes.
    """
    w = [float(v) for v in weights]
    if kind == "poly":
        terms = [MONOMIALS[i % len(MONOMIALS)] for i in picks]

        def part(a, b, c, ws):
            return sum(wk * a**i * b**j * c**k for wk, (i, j, k) in zip(ws, terms))

    else:
        freqs = [(1 + i % 3, 1 + (i // 3) % 3, 1 + (i // 9) % 3) for i in picks]

        def part(a, b, c, ws):
            return sum(wk * jnp.sin(p * a + q * b - r * c + wk) for wk, (p, q, r) in zip(ws, freqs))

    n = len(picks)

    def phi(a, b, c):
        return a * b + eps * part(a, b, c, w[:n])

    def Phi(a, b, c):
        return b * c + eps * part(a, b, c, w[n : 2 * n])

    return phi, Phi


def role_residual(phi, Phi):
    """(volpot1–3) written from the roles x₊ = x_{σ(1)}, …, X₋ = X_{Σ(3)} (MATH.md §2).

    ``s``, ``S`` are the 0-based role indices of σ and Σ, ``sign`` the sign of (volpot2).
    """
    d = lambda f, i: jax.grad(f, argnums=i)  # noqa: E731

    def R(x, X, s, S, sign):
        xp, xo, xm = x[s[0]], x[s[1]], x[s[2]]
        Xp, Xo, Xm = X[S[0]], X[S[1]], X[S[2]]
        return jnp.stack(
            [
                d(phi, 1)(Xm, xo, xm) - xp,
                d(Phi, 2)(Xm, Xo, xm) + sign * d(phi, 0)(Xm, xo, xm),
                d(Phi, 1)(Xm, Xo, xm) - Xp,
            ]
        )

    return R


def ift_checks(phi, Phi):
    """Jitted once per potential pair: the role residual and the IFT Jacobian −(∂R/∂X)⁻¹ ∂R/∂x."""
    R = role_residual(phi, Phi)

    @jax.jit
    def check(x, X, s, S, sign):
        res = jax.vmap(R, (0, 0, None, None, None))(x, X, s, S, sign)
        Rx = jax.vmap(jax.jacfwd(R, argnums=0), (0, 0, None, None, None))(x, X, s, S, sign)
        RX = jax.vmap(jax.jacfwd(R, argnums=1), (0, 0, None, None, None))(x, X, s, S, sign)
        return res, -jnp.linalg.solve(RX, Rx)

    return check


def points(seed, n=16):
    return np.random.default_rng(seed).uniform(-0.5, 0.5, (n, 3))


def fixed_potentials():
    return random_potentials(range(0, 10, 2), np.cos(np.arange(10.0)), "poly")


PHI_FIXED, PHI_FIXED_CAP = fixed_potentials()


@given(
    picks=st.lists(st.integers(0, 100), min_size=2, max_size=4),
    weights=st.lists(st.floats(-1, 1, allow_nan=False), min_size=8, max_size=8),
    kind=st.sampled_from(["poly", "trig"]),
    seed=st.integers(0, 99),
)
@settings(max_examples=4, deadline=None)
def test_all_36_cases_volume_inverse_residual(picks, weights, kind, seed):
    phi, Phi = random_potentials(picks, weights, kind)
    check = ift_checks(phi, Phi)
    x = points(seed)
    worst_det = worst_rt = worst_res = worst_ift = 0.0
    for case in cases():
        m = GeneratingMap(phi, Phi, case)
        X = m(x)
        # residual of the defining equations, re-derived from the roles
        s = jnp.array([i - 1 for i in case.sigma])
        S = jnp.array([i - 1 for i in case.Sigma])
        res, J_ift = check(jnp.asarray(x), X, s, S, float(case.sign))
        worst_res = max(worst_res, float(jnp.max(jnp.abs(res))))
        # det ≡ +1 with the sign rule ...
        J = m.jacobian(x)
        worst_det = max(worst_det, float(jnp.max(jnp.abs(jnp.linalg.det(J) - 1))))
        # ... and J equals the implicit-function-theorem Jacobian −(∂R/∂X)⁻¹ ∂R/∂x
        worst_ift = max(worst_ift, float(jnp.max(jnp.abs(J - J_ift))))
        # inverse (prop:permactvolpotinv): (Σ,σ)·f_{Φ·p, φ·p} with the same sign
        inv = m.inverse()
        assert inv.case == case.switched() and inv.sign == m.sign
        worst_rt = max(worst_rt, float(jnp.max(jnp.abs(inv(X) - x))))
        # the opposite sign reverses orientation: det ≡ −1
        m_rev = GeneratingMap(phi, Phi, case, sign=-case.sign)
        assert not m_rev.consistent_sign
        np.testing.assert_allclose(np.asarray(m_rev.det(x)), -1.0, atol=1e-12, rtol=0)
    assert worst_det <= 1e-12
    assert worst_rt <= 1e-12
    assert worst_res <= 1e-12
    assert worst_ift <= 1e-10


def test_inverse_needs_the_same_sign():
    # prop:volpotinv holds with the same sign; with the opposite sign the round trip is off by O(1)
    phi, Phi = PHI_FIXED, PHI_FIXED_CAP
    x = points(1)
    m = GeneratingMap(phi, Phi, Case((3, 2, 1), (1, 2, 3)))
    wrong = GeneratingMap(m.inverse().phi, m.inverse().Phi, m.case.switched(), sign=-m.sign)
    assert float(jnp.max(jnp.abs(wrong(m(x)) - x))) > 1e-2


@pytest.mark.parametrize("pi", Perm.all(), ids=str)
def test_relabel_identity(pi):
    # (π,π)·((σ,Σ)·f) = (π∘σ, π∘Σ)·f  (prop:permactalg), with (π,π)·g (x) = g(x·π)·π⁻¹
    phi, Phi = PHI_FIXED, PHI_FIXED_CAP
    x = points(2)
    for case in cases()[::5]:
        m = GeneratingMap(phi, Phi, case)
        lhs = pi.inverse().act(m(pi.act(x)))
        rel = m.relabel(pi)
        assert rel.case == Case(pi * case.sigma, pi * case.Sigma)
        np.testing.assert_allclose(np.asarray(rel(x)), np.asarray(lhs), atol=1e-13, rtol=0)


def test_shapes_jit_and_vmap():
    phi, Phi = PHI_FIXED, PHI_FIXED_CAP
    m = GeneratingMap(phi, Phi, Case((2, 3, 1), (1, 3, 2)))
    x = points(3, 10)
    X = m(x)
    assert X.shape == (10, 3)
    assert m(x[0]).shape == (3,)
    np.testing.assert_array_equal(np.asarray(m(x[0])), np.asarray(X[0]))
    assert m(x.reshape(2, 5, 3)).shape == (2, 5, 3)
    Xj, status = jax.jit(m.solve)(x)
    assert status.dtype == jnp.int32 and np.all(np.asarray(status) == RESULTS.successful)
    Xv = jax.vmap(lambda p: m.solve(p)[0])(jnp.asarray(x))
    np.testing.assert_allclose(np.asarray(Xv), np.asarray(X), atol=1e-15, rtol=0)
    np.testing.assert_allclose(np.asarray(Xj), np.asarray(X), atol=1e-15, rtol=0)
    with pytest.raises(ValueError, match="shape"):
        m(np.zeros((4, 2)))
    with pytest.raises(VPFormsError, match="jit"):
        jax.jit(m)(x)


def test_twist_failure_everywhere():
    # ∂₁₂φ ≡ 0: volpot1 cannot be solved for X₋
    m = GeneratingMap(lambda a, b, c: b * c, lambda a, b, c: b * c)
    x = points(4, 5)
    _, status = m.solve(x)
    assert np.all(np.asarray(status) == RESULTS.twist_failure)
    with pytest.raises(TwistConditionError, match=r"5 of 5 point\(s\).*first indices: \[0, 1, 2, 3, 4\]"):
        m(x)
    # ∂₂₃Φ ≡ 0: volpot2 cannot be solved for X∘
    m2 = GeneratingMap(lambda a, b, c: a * b, lambda a, b, c: a * b)
    with pytest.raises(TwistConditionError):
        m2(x)


def test_twist_failure_at_a_point():
    # ∂₂φ(a,b,c) = a³ + ε: the root of volpot1 is where ∂₁₂φ = 3a² vanishes only when y₁ = ε
    m = GeneratingMap(lambda a, b, c: b * a**3, lambda a, b, c: b * c)
    x = np.array([[0.0, 0.3, 0.2], [1.0, 0.1, 0.4], [0.0, -0.2, 0.1]])
    _, status = m.solve(x)
    assert list(np.asarray(status)) == [
        RESULTS.twist_failure,
        RESULTS.successful,
        RESULTS.twist_failure,
    ]
    with pytest.raises(TwistConditionError, match=r"2 of 3 point\(s\).*\[0, 2\]"):
        m(x)


def test_newton_that_cannot_converge():
    # ∂₂φ = arctan(Y₃): where arctan(Y₃) = y₁ has no root, Newton runs off to infinity
    m = GeneratingMap(lambda a, b, c: b * jnp.arctan(a), lambda a, b, c: b * c)
    x = np.array([[1.6, 0.1, 5.0], [0.1, 0.1, 0.1]])  # y₁ = 1.6 > π/2: arctan(Y₃) = y₁ has no root
    _, status = m.solve(x)
    assert list(np.asarray(status)) == [RESULTS.not_converged, RESULTS.successful]
    with pytest.raises(ConvergenceError, match=r"1 of 2 point\(s\).*\[0\]"):
        m(x)


def test_nonfinite_input():
    m = GeneratingMap(PHI_FIXED, PHI_FIXED_CAP)
    x = points(5, 4)
    x[2, 1] = np.nan
    x[3, 0] = np.inf
    _, status = m.solve(x)
    assert list(np.asarray(status)) == [0, 0, RESULTS.nonfinite, RESULTS.nonfinite]
    with pytest.raises(NonFiniteError, match=r"2 of 4 point\(s\).*\[2, 3\]"):
        m(x)


def test_bad_constructor_arguments():
    f = lambda a, b, c: a * b  # noqa: E731
    with pytest.raises(ValueError, match="sign"):
        GeneratingMap(f, f, sign=0)
    with pytest.raises(TypeError):
        GeneratingMap(f, 3.0)
    with pytest.raises(TypeError):
        GeneratingMap(f, f, case=((1, 2, 3), (1, 2, 3)))

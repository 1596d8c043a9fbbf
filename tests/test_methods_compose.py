"""Adjoint and compositions (issue #5, item 4).

* Ψ*_h = (Ψ_{−h})⁻¹ through the inverse map: Ψ_{−h}(Ψ*_h(x)) = x, (Ψ*)* = Ψ, case (Σ, σ), and the
  adjoint's generating map (φ̃ = Φ(−h)·p, Φ̃ = φ(−h)·p) solves the equations of (Σ, σ);
* the coefficients of every composition satisfy the order conditions of a symmetric composition of
  a symmetric method exactly to their order and not beyond — checked by multiplying the
  exponentials exp(γh E₁ + (γh)³E₃ + (γh)⁵E₅ + (γh)⁷E₇) in the free associative algebra;
* every composition, built from exact flows (Strang / Lie–Trotter splitting of two random
  non-commuting 4×4 matrices, scipy's expm), has a local error O(h^{p+1}) (log–log slope);
* observed global orders 2, 4, 6 and 8 (log–log fits against DOP853) for compositions of the class
  methods, including S1 through Quispel's correction map on a nonlinear field.
"""

from math import factorial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax

from vpforms import Case, compose, scheme
from vpforms._methods import (
    ADJOINT_COMPOSITIONS,
    COMPOSITIONS,
    Composition,
)
from vpforms._methods._compose import DEFAULT, from_splitting, stages
from vpforms.problems import get

from .test_methods_helpers import fit_order, reference_flow, step_det

# -- order conditions in the free algebra ---------------------------------------------------------
LETTERS = {1: "a", 3: "b", 5: "c", 7: "d"}  # E₁, E₃, E₅, E₇ with their weights


def _mul(u, v, wmax):
    out = {}
    for wu, cu in u.items():
        for wv, cv in v.items():
            w = wu + wv
            if sum(k for k, l in LETTERS.items() for ch in w if ch == l) <= wmax:
                out[w] = out.get(w, 0.0) + cu * cv
    return out


def _exp(gen, wmax):
    """exp of a Lie element given as {word: coeff} (truncated at weight wmax)."""
    out, term = {"": 1.0}, {"": 1.0}
    for n in range(1, wmax + 1):
        term = _mul(term, gen, wmax)
        for w, c in term.items():
            out[w] = out.get(w, 0.0) + c / factorial(n)
    return out


def composition_defect(gammas, wmax):
    """max |coefficient| per weight of Π exp(S_{γᵢ}) − exp(E₁), S_γ = Σ_k γ^k E_k (k odd)."""
    prod = {"": 1.0}
    for g in gammas:
        prod = _mul(_exp({LETTERS[k]: g**k for k in LETTERS}, wmax), prod, wmax)
    exact = _exp({"a": 1.0}, wmax)
    defect = {}
    for w in set(prod) | set(exact):
        weight = sum(k for k, l in LETTERS.items() for ch in w if ch == l)
        d = abs(prod.get(w, 0.0) - exact.get(w, 0.0))
        defect[weight] = max(defect.get(weight, 0.0), d)
    return defect


# Yoshida's published values have 15 digits; the order-8 triple jump's |γ| sum to 56, which
# amplifies the rounding of the products (measured defects: ≤ 2.7e-12 and ≤ 6.8e-13)
DEFECT_TOL = {(6, "yoshida"): 1e-12, (8, "yoshida"): 1e-11, (8, "triple_jump"): 5e-12}


@pytest.mark.parametrize("key", sorted(COMPOSITIONS))
def test_composition_coefficients_satisfy_their_order_conditions(key):
    order, _ = key
    gammas = COMPOSITIONS[key]
    assert np.allclose(gammas, gammas[::-1], atol=0, rtol=0)  # symmetric composition
    d = composition_defect(gammas, order + 1)
    tol = DEFECT_TOL.get(key, 1e-13)
    assert max(d[w] for w in range(1, order + 1)) <= tol, d
    assert d[order + 1] >= 1e-4, d  # and the order is not higher


@pytest.mark.parametrize("key", sorted(COMPOSITIONS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_composition_power_sums(key):
    """The cheap conditions (the single-letter words above): Σγ = 1, Σγ^k = 0 for odd 3 ≤ k < p."""
    order, _ = key
    g = np.asarray(COMPOSITIONS[key])
    assert abs(g.sum() - 1.0) <= 1e-14
    for k in range(3, order, 2):
        assert abs(np.sum(g**k)) <= DEFECT_TOL.get(key, 1e-13), (k, np.sum(g**k))


def test_order_two_from_the_free_algebra_too():
    # Ψ*_{h/2}∘Ψ_{h/2} has no even terms: with Ψ_h = exp(hE₁ + h²E₂ + …) this is the statement
    # that the (h/2)² terms cancel; the composition coefficients above start from it.
    assert composition_defect((1.0,), 2)[1] == 0.0


def adjoint_composition_defect(betas, alphas, wmax):
    """max |coefficient| per weight of Ψ*_{α_s}∘Ψ_{β_s}∘…∘Ψ_{β_1} − exp(E₁) for a generic
    method Ψ_h = exp(Σ_k h^k E_k) (all k: Ψ is not symmetric), whose adjoint is
    Ψ*_h = (Ψ_{−h})⁻¹ = exp(Σ_k (−1)^{k+1} h^k E_k)."""
    letters = {k: chr(ord("A") + k - 1) for k in range(1, wmax + 1)}

    def weight(w):
        return sum(k for k, l in letters.items() for ch in w if ch == l)

    def mul(u, v):
        out = {}
        for wu, cu in u.items():
            for wv, cv in v.items():
                if weight(wu + wv) <= wmax:
                    out[wu + wv] = out.get(wu + wv, 0.0) + cu * cv
        return out

    def exp(gen):
        out, term = {"": 1.0}, {"": 1.0}
        for n in range(1, wmax + 1):
            term = mul(term, gen)
            for w, c in term.items():
                out[w] = out.get(w, 0.0) + c / factorial(n)
        return out

    prod = {"": 1.0}
    for b, a in zip(betas, alphas):  # Ψ_β acts first, then Ψ*_α: left multiplication
        prod = mul(exp({letters[k]: b**k for k in letters}), prod)
        prod = mul(exp({letters[k]: (-1) ** (k + 1) * a**k for k in letters}), prod)
    exact = exp({"A": 1.0})
    defect = {}
    for w in set(prod) | set(exact):
        d = abs(prod.get(w, 0.0) - exact.get(w, 0.0))
        defect[weight(w)] = max(defect.get(weight(w), 0.0), d)
    return defect


@pytest.mark.parametrize("key", sorted(ADJOINT_COMPOSITIONS))
def test_adjoint_composition_coefficients_satisfy_their_order_conditions(key):
    """Every word up to weight p of the generic non-symmetric Ψ cancels (order p for *every*
    order-1 method), weight p + 1 does not; the palindrome makes the method symmetric."""
    order, _ = key
    betas, alphas = ADJOINT_COMPOSITIONS[key]
    seq = [c for b, a in zip(betas, alphas) for c in (b, a)]
    assert np.allclose(seq, seq[::-1], rtol=0, atol=1e-14)
    d = adjoint_composition_defect(betas, alphas, order + 1)
    assert max(d[w] for w in range(1, order + 1)) <= 1e-13, d
    assert d[order + 1] >= 1e-5, d


def test_from_splitting_rejects_an_inconsistent_splitting_and_inverts_lie_trotter():
    assert from_splitting((1.0, 0.0), (1.0,)) == ((1.0,), (0.0,))  # Ψ itself
    assert from_splitting((0.5, 0.5), (1.0,)) == ((0.5,), (0.5,))  # Strang = Ψ*_{h/2}∘Ψ_{h/2}
    with pytest.raises(ValueError, match="consistent"):
        from_splitting((0.5, 0.6), (1.0,))


# -- order from exact flows: splittings of two matrices -------------------------------------------
def _two_matrices():
    rng = np.random.default_rng(0)
    A, B = rng.standard_normal((2, 4, 4)) / 2  # ‖A‖₂ = 1.5, ‖B‖₂ = 1.0, ‖[A, B]‖_F = 2.0
    return A, B


#: step sizes per order: local errors between ~1e-3 and ~1e-12, above the rounding of the
#: products (~1e-15) and where the slope is already p + 1 within 0.2 (measured for these A, B:
#: every composition's local slopes lie in [p + 0.87, p + 1.2] over these h)
EXACT_FLOW_HS = {4: (0.4, 0.2, 0.1, 0.05), 6: (0.4, 0.3, 0.2, 0.15), 8: (0.6, 0.4, 0.3, 0.2)}


def _local_errors(step, hs):
    from scipy.linalg import expm

    A, B = _two_matrices()
    return np.array([np.max(np.abs(step(A, B, h) - expm(h * (A + B)))) for h in hs])


@pytest.mark.parametrize("key", sorted(COMPOSITIONS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_composition_of_exact_flows_has_its_order(key):
    """S_h = e^{hA/2} e^{hB} e^{hA/2} (Strang: symmetric, order 2); the composition
    S_{γ_s h}⋯S_{γ_1 h} minus e^{h(A+B)} is O(h^{p+1}): log–log slope ≥ p + 1 − 0.3."""
    from scipy.linalg import expm

    order, _ = key

    def step(A, B, h):
        M = np.eye(4)
        for g in COMPOSITIONS[key]:
            M = expm(g * h * A / 2) @ expm(g * h * B) @ expm(g * h * A / 2) @ M
        return M

    hs = EXACT_FLOW_HS[order]
    errs = _local_errors(step, hs)
    assert errs.min() >= 1e-13, errs  # above rounding: the slope is the truncation error's
    slope = fit_order(hs, errs)
    assert slope >= order + 1 - 0.3, (slope, errs)


@pytest.mark.parametrize("key", sorted(ADJOINT_COMPOSITIONS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_adjoint_composition_of_exact_flows_has_its_order(key):
    """Ψ_h = e^{hB} e^{hA} (Lie–Trotter, order 1, not symmetric), Ψ*_h = e^{hA} e^{hB}; the
    composition Ψ*_{α_s h}Ψ_{β_s h}⋯Ψ*_{α_1 h}Ψ_{β_1 h} minus e^{h(A+B)} is O(h^{p+1})."""
    from scipy.linalg import expm

    order, _ = key
    betas, alphas = ADJOINT_COMPOSITIONS[key]

    def step(A, B, h):
        M = np.eye(4)
        for b, a in zip(betas, alphas):
            M = expm(b * h * B) @ expm(b * h * A) @ M
            M = expm(a * h * A) @ expm(a * h * B) @ M
        return M

    hs = EXACT_FLOW_HS[order]
    errs = _local_errors(step, hs)
    assert errs.min() >= 1e-13, errs
    slope = fit_order(hs, errs)
    assert slope >= order + 1 - 0.3, (slope, errs)


def test_stage_counts_and_order_eight_defaults():
    assert stages(2) == 2 and stages(4) == 10 and stages(4, "blanes_moan") == 12
    assert stages(6) == 18 and stages(6, "yoshida") == 14 and stages(6, "blanes_moan") == 20
    assert stages(8, "suzuki_umeno") == stages(8, "yoshida") == 30
    assert stages(8, "kahan_li") == 34 and stages(8, "triple_jump") == 54
    assert stages(8) == stages(8, DEFAULT[8])
    with pytest.raises(ValueError, match="unknown"):
        stages(8, "nonsense")
    field = get("abc").field
    m = compose(scheme(field, "SE+SE", recover=False), order=8)
    assert isinstance(m, Composition) and m.order == 8 and m.symmetric
    # stages as data: S_{γh} = Ψ*_{γh/2}∘Ψ_{γh/2} for each γ, Ψ and Ψ* in alternation
    gam = COMPOSITIONS[(8, DEFAULT[8])]
    assert m.coefficients == tuple(g * 0.5 for g in gam for _ in (0, 1))
    psi = m.stages[0].method
    assert all(s.method is (psi if k % 2 == 0 else psi.adjoint()) for k, s in enumerate(m.stages))
    assert [s.adjoint for s in m.stages] == [k % 2 == 1 for k in range(len(m.stages))]
    m6 = compose(scheme(field, "SE+SE", recover=False), order=6, scheme="blanes_moan")
    assert isinstance(m6, Composition) and m6.order == 6 and m6.symmetric
    assert len(m6.stages) == stages(6, "blanes_moan")


# -- adjoint -------------------------------------------------------------------------------------
def test_adjoint_is_the_inverse_at_minus_h():
    field = get("lotka_volterra").field
    x = jnp.asarray(np.random.default_rng(3).uniform(0.5, 2.0, (6, 3)))
    for c in (Case((3, 2, 1), (1, 2, 3)), Case((1, 2, 3), (2, 3, 1)), Case((2, 1, 3), (1, 2, 3))):
        m = scheme(field, c)
        adj = m.adjoint()
        assert adj.case == c.switched() and adj.adjoint().case == c and adj.cls == m.cls
        Y = adj.step(x, 0.05)
        assert float(jnp.max(jnp.abs(m.step(Y, -0.05) - x))) <= 1e-13
        gm = adj.generating_map(0.05, x[0])
        if gm is not None:
            assert gm.case == c.switched()
            assert float(jnp.max(jnp.abs(adj.residual(x, Y, 0.05)))) <= 1e-12
        assert float(jnp.max(jnp.abs(m.inverse_step(m.step(x, 0.05), 0.05) - x))) <= 1e-13


# -- observed orders -----------------------------------------------------------------------------
def flow(method):
    """A compiled n-step flow (x0 batch, h, n) → x_n."""

    bare = method.without_recovery()  # the order of the recipe itself (no step fails here)

    def run(x0, h, n):
        step = jax.vmap(lambda p: bare._forward(p, h)[0])
        return lax.fori_loop(0, n, lambda i, x: step(x), x0)

    return jax.jit(run)


def observed_order(method, field, x0, T, ns):
    ref = reference_flow(field, x0, T)
    run = flow(method)
    errs = [float(np.max(np.abs(np.asarray(run(jnp.asarray(x0), T / n, n)) - ref))) for n in ns]
    return fit_order([T / n for n in ns], errs), errs


ABC_X0 = np.array([[0.5, 0.7, 0.9], [1.0, 0.6, 0.8]])
LV_X0 = np.array([[1.0, 1.5, 0.7], [0.8, 1.1, 1.3]])


@pytest.mark.parametrize(
    "cls,opts,field_name",
    [
        ("SE+SE", {}, "abc"),
        ("SE+DL", {}, "lotka_volterra"),
        ("DL+DL", {"theta": 0.5}, "lotka_volterra"),
        ("S1", {}, "lotka_volterra"),  # Quispel's correction map (t5vp), nonlinear field
        ("S2", {}, "lotka_volterra"),  # (t5vps2)
    ],
)
def test_adjoint_composition_has_order_two(cls, opts, field_name):
    field = get(field_name).field
    m = compose(scheme(field, cls, **opts), order=2)
    # a recovering scheme composes to a recovering composition (recovery of the composed step)
    pair = m.without_recovery()
    assert isinstance(pair, Composition) and pair.coefficients == (0.5, 0.5)
    assert pair.stages[1].method is pair.stages[0].method.adjoint()
    assert m.order == 2 and m.symmetric and m.cls == cls
    x0 = ABC_X0 if field_name == "abc" else LV_X0
    p, errs = observed_order(m, field, x0, 0.5, (4, 8, 16, 32))
    assert abs(p - 2.0) <= 0.1, (p, errs)


@pytest.mark.parametrize(
    "cls,field_name,order,scheme_name,ns",
    [
        ("SE+SE", "abc", 4, "suzuki", (4, 6, 8, 12)),
        ("SE+SE", "abc", 4, "triple_jump", (4, 6, 8, 12)),
        ("SE+SE", "abc", 6, "kahan_li", (3, 4, 5, 6)),
        ("SE+SE", "abc", 6, "yoshida", (3, 4, 5, 6)),
        ("S1", "lotka_volterra", 4, "suzuki", (4, 6, 8, 12)),
        ("S1", "lotka_volterra", 6, "kahan_li", (3, 4, 5, 6)),
        ("SE+SE", "abc", 4, "blanes_moan", (3, 4, 6, 8)),
        ("S1", "lotka_volterra", 4, "blanes_moan", (3, 4, 6, 8)),
    ],
)
def test_higher_order_compositions(cls, field_name, order, scheme_name, ns):
    field = get(field_name).field
    m = compose(scheme(field, cls), order=order, scheme=scheme_name)
    assert isinstance(m.without_recovery(), Composition) and m.order == order and m.symmetric
    x0 = ABC_X0 if field_name == "abc" else LV_X0
    p, errs = observed_order(m, field, x0, 1.0, ns)
    assert abs(p - order) <= 0.1 * order / 2, (p, errs)


@pytest.mark.slow  # 5–10 s each (compile of 30–54 unrolled stages, DOP853 reference)
@pytest.mark.parametrize(
    "order,scheme_name,ns",
    [
        (8, "kahan_li", (3, 4, 5, 6)),  # errors 6e-10 … 2e-12
        (8, "suzuki_umeno", (2, 3, 4, 5)),  # 7e-8 … 5e-11
        (8, "yoshida", (3, 4, 5, 6)),  # 8e-7 … 3e-9
        (8, "triple_jump", (4, 5, 6, 8)),  # 2e-6 … 8e-9
        (6, "blanes_moan", (3, 4, 6, 8)),  # 6e-8 … 2e-10
    ],
)
def test_order_eight_and_blanes_moan_six_on_abc(order, scheme_name, ns):
    """Global errors at T = 1 between ~1e-5 and ~1e-12 (order 8 reaches rounding quickly). The
    fit may be steeper than p where the next term still counts (Kahan–Li's h^9 coefficient is
    small: 8.5 here); not below p − 0.3."""
    field = get("abc").field
    m = compose(scheme(field, "SE+SE"), order=order, scheme=scheme_name)
    assert isinstance(m.without_recovery(), Composition) and m.order == order and m.symmetric
    p, errs = observed_order(m, field, ABC_X0, 1.0, ns)
    assert 1e-12 <= min(errs) and max(errs) <= 1e-5, errs
    assert order - 0.3 <= p <= order + 0.7, (p, errs)


def test_compositions_are_symmetric_and_checked():
    field = get("abc").field
    x = jnp.asarray(ABC_X0)
    for order, name in ((2, None), (4, None), (4, "blanes_moan")):
        m = compose(scheme(field, "SE+SE", recover=False), order=order, scheme=name)
        back = m.step(m.step(x, 0.1), -0.1)  # S_{−h}∘S_h = id for a symmetric method
        assert float(jnp.max(jnp.abs(back - x))) <= 1e-13
        # a composition of volume-preserving steps is volume preserving: det by jax.jacfwd
        _, det, status = step_det(m)(x, 0.1)
        assert np.all(np.asarray(status) == 0)
        assert float(jnp.max(jnp.abs(det - 1))) <= 1e-12, (order, det)
    with pytest.raises(ValueError, match="order"):
        compose(scheme(field, "SE+SE"), order=3)
    with pytest.raises(ValueError, match="2, 4, 6 or 8"):
        compose(scheme(field, "SE+SE"), order=10)
    with pytest.raises(ValueError, match="unknown"):
        compose(scheme(field, "SE+SE"), order=4, scheme="nonsense")
    with pytest.raises(TypeError, match="vpforms method"):
        compose(field, order=2)  # a field, not a method

"""Higher order by composition (Hairer–Lubich–Wanner II.4, V.3).

* order 2: S_h = Ψ*_{h/2} ∘ Ψ_{h/2} (symmetric, since (Ψ*)* = Ψ);
* order 4/6/8: symmetric compositions S_{γ_s h} ∘ … ∘ S_{γ_1 h} of the order-2 method with the
  coefficients of :data:`COMPOSITIONS` (data): triple jump (Creutz–Gocksch, Suzuki, Yoshida 1990),
  Suzuki's 5-stage order 4, Yoshida's 7-stage order 6 ("solution A") and Kahan–Li's 9-stage order 6
  (s9odr6a); order 8: Suzuki–Umeno's 15-stage set (also McLachlan's and Kahan–Li's s15odr8),
  Kahan–Li's 17-stage s17odr8, Yoshida's 15-stage "solution D" and the 27-stage triple jump.
  Their order conditions (Σγ = 1, Σγ³ = 0, …) are checked in the tests.
* order 4 and 6, "blanes_moan": a composition of Ψ with its adjoint,
  Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h} (HLW V.3.2, eq. (3.4)) with Blanes & Moan's optimised
  coefficients (:data:`ADJOINT_COMPOSITIONS`): at order 4, 12 order-1 stages where Suzuki's has 10,
  with a leading error ~20× smaller (measured on ABC), so fewer steps for a given accuracy; at order
  6 (S10), 20 stages where Kahan–Li's has 18, with an error constant 8–50× smaller (measured).

The cost of a step is its number of order-1 stages (:func:`stages`) times the cost of one step of
the method; ``benchmarks/results_orders.md`` measures which composition needs the fewest stages for
a given accuracy.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import lax

from .._spec_record import records_spec
from ._base import Method, merge_status
from .recover import Recovering, SubstepLadder

__all__ = [
    "ADJOINT_COMPOSITIONS",
    "COMPOSITIONS",
    "AdjointComposition",
    "Composition",
    "SymmetricPair",
    "compose",
    "stages",
    "triple_jump",
]


def triple_jump(order: int) -> tuple[float, ...]:
    """The recursive triple jump: γ = (γ₁, γ₂, γ₁), γ₁ = 1/(2 − 2^{1/(p+1)}), raising p → p + 2."""
    gam = np.array([1.0])
    for p in range(2, order, 2):
        g1 = 1.0 / (2.0 - 2.0 ** (1.0 / (p + 1)))
        g2 = 1.0 - 2.0 * g1
        gam = np.concatenate([g1 * gam, g2 * gam, g1 * gam])
    return tuple(float(g) for g in gam)


def _suzuki5() -> tuple[float, ...]:
    g = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
    return (g, g, 1.0 - 4.0 * g, g, g)


def _yoshida7() -> tuple[float, ...]:
    w1, w2, w3 = -1.17767998417887, 0.235573213359357, 0.784513610477560
    w0 = 1.0 - 2.0 * (w1 + w2 + w3)
    return (w3, w2, w1, w0, w1, w2, w3)


_KL9 = (
    0.39216144400731413928,
    0.33259913678935943860,
    -0.70624617255763935981,
    0.08221359629355080023,
    0.79854399093482996340,
)

# Order 8, 15 stages, γ₁ … γ₈ (γ₉ … γ₁₅ = γ₇ … γ₁): the solution of the 8 order conditions with
# the smallest max|γᵢ|, found by Suzuki & Umeno (1993, in "Computer Simulation Studies in Condensed-
# Matter Physics VI", Springer, 74–86) and McLachlan (SIAM J. Sci. Comput. 16 (1995) 151–168), and
# listed as "s15odr8" by Kahan & Li (Math. Comp. 66 (1997) 1089–1099); the 26 digits as printed in
# Hairer–Lubich–Wanner, Geometric Numerical Integration (2nd ed. 2006), V.3.2, for p = 8, s = 15.
_SU15 = (
    0.74167036435061295344822780,
    -0.40910082580003159399730010,
    0.19075471029623837995387626,
    -0.57386247111608226665638773,
    0.29906418130365592384446354,
    0.33462491824529818378495798,
    0.31529309239676659663205666,
    -0.79688793935291635401978884,
)

# Order 8, 17 stages, γ₁ … γ₉ (γ₁₀ … γ₁₇ = γ₈ … γ₁): Kahan & Li, Math. Comp. 66 (1997) 1089–1099,
# "s17odr8" (the two free parameters chosen for small error terms); 26 digits as printed in HLW
# V.3.2 for p = 8, s = 17.
_KL17 = (
    0.13020248308889008087881763,
    0.56116298177510838456196441,
    -0.38947496264484728640807860,
    0.15884190655515560089621075,
    -0.39590389413323757733623154,
    0.18453964097831570709183254,
    0.25837438768632204729397911,
    0.29501172360931029887096624,
    -0.60550853383003451169892108,
)


def _yoshida15() -> tuple[float, ...]:
    """Yoshida, Phys. Lett. A 150 (1990) 262–268, Table 2, order 8 "solution D" (15 digits):
    γ = (w₇, …, w₁, w₀, w₁, …, w₇), w₀ = 1 − 2(w₁ + … + w₇)."""
    w = (0.102799849391985, -1.96061023297549, 1.93813913762276, -0.158240635368243,
         -1.44485223686048, 0.253693336566229, 0.914844246229740)  # w₁ … w₇
    w0 = 1.0 - 2.0 * sum(w)
    return w[::-1] + (w0,) + w


def _palindrome(half):
    return tuple(half) + tuple(half[-2::-1])


#: (order, name) → coefficients γ of the symmetric composition of a symmetric order-2 method.
COMPOSITIONS: dict[tuple[int, str], tuple[float, ...]] = {
    (4, "triple_jump"): triple_jump(4),
    (4, "suzuki"): _suzuki5(),
    (6, "triple_jump"): triple_jump(6),
    (6, "yoshida"): _yoshida7(),
    (6, "kahan_li"): _palindrome(_KL9),
    (8, "suzuki_umeno"): _palindrome(_SU15),
    (8, "kahan_li"): _palindrome(_KL17),
    (8, "yoshida"): _yoshida15(),
    (8, "triple_jump"): triple_jump(8),
}
DEFAULT = {4: "suzuki", 6: "kahan_li", 8: "kahan_li"}


def from_splitting(a, b) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(β, α) of Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h} from a splitting method
    e^{a_{s+1}hA}e^{b_s hB}…e^{b_1 hB}e^{a_1 hA} (a₁ acts first): with Ψ_h = e^{hB}∘e^{hA} (Lie–Trotter),
    Ψ*_h = e^{hA}∘e^{hB}, the product is that splitting when a₁ = β₁, b_i = β_i + α_i,
    a_{i+1} = α_i + β_{i+1} (HLW V.3.2); a splitting of order p gives a composition of order p for
    every method Ψ of order ≥ 1 (the order conditions do not depend on Ψ)."""
    beta, alpha = [a[0]], []
    for i, bi in enumerate(b):
        alpha.append(bi - beta[i])
        if i + 1 < len(b):
            beta.append(a[i + 1] - alpha[i])
    if abs(alpha[-1] - a[-1]) > 1e-14:
        raise ValueError("a, b are not the coefficients of a consistent splitting")
    return tuple(beta), tuple(alpha)


def _blanes_moan_s6():
    """Blanes & Moan, J. Comput. Appl. Math. 142 (2002) 313–330, Table 2, S6 (order 4, 6 stages):
    a = (a₁, a₂, a₃, a₄, a₃, a₂, a₁), b = (b₁, b₂, b₃, b₃, b₂, b₁)."""
    a1, a2, a3 = 0.0792036964311957, 0.353172906049774, -0.0420650803577195
    b1, b2 = 0.209515106613362, -0.143851773179818
    a4, b3 = 1.0 - 2.0 * (a1 + a2 + a3), 0.5 - (b1 + b2)
    return from_splitting((a1, a2, a3, a4, a3, a2, a1), (b1, b2, b3, b3, b2, b1))


def _blanes_moan_s10():
    """Blanes & Moan, J. Comput. Appl. Math. 142 (2002) 313–330, Table 2, S10 (order 6, 10 stages):
    a = (a₁, …, a₅, a₆, a₅, …, a₁), b = (b₁, …, b₅, b₅, …, b₁)."""
    a = (0.0502627644003922, 0.413514300428344, 0.0450798897943977, -0.188054853819569,
         0.541960678450780)
    b = (0.148816447901042, -0.132385865767784, 0.067307604692185, 0.432666402578175)
    a6, b5 = 1.0 - 2.0 * sum(a), 0.5 - sum(b)
    return from_splitting(a + (a6,) + a[::-1], b + (b5, b5) + b[::-1])


#: (order, name) → (β, α) of the composition of a method with its adjoint (:class:`AdjointComposition`).
ADJOINT_COMPOSITIONS: dict[tuple[int, str], tuple[tuple[float, ...], tuple[float, ...]]] = {
    (4, "blanes_moan"): _blanes_moan_s6(),
    (6, "blanes_moan"): _blanes_moan_s10(),
}


def stages(order: int, scheme: str | None = None) -> int:
    """Order-1 stages (steps of the method Ψ or of its adjoint) in one step of
    ``compose(Ψ, order, scheme)`` for an order-1 Ψ: the cost of a step is this many times Ψ's.

    2 for order 2; 2·s for a symmetric composition of s order-2 stages Ψ*_{h/2}∘Ψ_{h/2} (e.g. 30
    for order 8, "suzuki_umeno"); 2·s for an adjoint composition of s pairs (12 for order 4,
    "blanes_moan")."""
    if order == 2 and scheme is None:
        return 2
    name = DEFAULT.get(order) if scheme is None else scheme
    if (order, name) in ADJOINT_COMPOSITIONS:
        return 2 * len(ADJOINT_COMPOSITIONS[(order, name)][0])
    if (order, name) in COMPOSITIONS:
        return 2 * len(COMPOSITIONS[(order, name)])
    raise ValueError(f"unknown order-{order} composition {name!r}")


class SymmetricPair(Method):
    """S_h = Ψ*_{h/2} ∘ Ψ_{h/2}: symmetric, order 2 (order ≥ 1 methods; HLW Thm II.3.2)."""

    def _submethods(self) -> tuple:
        return (self.base, self.adj)

    def __init__(self, base: Method):
        self.base, self.adj = base, base.adjoint()
        self.case, self.field = base.case, base.field
        self.order, self.symmetric = max(2, base.order if base.order % 2 == 0 else base.order + 1), True
        self.name = f"{base.name}*∘{base.name}"

    def _forward(self, x, h):
        y, s1, n1 = self.base._forward(x, h / 2)
        X, s2, n2 = self.adj._forward(y, h / 2)
        return X, merge_status(s1, s2), n1 + n2

    def _backward(self, X, h):
        y, s1, n1 = self.adj._backward(X, h / 2)
        x, s2, n2 = self.base._backward(y, h / 2)
        return x, merge_status(s1, s2), n1 + n2

    def _batched_step(self, x, h):  # stage by stage: each stage decides its own recovery
        y, s1, n1, r1 = self.base._batched_step(x, h / 2)
        X, s2, n2, r2 = self.adj._batched_step(y, h / 2)
        return X, _merge(s1, s2), n1 + n2, jnp.maximum(r1, r2)

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        return self if bare is self.base else SymmetricPair(bare)


class Composition(Method):
    """S_{γ_s h} ∘ … ∘ S_{γ_1 h} for a symmetric method S (one compiled stage, ``lax.scan``)."""

    def _submethods(self) -> tuple:
        return (self.base,)

    def __init__(self, base: Method, gammas, order: int, scheme_name: str):
        self.base = base
        self.gammas = tuple(float(g) for g in gammas)
        self.case, self.field = base.case, base.field
        self.order, self.symmetric = int(order), True
        self.name = f"{scheme_name}{order}[{base.name}]"
        self._g = jnp.asarray(self.gammas)

    def _forward(self, x, h):
        def body(carry, g):
            x, st, n = carry
            X, s, k = self.base._forward(x, g * h)
            return (X, merge_status(st, s), n + k), None

        init = (x, jnp.int32(0), jnp.int32(0))
        (X, st, n), _ = lax.scan(body, init, self._g, unroll=True)  # unrolled: see notes/issue-9-jax.md
        return X, st, n

    def _backward(self, X, h):
        def body(carry, g):
            X, st, n = carry
            x, s, k = self.base._backward(X, g * h)
            return (x, merge_status(st, s), n + k), None

        init = (X, jnp.int32(0), jnp.int32(0))
        (x, st, n), _ = lax.scan(body, init, self._g[::-1], unroll=True)
        return x, st, n

    def _batched_step(self, x, h):  # stage by stage: each stage decides its own recovery
        def body(carry, g):
            x, st, n, r = carry
            X, s, k, q = self.base._batched_step(x, g * h)
            return (X, _merge(st, s), n + k, jnp.maximum(r, q)), None

        z = jnp.zeros(x.shape[0], jnp.int32)
        (X, st, n, r), _ = lax.scan(body, (x, z, z, z), self._g)
        return X, st, n, r

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        if bare is self.base:
            return self
        out = Composition(bare, self.gammas, self.order, "")
        out.name = self.name.replace(self.base.name, bare.name)
        return out


class AdjointComposition(Method):
    """Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h} (HLW V.3.2, eq. (3.4)): the method ``base`` and
    its adjoint in alternation, ``stages`` = ((Ψ, β₁), (Ψ*, α₁), …) in the order they act.
    Symmetric when the sequence of coefficients is a palindrome (α_i = β_{s+1−i})."""

    def _submethods(self) -> tuple:
        return (self.base, self.adj)

    def __init__(self, base: Method, betas, alphas, order: int, scheme_name: str):
        self.base, self.adj = base, base.adjoint()
        self.betas, self.alphas = tuple(map(float, betas)), tuple(map(float, alphas))
        self.stages = tuple((m, c) for b, a in zip(self.betas, self.alphas)
                            for m, c in ((self.base, b), (self.adj, a)))
        self.case, self.field = base.case, base.field
        coef = [c for _, c in self.stages]
        self.order, self.symmetric = int(order), bool(np.allclose(coef, coef[::-1], rtol=0, atol=1e-14))
        self.scheme_name = scheme_name
        self.name = f"{scheme_name}{order}[{base.name}]"

    def _forward(self, x, h):
        st, n = jnp.int32(0), jnp.int32(0)
        for m, c in self.stages:
            x, s, k = m._forward(x, c * h)
            st, n = merge_status(st, s), n + k
        return x, st, n

    def _backward(self, X, h):
        st, n = jnp.int32(0), jnp.int32(0)
        for m, c in reversed(self.stages):
            X, s, k = m._backward(X, c * h)
            st, n = merge_status(st, s), n + k
        return X, st, n

    def _batched_step(self, x, h):  # stage by stage: each stage decides its own recovery
        z = jnp.zeros(x.shape[0], jnp.int32)
        st, n, r = z, z, z
        for m, c in self.stages:
            x, s, k, q = m._batched_step(x, c * h)
            st, n, r = _merge(st, s), n + k, jnp.maximum(r, q)
        return x, st, n, r

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        if bare is self.base:
            return self
        out = AdjointComposition(bare, self.betas, self.alphas, self.order, self.scheme_name)
        out.name = self.name.replace(self.base.name, bare.name)
        return out


def _merge(a, b):
    return jnp.where(a == 0, b, a).astype(jnp.int32)


@records_spec("compose")
def compose(method: Method, order: int = 2, scheme: str | None = None) -> Method:
    """A method of order 2, 4, 6 or 8 from ``method`` (any order-1 method of vpforms).

    order 2: Ψ*_{h/2}∘Ψ_{h/2}; order 4: ``scheme`` "suzuki" (default) or "triple_jump"; order 6:
    "kahan_li" (default), "yoshida" or "triple_jump"; order 8: "kahan_li" (default),
    "suzuki_umeno", "yoshida" or "triple_jump" — each a symmetric composition of the order-2
    method (or of ``method`` itself if it is already symmetric of order ≥ 2). Order 4 and 6,
    "blanes_moan":
    ``method`` and its adjoint in alternation (:class:`AdjointComposition`).

    Cost per step, in steps of an order-1 ``method`` (:func:`stages`; halve the symmetric
    compositions' counts for a symmetric order-2 ``method``):

    ======  ======================================================================================
    order   scheme: stages
    ======  ======================================================================================
    2       — : 2
    4       "triple_jump": 6, "suzuki": 10, "blanes_moan": 12
    6       "yoshida": 14 (Yoshida 1990, solution A), "kahan_li": 18 (s9odr6a), "blanes_moan": 20
            (Blanes & Moan 2002, S10), "triple_jump": 18
    8       "suzuki_umeno": 30 (Suzuki–Umeno 1993, = McLachlan 1995's and Kahan–Li 1997's s15odr8),
            "yoshida": 30 (Yoshida 1990, solution D), "kahan_li": 34 (Kahan–Li 1997, s17odr8),
            "triple_jump": 54
    ======  ======================================================================================

    Which needs the fewest stages for a given accuracy (``benchmarks/results_orders.md``: SE+SE,
    max global error at T = 4, stages for the whole run; after ";" those within 10 %):

    ======  ==========================================  ==========================================
    error   ABC flow                                    tokamak field lines
    ======  ==========================================  ==========================================
    1e-6    6 "blanes_moan" (160)                       8 "kahan_li" (374); 6 "blanes_moan" (400)
    1e-9    6 "blanes_moan" (500); 8 "kahan_li",         8 "kahan_li" (850)
            "suzuki_umeno" (510)
    1e-12   8 "suzuki_umeno" (1200); 8 "kahan_li"       8 "kahan_li" (1972)
            (1224)
    ======  ==========================================  ==========================================

    Order 2 needs 5526 (ABC) and 9552 (tokamak) stages for 1e-6; the default order 4 ("suzuki")
    460 and 850, order 6 "kahan_li" 270 and 504. Measured error constants (err ≈ C·h^p at T = 4,
    ABC / tokamak): order 8 "kahan_li" 4.0e-5 / 1.8e-3, "suzuki_umeno" 9.7e-5 / 1.5e-2, "yoshida"
    7.7e-3 / 1.25, "triple_jump" 0.38 / 70 — hence the default.
    """
    if not isinstance(method, Method):
        raise TypeError(f"compose needs a vpforms method (vpforms.scheme(...)), got {type(method).__name__}")
    if order not in (2, 4, 6, 8):
        raise ValueError(f"order must be 2, 4, 6 or 8, not {order!r}")
    if isinstance(method, Recovering):
        # recovery of the COMPOSED step (issue #19, item 5): where it fails, the whole composition
        # of an alternative is taken — the same order — instead of one switched stage, which
        # would make the step an order-1 map (e.g. Ψ*_c∘Ψ_{c'} is not symmetric)
        bare = compose(method.bare, order, scheme)
        alts = [(SubstepLadder(bare, a.k) if isinstance(a, SubstepLadder) else compose(a, order, scheme), c)
                for a, c in method.alternatives]
        return Recovering(bare, alts, method.buffer, method.refused)
    base = method if (method.symmetric and method.order >= 2) else SymmetricPair(method)
    if order == 2:
        if scheme is not None:
            raise ValueError("order 2 is Ψ*_{h/2}∘Ψ_{h/2}; it takes no scheme")
        return base
    name = DEFAULT[order] if scheme is None else scheme
    if (order, name) in ADJOINT_COMPOSITIONS:
        return AdjointComposition(method, *ADJOINT_COMPOSITIONS[(order, name)], order, name)
    if (order, name) not in COMPOSITIONS:
        known = [n for (o, n) in [*COMPOSITIONS, *ADJOINT_COMPOSITIONS] if o == order]
        raise ValueError(f"unknown order-{order} composition {name!r}; known: {known}")
    return Composition(base, COMPOSITIONS[(order, name)], order, name)

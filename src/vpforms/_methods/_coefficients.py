"""The coefficients of the compositions (data): which order-1 stages, at which fractions of h.

* symmetric compositions S_{γ_s h} ∘ … ∘ S_{γ_1 h} of a symmetric order-2 method S
  (:data:`COMPOSITIONS`, HLW II.4 and V.3): triple jump (Creutz–Gocksch, Suzuki, Yoshida 1990),
  Suzuki's 5-stage order 4, Yoshida's order 6 and 8, Kahan–Li's order 6 and 8, Suzuki–Umeno's
  order 8; their order conditions (Σγ = 1, Σγ³ = 0, …) are checked in the tests;
* compositions of a method with its adjoint Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h}
  (:data:`ADJOINT_COMPOSITIONS`, HLW V.3.2 eq. (3.4)): Blanes & Moan's optimised orders 4 and 6.

:func:`vpforms.compose` turns them into the stage list of a :class:`~vpforms._methods._stages.Composition`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ADJOINT_COMPOSITIONS", "COMPOSITIONS", "DEFAULT", "from_splitting", "stages",
           "triple_jump"]


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


#: (order, name) → (β, α) of the composition of a method with its adjoint (``adjoint_composition``).
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

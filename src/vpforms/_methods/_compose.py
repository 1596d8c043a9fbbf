"""Higher order by composition (Hairer–Lubich–Wanner II.4, V.3).

* order 2: S_h = Ψ*_{h/2} ∘ Ψ_{h/2} (symmetric, since (Ψ*)* = Ψ);
* order 4/6/8: symmetric compositions S_{γ_s h} ∘ … ∘ S_{γ_1 h} of the order-2 method with the
  coefficients of :data:`COMPOSITIONS` (``_coefficients.py``);
* order 4 and 6, "blanes_moan": a composition of Ψ with its adjoint,
  Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h} (HLW V.3.2, eq. (3.4)) with Blanes & Moan's optimised
  coefficients (:data:`ADJOINT_COMPOSITIONS`): at order 4, 12 order-1 stages where Suzuki's has 10,
  with a leading error ~20× smaller (measured on ABC), so fewer steps for a given accuracy; at order
  6 (S10), 20 stages where Kahan–Li's has 18, with an error constant 8–50× smaller (measured).

Each is one :class:`~vpforms._methods._stages.Composition`: the list of order-1 stages (Ψ or Ψ*)
with their coefficients of h (issue #19, stages as data). The cost of a step is its number of
order-1 stages (:func:`stages`) times the cost of one step of the method;
``benchmarks/methods/results_orders.md`` measures which composition needs the fewest stages for a given
accuracy.
"""

from __future__ import annotations

import numpy as np

from .._spec_record import records_spec
from ._base import Method
from ._coefficients import (ADJOINT_COMPOSITIONS, COMPOSITIONS, DEFAULT, from_splitting, stages,
                            triple_jump)
from ._stages import Composition
from .recover import Recovering, SubstepLadder

__all__ = [
    "ADJOINT_COMPOSITIONS",
    "COMPOSITIONS",
    "Composition",
    "adjoint_composition",
    "compose",
    "from_splitting",
    "stages",
    "symmetric_pair",
    "triple_jump",
]


def symmetric_pair(method: Method) -> Composition:
    """S_h = Ψ*_{h/2} ∘ Ψ_{h/2}: symmetric, order 2 (order ≥ 1 methods; HLW Thm II.3.2)."""
    order = max(2, method.order if method.order % 2 == 0 else method.order + 1)
    return Composition([(method, 0.5), (method.adjoint(), 0.5)], order, True,
                       f"{method.name}*∘{method.name}")


def symmetric_composition(base: Method, gammas, order: int, scheme_name: str) -> Composition:
    """S_{γ_s h} ∘ … ∘ S_{γ_1 h} of a symmetric method S (HLW II.4): the stages of S, scaled by each γ."""
    return Composition([(base, float(g)) for g in gammas], order, True,
                       f"{scheme_name}{order}[{base.name}]")


def adjoint_composition(method: Method, betas, alphas, order: int, scheme_name: str) -> Composition:
    """Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ*_{α_1 h}∘Ψ_{β_1 h} (HLW V.3.2, eq. (3.4)): ``method`` and its
    adjoint in alternation. Symmetric when the coefficients are a palindrome (α_i = β_{s+1−i})."""
    adj = method.adjoint()
    parts = [(m, float(c)) for b, a in zip(betas, alphas) for m, c in ((method, b), (adj, a))]
    coef = [c for _, c in parts]
    return Composition(parts, order, bool(np.allclose(coef, coef[::-1], rtol=0, atol=1e-14)),
                       f"{scheme_name}{order}[{method.name}]")


@records_spec("compose")
def compose(method: Method, order: int = 2, scheme: str | None = None) -> Method:
    """A method of order 2, 4, 6 or 8 from ``method`` (any order-1 method of vpforms).

    order 2: Ψ*_{h/2}∘Ψ_{h/2}; order 4: ``scheme`` "suzuki" (default) or "triple_jump"; order 6:
    "kahan_li" (default), "yoshida" or "triple_jump"; order 8: "kahan_li" (default),
    "suzuki_umeno", "yoshida" or "triple_jump" — each a symmetric composition of the order-2
    method (or of ``method`` itself if it is already symmetric of order ≥ 2). Order 4 and 6,
    "blanes_moan":
    ``method`` and its adjoint in alternation (:func:`adjoint_composition`).

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

    Which needs the fewest stages for a given accuracy (``benchmarks/methods/results_orders.md``: SE+SE,
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
        return method._derived(bare, lambda a: SubstepLadder(bare, a.k) if isinstance(a, SubstepLadder)
                               else compose(a, order, scheme))
    base = method if (method.symmetric and method.order >= 2) else symmetric_pair(method)
    if order == 2:
        if scheme is not None:
            raise ValueError("order 2 is Ψ*_{h/2}∘Ψ_{h/2}; it takes no scheme")
        return base
    name = DEFAULT[order] if scheme is None else scheme
    if (order, name) in ADJOINT_COMPOSITIONS:
        return adjoint_composition(method, *ADJOINT_COMPOSITIONS[(order, name)], order, name)
    if (order, name) not in COMPOSITIONS:
        known = [n for (o, n) in [*COMPOSITIONS, *ADJOINT_COMPOSITIONS] if o == order]
        raise ValueError(f"unknown order-{order} composition {name!r}; known: {known}")
    return symmetric_composition(base, COMPOSITIONS[(order, name)], order, name)

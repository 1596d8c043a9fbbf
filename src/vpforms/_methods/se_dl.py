"""Class SE+DL — the paper's "DL+SE" (eq:case4): a discrete-Lagrangian stage for vf1(G¹) and a
symplectic Euler stage for vf2(G²).

Representative σ = (3,2,1), Σ = (1,3,2), sign +1. Corrected potentials (spec §4; the printed
φ = +L_d¹ is volume preserving but inconsistent):

    φ(x₁, x₂, X₂) = −L_d¹(x₂, X₂; x₁),   Φ(x₁, X₂, X₃) = −x₁X₃ + hG²(x₁, X₂, X₃)   (paper normalisation)

with L_d¹ the discrete Lagrangian of H = G¹ in (q, p) = (x₂, x₃), x₁ frozen. With θ = 0:
x̃₃ = x₃ − h∂₂G¹(x₁,x₂,x̃₃); X₂ = x₂ + h∂₃G¹(x₁,x₂,x̃₃); X₃ = x̃₃ + h∂₁G²(x₁,X₂,X₃);
X₁ = x₁ − h∂₃G²(x₁,X₂,X₃).
"""

from __future__ import annotations

from typing import Any

from .._map import GeneratingMap
from ._base import GeneratingMethod
from ._lagrangian import discrete_lagrangian
from ._representatives import REPRESENTATIVES

__all__ = ["SEDL"]


def dl_stage_one(field, theta: float, newton: dict, printed: bool):
    """φ in generic order, φ(Y₃, y₂, y₃) = φ(X₂, x₂, x₁) = s·L_d¹(x₂, X₂; x₁), and s.

    s = −1 (corrected, spec §4) or +1 (as printed in eq:case4 / eq:case3). H¹(q, p; x₁) = G¹(x₁, q, p).
    """
    G1, _ = field.dl_potentials
    L1 = discrete_lagrangian(lambda q, p, c: G1(c, q, p), theta, newton)
    s = 1.0 if printed else -1.0
    return L1, s


class SEDL(GeneratingMethod):
    """SE+DL (eq:case4, corrected): order 1, not symmetric.

    Parameters
    ----------
    theta:
        the discrete Lagrangian's evaluation point q₀ + θ(q₁ − q₀): 0 (symplectic Euler) or ½.
    printed:
        use the paper's printed sign φ = +L_d¹ (volume preserving, *not* consistent) — only to
        demonstrate the erratum.
    """

    name = "SE+DL"

    def __init__(self, field: Any, *, theta: float = 0.0, printed: bool = False,
                 newton: dict | None = None):
        self.field = field
        self.case = REPRESENTATIVES["SE+DL"]
        self.order, self.symmetric = 1, False
        self.theta, self.printed = float(theta), bool(printed)
        self.newton = {**GeneratingMethod.newton, **(newton or {})}
        if printed:
            self.name = "SE+DL(printed)"
        self._L1, self._s1 = dl_stage_one(field, self.theta, self.newton, self.printed)
        _, self._G2 = field.dl_potentials

    def generating_map(self, h, x=None):
        if x is None:
            raise ValueError("the DL potentials need the point x to select the root p̄ of L_d")
        L1, s1, G2 = self._L1, self._s1, self._G2
        p_guess = -s1 * x[2]  # volpot1: p₀ = −∂_{q₀}L_d¹ = −s1·x₃... so p̄ ≈ −s1·x₃

        def phi(X2, x2, x1):  # φ(Y₃, y₂, y₃) = φ(X₂, x₂, x₁)
            return s1 * L1(x2, X2, x1, h, p_guess)[0]

        def Phi(X2, X3, x1):  # Φ(Y₃, Y₂, y₃) = Φ(X₂, X₃, x₁) = −(−x₁X₃ + hG²(x₁, X₂, X₃)), sign +1
            return x1 * X3 - h * G2(x1, X2, X3)

        return GeneratingMap(phi, Phi, self.case, **self.newton)

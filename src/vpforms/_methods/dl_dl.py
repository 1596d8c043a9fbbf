"""Class DL+DL (eq:case3): discrete-Lagrangian stages for vf1(G¹) and vf2(G²).

Representative σ = (3,2,1), Σ = (3,1,2), sign −1. Corrected potentials (spec §4; both printed
signs are wrong):

    φ(x₁, x₂, X₂) = −L_d¹(x₂, X₂; x₁)  (H¹ = G¹ in (x₂, x₃)),
    Φ(x₁, X₁, X₂) = +L_d²(x₁, X₁; X₂)  (L² = x₃ẋ₁ + G²(x₁, X₂, x₃): H² = −G² in (x₁, x₃)),

so that x̃₃ = ∂_{X₂}L_d¹ = −∂_{x₁}L_d² and X₃ = ∂_{X₁}L_d². As printed: φ = +L_d¹ and
Φ = −L_d² with H² = +G². θ = 0 in both stages gives the same map as SE+DL; θ = ½ differs.
"""

from __future__ import annotations

from typing import Any

import jax

from .._map import GeneratingMap
from ._base import GeneratingMethod
from ._lagrangian import discrete_lagrangian
from .se_dl import DLPredictor

__all__ = ["DLDL"]


class DLDL(DLPredictor, GeneratingMethod):
    """DL+DL (eq:case3, corrected): order 1, not symmetric; ``theta`` ∈ {0, ½}; ``printed=True``
    gives the paper's signs (volume preserving, not consistent). The step is evaluated as its two
    θ-stages (default, ``fast=True``; see :class:`vpforms._methods.se_dl.DLPredictor`) or, with
    ``fast=False``, by the engine's solve of the generating map (the reference form)."""

    splitting = "dl"
    name = "DL+DL"

    def __init__(self, field: Any, *, theta: float = 0.0, printed: bool = False,
                 fast: bool | None = None, newton: dict | None = None):
        self._init_dl(field, "DL+DL", theta, printed, fast, newton)
        _, G2 = field.dl_potentials
        kappa = 1.0 if printed else -1.0  # H²(q, p; X₂) = κ·G²(q, X₂, p), (q, p) = (x₁, x₃)
        self._L2 = discrete_lagrangian(lambda q, p, c: kappa * G2(q, c, p), self.theta, self.newton)
        self._s2 = -1.0 if printed else 1.0  # Φ = s2·L_d²
        self._init_predictor(self.theta)

    def generating_map(self, h, x=None):
        if x is None:
            raise ValueError("the DL potentials need the point x to select the roots p̄ of L_d")
        L1, s1, L2, s2 = self._L1, self._s1, self._L2, self._s2
        # volpot1: p₀¹ = −s1·x₃; volpot2 (sign −1): p₀² = −s1·p₁¹/s2 ≈ x₃/s2
        x3 = jax.lax.stop_gradient(x[2])
        g1, g2 = -s1 * x3, x3 / s2

        def phi(X2, x2, x1):  # φ(Y₃, y₂, y₃) = φ(X₂, x₂, x₁)
            return s1 * L1(x2, X2, x1, h, g1)

        def Phi(X2, X1, x1):  # Φ(Y₃, Y₂, y₃) = Φ(X₂, X₁, x₁) = s2·L_d²(x₁, X₁; X₂)
            return s2 * L2(x1, X1, X2, h, g2)

        return GeneratingMap(phi, Phi, self.case, **self.newton)

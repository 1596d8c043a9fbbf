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

import math
from typing import Any

import jax

import jax.numpy as jnp

from .._map import GeneratingMap
from ._base import GeneratingMethod, merge_status
from ._lagrangian import discrete_lagrangian, dl_stage
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


class DLPredictor:
    """Initial guesses for the DL classes: the stages of the map written as nested scalar roots
    (:func:`dl_stage`), stage 1 for H¹ = G¹ in (x₂, x₃) and stage 2 for H² = −G² in (x₁, x₃).

    The step itself is the engine's solve; a guess at the solution only keeps its Newton iteration
    from crossing the fold of L_d (where the DL twist fails) when the trajectory passes close to it.
    The printed variants keep the Euler guess. With ``fast=True`` (the default since issue #19; ``fast=False``
    is the engine form) the step *is* the stage form
    (tested equal to the engine where the twist holds): a composition of two exactly symplectic
    θ-stages with a frozen coordinate, hence exactly volume preserving, and defined also across the
    fold where the DL generating form ceases to exist.
    """

    @property
    def guess_is_solution(self) -> bool:
        return not self.printed

    def _init_predictor(self, theta2: float):
        G1, G2 = self.field.dl_potentials
        H1 = lambda q, p, c: G1(c, q, p)  # noqa: E731
        H2 = lambda q, p, c: -G2(q, c, p)  # noqa: E731
        n = self.newton
        self._st = (dl_stage(H1, self.theta, n), dl_stage(H2, theta2, n))
        self._st_inv = (dl_stage(H1, 1.0 - self.theta, n), dl_stage(H2, 1.0 - theta2, n))

    def _stages(self, x, h):
        """The step as its two stages (the direct path): (X, status, iterations)."""
        X2, pt, s1, n1 = self._st[0](x[1], x[2], x[0], h)
        X1, X3, s2, n2 = self._st[1](x[0], pt, X2, h)
        X = jnp.stack([X1, X2, X3])
        return X, merge_status(s1, s2, jnp.where(jnp.all(jnp.isfinite(X)), 0, 3)), n1 + n2

    def _stages_inverse(self, X, h):
        x1, pt, s1, n1 = self._st_inv[1](X[0], X[2], X[1], -h)
        x2, x3, s2, n2 = self._st_inv[0](X[1], pt, x1, -h)
        x = jnp.stack([x1, x2, x3])
        return x, merge_status(s1, s2, jnp.where(jnp.all(jnp.isfinite(x)), 0, 3)), n1 + n2

    def _guess(self, x, h):
        if self.printed:
            return self.euler_guess(x, h), jnp.int32(0)
        X, _, n = self._stages(x, h)
        return X, n

    def _guess_inverse(self, X, h):
        if self.printed:
            return self.euler_guess(X, -h), jnp.int32(0)
        x, _, n = self._stages_inverse(X, h)
        return x, n

    def _forward(self, x, h):
        return self._stages(x, h) if self.fast else super()._forward(x, h)

    def _backward(self, X, h):
        return self._stages_inverse(X, h) if self.fast else super()._backward(X, h)

    @property
    def via_engine(self) -> bool:
        return not self.fast

    @staticmethod
    def _theta(theta: Any) -> float:
        """θ as a float; a NaN/infinite θ is an error here, not a NaN in every step."""
        t = float(theta)
        if not math.isfinite(t):
            raise ValueError(f"theta must be a finite number (0 or 0.5), got {theta!r}")
        return t

    def _init_dl(self, field: Any, cls: str, theta: Any, printed: bool, fast: bool | None,
                 newton: dict | None):
        """The traits and stage 1 (H¹ = G¹, shared by SE+DL and DL+DL) of the class ``cls``."""
        self.field = field
        self.case = REPRESENTATIVES[cls]
        self.order, self.symmetric = 1, False
        self.theta, self.printed = self._theta(theta), bool(printed)
        self.newton = {**GeneratingMethod.newton, **(newton or {})}
        self._check_fast(fast)
        if printed:
            self.name = f"{cls}(printed)"
        self._L1, self._s1 = dl_stage_one(field, self.theta, self.newton, self.printed)

    def _check_fast(self, fast: bool | None):
        """``fast`` None (default): the stage form, but the printed variant (which has no stages)
        runs through the engine; ``fast=False`` asks for the engine form (the reference)."""
        if fast and self.printed:
            raise ValueError("fast=True evaluates the corrected stages; the printed variant has none")
        self.fast = (not self.printed) if fast is None else bool(fast)


class SEDL(DLPredictor, GeneratingMethod):
    """SE+DL (eq:case4, corrected): order 1, not symmetric.

    Parameters
    ----------
    theta:
        the discrete Lagrangian's evaluation point q₀ + θ(q₁ − q₀): 0 (symplectic Euler) or ½.
    printed:
        use the paper's printed sign φ = +L_d¹ (volume preserving, *not* consistent) — only to
        demonstrate the erratum.
    fast:
        evaluate the step as its two stages (:class:`DLPredictor`), the default (issue #19: no fold
        failures, native, 7–11× faster than the engine); ``False`` solves the generating map by the
        engine (the reference form, tested equal to the stages where the twist holds).
    """

    splitting = "dl"
    name = "SE+DL"

    def __init__(self, field: Any, *, theta: float = 0.0, printed: bool = False,
                 fast: bool | None = None, newton: dict | None = None):
        self._init_dl(field, "SE+DL", theta, printed, fast, newton)
        _, self._G2 = field.dl_potentials
        self._init_predictor(0.0)  # the SE stage for vf2(G²) is the θ = 0 stage

    def generating_map(self, h, x=None):
        if x is None:
            raise ValueError("the DL potentials need the point x to select the root p̄ of L_d")
        L1, s1, G2 = self._L1, self._s1, self._G2
        # volpot1: s1·∂_{q₀}L_d¹ = x₃, so p₀ = −∂_{q₀}L_d¹ = −s1·x₃ and p̄ = p₀ + O(h)
        p_guess = -s1 * jax.lax.stop_gradient(x[2])

        def phi(X2, x2, x1):  # φ(Y₃, y₂, y₃) = φ(X₂, x₂, x₁)
            return s1 * L1(x2, X2, x1, h, p_guess)

        def Phi(X2, X3, x1):  # Φ(Y₃, Y₂, y₃) = Φ(X₂, X₃, x₁) = −(−x₁X₃ + hG²(x₁, X₂, X₃)), sign +1
            return x1 * X3 - h * G2(x1, X2, X3)

        return GeneratingMap(phi, Phi, self.case, **self.newton)

"""Class SE+SE (eq:case5): two symplectic Euler stages, for vf1(F¹) and vf3(F³).

Representative σ = (3,2,1), Σ = (1,2,3), sign −1, potentials (correct as printed, spec §4)

    φ = x₂X₃ + hF¹(x₁, x₂, X₃),    Φ = x₁X₂ + hF³(x₁, X₂, X₃),

which give X₃ = x₃ − h∂₂F¹(x₁,x₂,X₃); X₂ = x₂ + h∂₃F¹(x₁,x₂,X₃) − h∂₁F³(x₁,X₂,X₃);
X₁ = x₁ + h∂₂F³(x₁,X₂,X₃).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import sympy as sp

from .._map import GeneratingMap
from .._newton import newton_scalar
from ._base import GeneratingMethod, merge_status
from ._representatives import REPRESENTATIVES

__all__ = ["SESE", "SESEFast"]


class SESE(GeneratingMethod):
    """SE+SE (eq:case5) for any field with SE potentials a = vf1(F¹) + vf3(F³) (eq:vf1, eq:vf3).

    Order 1, not symmetric. ``newton`` overrides the GeneratingMap Newton controls.
    """

    splitting = "se"
    name = "SE+SE"

    def __init__(self, field: Any, *, newton: dict | None = None):
        self.field = field
        self.case = REPRESENTATIVES["SE+SE"]
        self.order, self.symmetric = 1, False
        self.newton = {**GeneratingMethod.newton, **(newton or {})}
        self._F1, self._F3 = field.se_potentials

    def generating_map(self, h, x=None):
        F1, F3 = self._F1, self._F3

        # generic arguments (MATH.md §2): φ(Y₃, y₂, y₃) = φ(X₃, x₂, x₁), Φ(Y₃, Y₂, y₃) = Φ(X₃, X₂, x₁)
        def phi(X3, x2, x1):
            return x2 * X3 + h * F1(x1, x2, X3)

        def Phi(X3, X2, x1):
            return x1 * X2 + h * F3(x1, X2, X3)

        return GeneratingMap(phi, Phi, self.case, **self.newton)


class SESEFast(SESE):
    """SE+SE evaluated directly as the composition of its shears (same map as :class:`SESE`).

    Each scalar equation that is explicit — decided symbolically from the closed-form potentials
    (e.g. ABC: ∂₂F¹ does not depend on x₃, ∂₁F³ not on x₂) — is evaluated in closed form; the
    others use the one scalar Newton. The inverse Ψ_h⁻¹ — hence the adjoint Ψ*_h = (Ψ_{−h})⁻¹,
    which :class:`~vpforms._methods._base.Adjoint` evaluates as ``_backward(x, −h)`` — is the
    inverse shears in reverse order, explicit where the same symbolic test holds for the inverse
    equations (e.g. ABC: ∂₂F³ free of x₁, ∂₃F¹ free of x₂), one scalar Newton otherwise.
    """

    name = "SE+SE(fast)"
    via_engine = False

    def __init__(self, field: Any, *, newton: dict | None = None):
        super().__init__(field, newton=newton)
        self.explicit = _explicit_flags(field)
        self.explicit_inverse = _explicit_inverse_flags(field)
        g = jax.grad
        self._d2F1, self._d3F1 = g(self._F1, 1), g(self._F1, 2)
        self._d1F3, self._d2F3 = g(self._F3, 0), g(self._F3, 1)

    def _forward(self, x, h):
        x1, x2, x3 = x[0], x[1], x[2]
        e3, e2 = self.explicit
        opts = dict(self.newton)
        d2F1, d3F1, d1F3, d2F3 = self._d2F1, self._d3F1, self._d1F3, self._d2F3
        # X₃ = x₃ − h∂₂F¹(x₁, x₂, X₃)   (volpot1)
        X3, s3, i3 = _shear(e3, lambda: x3 - h * d2F1(x1, x2, x3),
                            lambda z, p: z - p[2] + p[3] * d2F1(p[0], p[1], z), x3, (x1, x2, x3, h), opts)
        # X₂ = x₂ + h∂₃F¹(x₁, x₂, X₃) − h∂₁F³(x₁, X₂, X₃)   (volpot2)
        b = x2 + h * d3F1(x1, x2, X3)
        X2, s2, i2 = _shear(e2, lambda: b - h * d1F3(x1, x2, X3),
                            lambda z, p: z - p[1] + p[3] * d1F3(p[0], z, p[2]), x2, (x1, b, X3, h), opts)
        X1 = x1 + h * d2F3(x1, X2, X3)  # volpot3
        X = jnp.stack([X1, X2, X3])
        status = merge_status(s3, s2, jnp.where(jnp.all(jnp.isfinite(X)), 0, 3))
        return X, status, i3 + i2

    def _backward(self, X, h):
        X1, X2, X3 = X[0], X[1], X[2]
        e1, e2 = self.explicit_inverse
        opts = dict(self.newton)
        d2F1, d3F1, d1F3, d2F3 = self._d2F1, self._d3F1, self._d1F3, self._d2F3
        # x₁ from X₁ = x₁ + h∂₂F³(x₁, X₂, X₃)   (volpot3, solved for x₁)
        x1, s1, i1 = _shear(e1, lambda: X1 - h * d2F3(X1, X2, X3),
                            lambda z, p: z - p[0] + p[3] * d2F3(z, p[1], p[2]), X1, (X1, X2, X3, h), opts)
        # x₂ from x₂ + h∂₃F¹(x₁, x₂, X₃) = X₂ + h∂₁F³(x₁, X₂, X₃)   (volpot2, solved for x₂)
        c = X2 + h * d1F3(x1, X2, X3)
        x2, s2, i2 = _shear(e2, lambda: c - h * d3F1(x1, X2, X3),
                            lambda z, p: z - p[1] + p[3] * d3F1(p[0], z, p[2]), X2, (x1, c, X3, h), opts)
        x3 = X3 + h * d2F1(x1, x2, X3)  # volpot1, explicit for x₃
        x = jnp.stack([x1, x2, x3])
        status = merge_status(s1, s2, jnp.where(jnp.all(jnp.isfinite(x)), 0, 3))
        return x, status, i1 + i2


def _shear(explicit: bool, closed_form, residual, z0, params, opts):
    """One scalar equation of the three shears: its closed form where it is explicit in the
    unknown (decided symbolically), else the one Newton solve of residual(z, params) = 0."""
    if explicit:
        return closed_form(), jnp.int32(0), jnp.int32(0)
    return newton_scalar(residual, jax.grad(residual), z0, params, **opts)


def _derivatives_free_of(field, checks) -> tuple[bool, ...]:
    """For each (k, i, j) of ``checks``: is ∂ᵢ of the SE potential k (0: F¹, 1: F³) free of xⱼ
    (0-based indices), symbolically; all False without closed-form potentials."""
    exprs = getattr(field, "se_potential_exprs", None)
    if exprs is None or field.symbols is None:
        return tuple(False for _ in checks)
    xs = field.symbols
    F = [sp.sympify(e) for e in exprs]
    return tuple(xs[j] not in sp.diff(F[k], xs[i]).free_symbols for k, i, j in checks)


def _explicit_inverse_flags(field) -> tuple[bool, bool]:
    """(∂₂F³ free of x₁, ∂₃F¹ free of x₂), symbolically: the inverse shears are explicit."""
    return _derivatives_free_of(field, ((1, 1, 0), (0, 2, 1)))


def _explicit_flags(field) -> tuple[bool, bool]:
    """(∂₂F¹ free of x₃, ∂₁F³ free of x₂), symbolically; (False, False) without closed forms."""
    return _derivatives_free_of(field, ((0, 1, 2), (1, 0, 1)))

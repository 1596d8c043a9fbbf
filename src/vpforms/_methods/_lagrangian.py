"""The phase-space discrete Lagrangian used by the DL stages (spec §4, Marsden–West).

For a one-degree-of-freedom Hamiltonian H(q, p; c) (c a frozen coordinate),

    L_d(q₀, q₁) = ext_p̄ [ p̄ (q₁ − q₀) − h H(q₀ + θ(q₁ − q₀), p̄; c) ],

i.e. p̄ solves B(p̄) = q₁ − q₀ − h ∂_pH(q_θ, p̄; c) = 0, a scalar root found by the one Newton
(:func:`vpforms._newton.newton_scalar`). Then p₀ = −∂_{q₀}L_d and p₁ = ∂_{q₁}L_d: θ = 0 is
symplectic Euler (p̄ = p₁), θ = ½ an implicit-midpoint-type stage. No Legendre inversion.

Why first-derivative-exact p̄ is enough: autodiff of L_d gives ∂L_d = (envelope terms) + B·∂p̄,
and ∂²L_d = (envelope second derivatives, which need only ∂p̄) + (∂B)·∂p̄ + B·∂²p̄. The IFT makes
∂B = 0 and B ≈ 0 at the root, so the second derivatives the generating-map engine uses for the
step and its Jacobian are exact to rounding (det ≡ 1).
"""

from __future__ import annotations

import jax

from .._newton import newton_scalar

__all__ = ["discrete_lagrangian"]


def discrete_lagrangian(H, theta: float, newton: dict):
    """Return L(q0, q1, c, h, p_guess) -> (L_d, status) for the Hamiltonian H(q, p, c).

    ``p_guess`` selects the branch of p̄ (use the momentum of the current point).
    """
    dHp = jax.grad(H, argnums=1)
    theta = float(theta)

    def B(pbar, prm):
        q0, q1, c, h = prm
        return (q1 - q0) - h * dHp(q0 + theta * (q1 - q0), pbar, c)

    dB = jax.grad(B, argnums=0)

    def L(q0, q1, c, h, p_guess):
        pbar, status, _ = newton_scalar(B, dB, p_guess, (q0, q1, c, h), **newton)
        return pbar * (q1 - q0) - h * H(q0 + theta * (q1 - q0), pbar, c), status

    return L

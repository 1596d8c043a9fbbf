"""The generic implicit volume-preserving map f^±_{φ,Φ} (eq:volpot) and its permuted versions.

For two potentials φ, Φ : R³ → R and a sign ±, the map y ↦ Y is defined by

    ∂₂φ(Y₃, y₂, y₃) = y₁                      (volpot1)  — a scalar equation for Y₃
    ∂₃Φ(Y₃, Y₂, y₃) ± ∂₁φ(Y₃, y₂, y₃) = 0     (volpot2)  — then a scalar equation for Y₂
    Y₁ = ∂₂Φ(Y₃, Y₂, y₃)                      (volpot3)  — explicit

and the case (σ, Σ) acts by ((σ, Σ)·f)(x) = f(x·σ)·Σ⁻¹, i.e. y = x·σ and Y = X·Σ (MATH.md §2).
det D((σ,Σ)·f^±) = ±sgn σ sgn Σ, so the sign must be sgn τ = case.sign for a consistent map.
This is the one engine every integrator in vpforms goes through.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp

from ._case import Case
from ._errors import RESULTS, VPFormsError, raise_for_status
from ._newton import newton_scalar
from ._perm import FLIP, Perm, as_perm

__all__ = ["GeneratingMap"]

Potential = Callable[[Any, Any, Any], Any]


def _as_points(x: Any, name: str = "x") -> jax.Array:
    x = jnp.asarray(x, dtype=jnp.result_type(float))
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (N, 3); got shape {tuple(x.shape)}")
    return x


def _batched(fn: Callable, x: jax.Array, *more: jax.Array):
    """Apply a per-point function to (3,) or (..., 3) arrays by vmap over flattened points."""
    if x.ndim == 1:
        return fn(x, *more)
    lead = x.shape[:-1]
    flat = [a.reshape(-1, *a.shape[len(lead):]) for a in (x, *more)]
    out = jax.vmap(fn)(*flat)
    return jax.tree_util.tree_map(lambda o: o.reshape(*lead, *o.shape[1:]), out)


def _derivatives(phi: Potential, Phi: Potential):
    d1phi = jax.grad(phi, argnums=0)
    d2phi = jax.grad(phi, argnums=1)
    d12phi = jax.grad(d2phi, argnums=0)
    d2Phi = jax.grad(Phi, argnums=1)
    d3Phi = jax.grad(Phi, argnums=2)
    d23Phi = jax.grad(d3Phi, argnums=1)
    return d1phi, d2phi, d12phi, d2Phi, d3Phi, d23Phi


def _solve_generic(static, y: jax.Array, Y_guess: jax.Array, s: jax.Array):
    """The generic map f^± (s = ±1) on one point y = (y1, y2, y3): (Y, status, iterations)."""
    phi, Phi, tol, max_iter, twist_tol = static
    d1phi, d2phi, d12phi, d2Phi, d3Phi, d23Phi = _derivatives(phi, Phi)
    opts = dict(tol=tol, max_iter=max_iter, twist_tol=twist_tol)

    # (volpot1) ∂₂φ(Y₃, y₂, y₃) − y₁ = 0, solved for Y₃; twist ∂₁₂φ ≠ 0.
    Y3, st1, it1 = newton_scalar(
        lambda Y3, p: d2phi(Y3, p[1], p[2]) - p[0],
        lambda Y3, p: d12phi(Y3, p[1], p[2]),
        Y_guess[2],
        (y[0], y[1], y[2]),
        **opts,
    )
    # (volpot2) ∂₃Φ(Y₃, Y₂, y₃) ± ∂₁φ(Y₃, y₂, y₃) = 0, solved for Y₂; twist ∂₂₃Φ ≠ 0.
    Y2, st2, it2 = newton_scalar(
        lambda Y2, p: d3Phi(p[0], Y2, p[2]) + s * d1phi(p[0], p[1], p[2]),
        lambda Y2, p: d23Phi(p[0], Y2, p[2]),
        Y_guess[1],
        (Y3, y[1], y[2]),
        **opts,
    )
    # (volpot3) Y₁ = ∂₂Φ(Y₃, Y₂, y₃).
    Y1 = d2Phi(Y3, Y2, y[2])
    Y = jnp.stack([Y1, Y2, Y3])

    status = jnp.where(st1 != RESULTS.successful, st1, st2)
    bad_in = ~jnp.all(jnp.isfinite(y))
    bad_out = ~jnp.all(jnp.isfinite(Y))
    status = jnp.where(
        bad_in | ((status == RESULTS.successful) & bad_out), RESULTS.nonfinite, status
    ).astype(jnp.int32)
    return Y, status, it1 + it2


def _solve_point(static, x: jax.Array, X_guess: jax.Array, idx: jax.Array, sign: jax.Array):
    """((σ,Σ)·f)(x) = f(x·σ)·Σ⁻¹ on one point; idx = gather indices of (σ, Σ, Σ⁻¹)."""
    y = x[idx[0]]  # y = x·σ = (x₊, x∘, x₋)
    Y_guess = X_guess[idx[1]]  # Y = X·Σ = (X₊, X∘, X₋)
    Y, status, iters = _solve_generic(static, y, Y_guess, sign)
    return Y[idx[2]], status, iters  # X = Y·Σ⁻¹


@partial(jax.jit, static_argnums=0)
def _solve_kernel(static, x, guess, idx, sign):
    return _batched(lambda a, b: _solve_point(static, a, b, idx, sign), x, guess)


@partial(jax.jit, static_argnums=0)
def _residual_kernel(static, x, X, idx, s):
    phi, Phi = static[:2]
    d1phi, d2phi, _, d2Phi, d3Phi, _ = _derivatives(phi, Phi)

    def one(xp, Xp):
        y, Y = xp[idx[0]], Xp[idx[1]]
        return jnp.stack(
            [
                d2phi(Y[2], y[1], y[2]) - y[0],  # volpot1
                d3Phi(Y[2], Y[1], y[2]) + s * d1phi(Y[2], y[1], y[2]),  # volpot2
                d2Phi(Y[2], Y[1], y[2]) - Y[0],  # volpot3
            ]
        )

    return _batched(one, x, X)


@partial(jax.jit, static_argnums=0)
def _jacobian_kernel(static, x, idx, sign):
    def one(xp):
        # forward-mode AD through the solves; the status rides along as auxiliary output
        return jax.jacfwd(lambda z: _solve_point(static, z, z, idx, sign)[:2], has_aux=True)(xp)

    return _batched(one, x)


class GeneratingMap:
    """The volume-preserving map ((σ, Σ)·f^±_{φ,Φ}) of eq:volpot.

    Parameters
    ----------
    phi, Phi:
        JAX-traceable potentials R³ → R called with three scalars ``(y1, y2, y3)`` in the *generic*
        argument order of eq:volpot: φ(Y₃, y₂, y₃) = φ(X₋, x∘, x₋) and Φ(Y₃, Y₂, y₃) = Φ(X₋, X∘, x₋).
        All derivatives come from JAX autodiff.
    case:
        The permutation case; default ``Case((1,2,3), (1,2,3))`` (the bare map f).
    sign:
        The sign in (volpot2). ``None`` means ``case.sign`` (= sgn τ), the only choice that can be
        consistent. The opposite sign is allowed and gives an orientation-*reversing* map
        (det = −1), which is never consistent with any vector field.
    tol, max_iter, twist_tol:
        Newton controls for the two scalar solves (see :func:`vpforms._newton.newton_scalar`).

    Notes
    -----
    Evaluation is two sequential scalar Newton solves (volpot1 for X₋, then volpot2 for X∘) and
    one explicit formula (volpot3 for X₊) — never a 3×3 system.

    * ``m(x)`` returns X and raises :class:`TwistConditionError`, :class:`ConvergenceError` or
      :class:`NonFiniteError` when any point failed (it cannot be used under ``jit``).
    * ``m.solve(x)`` is the jit/vmap-compatible entry point and returns ``(X, status)`` with a
      per-point ``RESULTS`` code.
    """

    def __init__(
        self,
        phi: Potential,
        Phi: Potential,
        case: Case | None = None,
        sign: int | None = None,
        *,
        tol: float = 1e-13,
        max_iter: int = 50,
        twist_tol: float = 1e-12,
    ):
        if not callable(phi) or not callable(Phi):
            raise TypeError("phi and Phi must be callables of three scalars (y1, y2, y3)")
        self.phi = phi
        self.Phi = Phi
        self.case = Case((1, 2, 3), (1, 2, 3)) if case is None else case
        if not isinstance(self.case, Case):
            raise TypeError(f"case must be a vpforms.Case, got {type(case).__name__}")
        if sign is None:
            sign = self.case.sign
        if sign not in (1, -1):
            raise ValueError(f"sign must be +1, -1 or None, got {sign!r}")
        self.sign = int(sign)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.twist_tol = float(twist_tol)

    @property
    def consistent_sign(self) -> bool:
        """Whether the sign obeys the sign rule (sign = sgn τ), i.e. the map preserves orientation."""
        return self.sign == self.case.sign

    @property
    def _static(self):
        return (self.phi, self.Phi, self.tol, self.max_iter, self.twist_tol)

    @property
    def _perm_indices(self) -> jax.Array:
        # σ, Σ and Σ⁻¹ as 0-based gather indices, passed as *data* (like the sign) so that the 36
        # cases (and the inverse and relabelled maps) share one compiled kernel per potential pair.
        c = self.case
        return jnp.array([c.sigma.index, c.Sigma.index, c.Sigma.inverse().index], dtype=jnp.int32)

    @property
    def _sign_array(self) -> jax.Array:
        return jnp.asarray(self.sign, dtype=jnp.result_type(float))

    # -- public evaluation ------------------------------------------------------------------------
    def solve(self, x: Any, guess: Any = None, *, return_iterations: bool = False):
        """X and the per-point status for x of shape (3,) or (..., 3); jit- and vmap-compatible.

        ``guess`` is an initial guess for X (default: x). With ``return_iterations=True`` the total
        Newton iteration count per point is returned as a third array.
        """
        x = _as_points(x)
        g = x if guess is None else jnp.broadcast_to(_as_points(guess, "guess"), x.shape)
        X, status, iters = _solve_kernel(self._static, x, g, self._perm_indices, self._sign_array)
        return (X, status, iters) if return_iterations else (X, status)

    def __call__(self, x: Any, guess: Any = None) -> jax.Array:
        """X = ((σ,Σ)·f^±)(x); raises the named error if any point fails. Not for use under jit."""
        X, status = self.solve(x, guess)
        if isinstance(status, jax.core.Tracer):
            raise VPFormsError(
                "GeneratingMap.__call__ checks the per-point status and cannot run under "
                "jit/vmap tracing; use m.solve(x), which returns (X, status)."
            )
        raise_for_status(status, what=f"GeneratingMap{self.case}")
        return X

    def residual(self, x: Any, X: Any) -> jax.Array:
        """The three defining equations (volpot1–3) evaluated at (x, X); zero at X = m(x)."""
        x = _as_points(x)
        X = jnp.broadcast_to(_as_points(X, "X"), x.shape)
        return _residual_kernel(self._static, x, X, self._perm_indices, self._sign_array)

    def jacobian_and_status(self, x: Any):
        """(DX/Dx, status) by forward-mode AD through the solves (exact IFT derivatives)."""
        return _jacobian_kernel(self._static, _as_points(x), self._perm_indices, self._sign_array)

    def jacobian(self, x: Any) -> jax.Array:
        """The one-step Jacobian DX/Dx, shape (3, 3) or (N, 3, 3); raises on failed points."""
        J, status = self.jacobian_and_status(x)
        if not isinstance(status, jax.core.Tracer):
            raise_for_status(status, what=f"GeneratingMap{self.case}.jacobian")
        return J

    def det(self, x: Any) -> jax.Array:
        """det DX/Dx: ≡ +1 when sign = case.sign, ≡ −1 with the opposite sign."""
        return jnp.linalg.det(self.jacobian(x))

    # -- inverse and relabelling ----------------------------------------------------------------
    def inverse(self) -> "GeneratingMap":
        """The inverse map: (Σ, σ)·f_{Φ·p, φ·p} with the same sign (prop:permactvolpotinv)."""
        return GeneratingMap(
            FLIP.act_args(self.Phi),
            FLIP.act_args(self.phi),
            self.case.switched(),
            self.sign,
            tol=self.tol,
            max_iter=self.max_iter,
            twist_tol=self.twist_tol,
        )

    def relabel(self, pi: Perm | tuple[int, int, int]) -> "GeneratingMap":
        """(π, π)·((σ, Σ)·f) = (π∘σ, π∘Σ)·f  (prop:permactalg): same potentials, relabelled case."""
        return GeneratingMap(
            self.phi,
            self.Phi,
            self.case.relabel(as_perm(pi)),
            self.sign,
            tol=self.tol,
            max_iter=self.max_iter,
            twist_tol=self.twist_tol,
        )

    def __repr__(self) -> str:
        return (
            f"GeneratingMap(phi={getattr(self.phi, '__name__', self.phi)!s}, "
            f"Phi={getattr(self.Phi, '__name__', self.Phi)!s}, case={self.case!r}, "
            f"sign={self.sign:+d})"
        )

"""Beyond the paper: Quispel's correction maps for S1 and S2 on *nonlinear* fields (spec §5).

Quispel (Phys. Lett. A 206, 1995), in the form of Appendix A (t5vp) and B (t5vps2) *before* the
linear specialisation. With roles (i, j, k) = (1, 2, 3) for S1 and (1, 3, 2) for S2:

    X_i = x_i + h a_i(x_i, X_j, x_k)
    X_j = x_j + h a_j(x_i, X_j, x_k) − f_c(x_i, X_j, x_k)
    X_k = x_k + h a_k(X_i, X_j, x_k)

(arguments listed in the slots i, j, k), with the correction

    f_c = ∫_c^{X_j} [h ∂_k a_k(Q(s)) − h ∂_k a_k(P(s)) + h² ∂_i a_i(P(s)) ∂_k a_k(Q(s))] ds,

P(s) = (x_i, s, x_k), Q(s) = (x_i + h a_i(P(s)), s, x_k), and the lower limit c(x_i, x_k) fixed by
c = h a_j(x_i, c, x_k). Then ∂_{X_j} of the middle equation equals (1 + h∂_i a_i)(1 + h∂_k a_k(Q)),
which is exactly the condition det = 1 (div a = 0). One step is three scalar equations in
sequence — c, then X_j (both by the one Newton), then X_i, X_k explicitly; the inverse likewise
(x_k, x_i by Newton, x_j explicitly).

f_c is computed in closed form (SymPy antiderivative) when the field has SymPy expressions and the
integrand is polynomial in s (or zero, e.g. ABC); otherwise by differentiable Gauss–Legendre
quadrature (:func:`vpforms._quadrature.line_integral`), whose exact derivatives keep det = 1 up to
the quadrature error of the integrand (≈ 1e-16 for the default 32 nodes on smooth fields).

These maps exist wherever the scalar equations are solvable (h small), also where the S1/S2
twist fails (e.g. ∂a₁/∂x₃ = 0 for S1): there the generating form ceases to exist, not the map;
``method.twist(x, h)`` reports it. For linear fields the S1 map equals eq:S1_quispel (corrected)
and the S2 map equals eq:S2_quispel exactly.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import sympy as sp

from .._fieldops import _lambdify_with
from .._newton import newton_scalar
from .._quadrature import DEFAULT_N, line_integral
from ._base import GeneratingMethod, Method, merge_status
from ._representatives import REPRESENTATIVES

__all__ = ["QuispelCorrection", "QuispelS1", "QuispelS2"]

_ROLES = {"S1": (0, 1, 2), "S2": (0, 2, 1)}  # (i, j, k), 0-based
_LABEL = {"S1": "t5vp", "S2": "t5vps2"}


class QuispelCorrection(Method):
    """Quispel's correction map (t5vp / t5vps2) for any divergence-free field: order 1.

    Parameters
    ----------
    kind:
        ``"S1"`` or ``"S2"``.
    integral:
        ``"auto"`` (closed form when possible, else quadrature), ``"closed"`` or ``"quadrature"``.
    quadrature_n:
        Gauss–Legendre nodes for the quadrature (default 32).
    """

    def __init__(self, field: Any, kind: str = "S1", *, integral: str = "auto",
                 quadrature_n: int = DEFAULT_N, newton: dict | None = None):
        if kind not in _ROLES:
            raise ValueError(f"kind must be 'S1' or 'S2', not {kind!r}")
        if integral not in ("auto", "closed", "quadrature"):
            raise ValueError(f"integral must be 'auto', 'closed' or 'quadrature', not {integral!r}")
        self.field, self.kind = field, kind
        self.case = REPRESENTATIVES[kind]
        self.order, self.symmetric = 1, False
        self.name = f"{kind}-correction({_LABEL[kind]})"
        self.newton = {**GeneratingMethod.newton, **(newton or {})}
        self.roles = _ROLES[kind]
        self.quadrature_n = int(quadrature_n)
        a = field.components
        i, j, k = self.roles
        self._a = a
        self._dai = jax.grad(a[i], argnums=i)
        self._dak = jax.grad(a[k], argnums=k)
        self._fc_closed = None
        if integral != "quadrature":
            self._fc_closed = _closed_form_correction(field, self.roles)
            if self._fc_closed is None and integral == "closed":
                raise ValueError(
                    f"no closed form for the correction integral of {self.name} on field "
                    f"{field.name!r} (needs SymPy expressions with an integrand polynomial in s)"
                )
        self.integral = "closed form" if self._fc_closed is not None else (
            f"quadrature(n={self.quadrature_n})"
        )

    # -- the pieces, on role values (slot i, slot j, slot k) --------------------------------------
    def _at(self, m, vi, vj, vk):
        i, j, k = self.roles
        p = [None, None, None]
        p[i], p[j], p[k] = vi, vj, vk
        return self._a[m](p[0], p[1], p[2])

    def _d(self, fn, vi, vj, vk):
        i, j, k = self.roles
        p = [None, None, None]
        p[i], p[j], p[k] = vi, vj, vk
        return fn(p[0], p[1], p[2])

    def _lower(self, xi, xk, h):
        """c(x_i, x_k): c = h a_j(x_i, c, x_k)."""
        j = self.roles[1]

        def g(c, p):
            return c - p[2] * self._at(j, p[0], c, p[1])

        return newton_scalar(g, jax.grad(g), jnp.zeros_like(xi), (xi, xk, h), **self.newton)

    def correction(self, xi, u, xk, c, h):
        """f_c(x_i, u, x_k) = ∫_c^u w(s) ds (closed form or quadrature)."""
        if self._fc_closed is not None:
            W = self._fc_closed
            return W(xi, u, xk, h) - W(xi, c, xk, h)
        i = self.roles[0]

        def w(s):
            ai = self._at(i, xi, s, xk)
            Qi = xi + h * ai
            dk_Q = self._d(self._dak, Qi, s, xk)
            return h * dk_Q - h * self._d(self._dak, xi, s, xk) + h**2 * self._d(
                self._dai, xi, s, xk
            ) * dk_Q

        return line_integral(w, c, u, self.quadrature_n)

    # -- the map and its inverse -----------------------------------------------------------------
    def _forward(self, x, h):
        i, j, k = self.roles
        xi, xj, xk = x[i], x[j], x[k]
        c, s0, n0 = self._lower(xi, xk, h)

        # middle equation of t5vp: X_j − x_j − h a_j(x_i, X_j, x_k) + f_c(x_i, X_j, x_k) = 0
        def g(u, p):
            xi_, xj_, xk_, c_, h_ = p
            return u - xj_ - h_ * self._at(j, xi_, u, xk_) + self.correction(xi_, u, xk_, c_, h_)

        u0 = xj + h * self._at(j, xi, xj, xk)
        Xj, s1, n1 = newton_scalar(g, jax.grad(g), u0, (xi, xj, xk, c, h), **self.newton)
        Xi = xi + h * self._at(i, xi, Xj, xk)
        Xk = xk + h * self._at(k, Xi, Xj, xk)
        X = _place(self.roles, Xi, Xj, Xk)
        return X, merge_status(s0, s1, _finite(X)), n0 + n1

    def _backward(self, X, h):
        i, j, k = self.roles
        Xi, Xj, Xk = X[i], X[j], X[k]

        def gk(z, p):  # X_k = x_k + h a_k(X_i, X_j, x_k)
            return z + p[3] * self._at(k, p[0], p[1], z) - p[2]

        xk, s0, n0 = newton_scalar(
            gk, jax.grad(gk), Xk - h * self._at(k, Xi, Xj, Xk), (Xi, Xj, Xk, h), **self.newton
        )

        def gi(z, p):  # X_i = x_i + h a_i(x_i, X_j, x_k)
            return z + p[3] * self._at(i, z, p[1], p[2]) - p[0]

        xi, s1, n1 = newton_scalar(
            gi, jax.grad(gi), Xi - h * self._at(i, Xi, Xj, xk), (Xi, Xj, xk, h), **self.newton
        )
        c, s2, n2 = self._lower(xi, xk, h)
        xj = Xj - h * self._at(j, xi, Xj, xk) + self.correction(xi, Xj, xk, c, h)
        x = _place(self.roles, xi, xj, xk)
        return x, merge_status(s0, s1, s2, _finite(x)), n0 + n1 + n2


class QuispelS1(QuispelCorrection):
    """S1 through Quispel's correction map (t5vp), for any divergence-free field."""

    def __init__(self, field, **kw):
        super().__init__(field, "S1", **kw)


class QuispelS2(QuispelCorrection):
    """S2 through Quispel's correction map (t5vps2), for any divergence-free field."""

    def __init__(self, field, **kw):
        super().__init__(field, "S2", **kw)


def _place(roles, vi, vj, vk):
    i, j, k = roles
    p = [None, None, None]
    p[i], p[j], p[k] = vi, vj, vk
    return jnp.stack(p)


def _finite(X):
    return jnp.where(jnp.all(jnp.isfinite(X)), 0, 3).astype(jnp.int32)


def correction_integrand(a, symbols, roles, s, h):
    """w(s) of f_c = ∫_c^u w(s) ds as SymPy (what :meth:`QuispelCorrection.correction` integrates):
    h ∂_k a_k(Q(s)) − h ∂_k a_k(P(s)) + h² ∂_i a_i(P(s)) ∂_k a_k(Q(s)) with P(s) = (x_i, s, x_k),
    Q(s) = (x_i + h a_i(P(s)), s, x_k) in the slots (i, j, k); ``a`` in ``symbols``. The closed
    form integrates it; the native backend sums it by the quadrature rule."""
    i, j, k = roles
    sym = symbols
    P = {sym[j]: s}
    Q = {sym[i]: sym[i] + h * a[i].xreplace(P), sym[j]: s}
    dk = sp.diff(a[k], sym[k])
    di = sp.diff(a[i], sym[i])
    return h * dk.xreplace(Q) - h * dk.xreplace(P) + h**2 * di.xreplace(P) * dk.xreplace(Q)


def correction_antiderivative(field, roles):
    """(W, (s, h)): W(x_i, s, x_k, h) an antiderivative in s of the integrand of f_c, a SymPy
    expression in ``field.symbols[i]``, ``s``, ``field.symbols[k]``, ``h``; or None (no SymPy /
    integrand not polynomial in s). The native backend generates C from it."""
    if field.exprs is None or field.symbols is None:
        return None
    s, h = sp.Dummy("s", real=True), sp.Dummy("h", real=True)
    w = sp.expand(correction_integrand(field.exprs, field.symbols, roles, s, h))
    if w == 0:
        W = sp.Integer(0)
    elif w.is_polynomial(s):
        W = sp.integrate(w, s)
    else:
        return None
    return W, (s, h)


def _closed_form_correction(field, roles):
    """W(x_i, s, x_k, h) as a JAX function (:func:`correction_antiderivative`), or None."""
    found = correction_antiderivative(field, roles)
    if found is None:
        return None
    W, (s, h) = found
    i, j, k = roles
    sym = field.symbols
    f = _lambdify_with((sym[i], s, sym[k], h), W, "jax")

    def Wfun(vi, vs, vk, vh):
        return jnp.asarray(f(vi, vs, vk, vh), float) + 0.0 * vs

    return Wfun

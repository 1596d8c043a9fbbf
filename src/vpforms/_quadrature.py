"""Differentiable Gauss–Legendre line integrals in JAX.

Used by :mod:`vpforms.fields` when a potential of MATH.md §3 has no closed form.  A line integral
from a base point ``c`` to ``u`` is written on the fixed reference interval [0, 1],

    ∫_c^u f(s) ds = (u − c) · Σᵢ wᵢ f(c + (u − c) tᵢ),

with the n-point Gauss–Legendre nodes tᵢ and weights wᵢ mapped to [0, 1].  This is an ordinary
JAX expression in u and in every other variable f depends on, so ``jax.grad`` differentiates the
*quadrature itself*: a method built on quadrature potentials uses the exact derivatives of the
approximate potentials and stays exactly volume preserving (MATH.md §3, last paragraph).

Accuracy.  What the methods consume are derivatives of the potentials.  For the upper limit,
d/du of the rule above is exactly the n-point rule applied to ∫₀¹ d/dt[t f(c + (u − c)t)] dt =
f(u) (after the change of variables), so the reconstruction error of the field is the Gauss–Legendre
error of the smooth integrand g(t) = d/dt[t f(c + (u − c)t)] on [0, 1]:

    |E_n| ≤ (n!)⁴ / ((2n + 1) ((2n)!)³) · max_{[0,1]} |g^{(2n)}|,

which decays faster than geometrically in n for entire integrands (all fields in
:mod:`vpforms.problems`): with L = |u − c| and a derivative scale k (|f^{(j)}| ≲ M k^j), the
bound is ≈ M (2n + 1) (kL/4)^{2n} (e/(2n))^{2n}·const, below 1e-15 for kL ≲ 10 and n = 32.
Derivatives in the other variables (x₁, x₃ for ∂/∂x₁ of a potential) are the same n-point rule
applied to the derivative of the integrand, with the same kind of bound.

The same rule as a SymPy expression (:func:`line_integral_expr`, :class:`GLSum`) is what the
native backend generates C from: (u − c)·GLSum(f(c + (u − c)T)), whose derivatives are again
GLSums of the differentiated integrand — the derivatives ``jax.grad`` takes of
:func:`line_integral`, term by term.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from math import exp, lgamma, log
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

__all__ = [
    "GL_T",
    "GLSum",
    "gauss_legendre_01",
    "gl_error_bound",
    "line_integral",
    "line_integral_expr",
]

DEFAULT_N = 32


@lru_cache(maxsize=64)
def _nodes_weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
        raise ValueError(f"the number of Gauss–Legendre nodes must be a positive integer, not {n!r}")
    t, w = np.polynomial.legendre.leggauss(int(n))
    return (t + 1.0) / 2.0, w / 2.0


def gauss_legendre_01(n: int = DEFAULT_N) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of the n-point Gauss–Legendre rule on [0, 1] (weights sum to 1)."""
    t, w = _nodes_weights(n)
    return t.copy(), w.copy()


def line_integral(f: Callable[[Any], Any], lower: Any, upper: Any, n: int = DEFAULT_N) -> jax.Array:
    """∫_lower^upper f(s) ds by the n-point Gauss–Legendre rule, differentiable in everything.

    ``f`` is a scalar JAX function of one scalar (it may close over other traced variables); it
    is vmapped over the nodes.
    """
    t, w = _nodes_weights(n)
    t = jnp.asarray(t)
    w = jnp.asarray(w)
    length = upper - lower
    vals = jax.vmap(lambda ti: f(lower + length * ti))(t)
    return length * jnp.dot(w, vals)


#: the node variable of a :class:`GLSum` integrand (t ∈ [0, 1])
GL_T = sp.Symbol("gl_t", real=True)


class GLSum(sp.Expr):
    """Σᵢ wᵢ f(tᵢ): the n-point Gauss–Legendre rule on [0, 1] applied to the SymPy integrand
    f = ``args[0]``, a function of the node variable :data:`GL_T` and of other symbols.

    Unevaluated (the native backend loops over the nodes in C).  It is linear in f, so
    ∂/∂x Σᵢ wᵢ f(tᵢ, x) = Σᵢ wᵢ ∂f/∂x(tᵢ, x) (:meth:`_eval_derivative`), and T is bound (not a
    free symbol)."""

    is_commutative = True

    def __new__(cls, f: Any, n: int = DEFAULT_N):
        f = sp.sympify(f)
        if f == 0:
            return sp.S.Zero
        _nodes_weights(int(n))  # validates n
        return super().__new__(cls, f, sp.Integer(int(n)))

    @property
    def integrand(self) -> sp.Expr:
        return self.args[0]

    @property
    def n(self) -> int:
        return int(self.args[1])

    @property
    def free_symbols(self) -> set:
        return self.args[0].free_symbols - {GL_T}

    def _eval_derivative(self, s):
        return GLSum(sp.diff(self.args[0], s), self.n)

    def _sympystr(self, printer) -> str:
        return f"GLSum[n={self.n}]({printer._print(self.args[0])})"


def line_integral_expr(f: Callable[[Any], Any], lower: Any, upper: Any, n: int = DEFAULT_N) -> sp.Expr:
    """:func:`line_integral` as a SymPy expression: ∫_lower^upper f(s) ds ≈
    (upper − lower)·Σᵢ wᵢ f(lower + (upper − lower) tᵢ) = (upper − lower)·GLSum(f(lower + (upper − lower)T)).

    ``f`` maps a SymPy expression to one; its derivatives are those of the rule itself."""
    lower, upper = (sp.Integer(0) if v == 0 else sp.sympify(v) for v in (lower, upper))
    length = upper - lower
    return length * GLSum(f(lower + length * GL_T), n)


def gl_error_bound(n: int, max_deriv_2n: float, length: float = 1.0) -> float:
    """The classical bound |E_n| ≤ L^{2n+1} (n!)⁴ / ((2n+1) ((2n)!)³) · max |f^{(2n)}| on [a, a+L]."""
    if length == 0 or max_deriv_2n == 0:
        return 0.0
    logc = (2 * n + 1) * log(abs(length)) + 4 * lgamma(n + 1) - log(2 * n + 1) - 3 * lgamma(2 * n + 1)
    return exp(logc) * abs(max_deriv_2n)

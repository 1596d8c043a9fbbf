"""Vector potentials as objects: A with ∇×A = a, that know how to integrate themselves (issue #20).

A field given by a vector potential (coils, a spline of A on a grid, a toroidal-coordinate field)
is stepped by the generating-form methods through the SE or DL *pair* of A (MATH.md §3):

    SE:  A − ∇χ with χ = ∫_{c₂}^{x₂} A₂ dx₂  →  (F¹, F³) = (A₁ − ∂₁χ, A₃ − ∂₃χ)   (A₂ − ∂₂χ = 0)
    DL:  A − ∇χ with χ = ∫_{c₃}^{x₃} A₃ dx₃  →  (G¹, G²) = (A₁ − ∂₁χ, A₂ − ∂₂χ)

and the pair is exact — its curl is ∇×A to rounding — exactly when ∂_kχ = A_k. A
:class:`VectorPotential` supplies that antiderivative along its own axes: by the differentiable
Gauss–Legendre rule for callables (:class:`CallablePotential`), exactly for a spline (the
antiderivative of a B-spline along one axis is a B-spline of one degree more). Along a *periodic*
axis (φ of a toroidal field) the integral is split at whole periods,

    ∫_c^x f = k·∫_c^{c+T} f + ∫_c^{c+r} f,   x = c + kT + r,  0 ≤ r < T,

which is the same smooth function of x (continuous at every r = 0 seam, derivative f(x)) but never
integrates over more than one period, however far a field line has gone round the torus.

Relabelling (prop:trivperm) acts on the object (:meth:`VectorPotential.relabel`): Ã(x) = sgn π ·
A(x·π⁻¹)·π, and its antiderivative along x_k is sgn π times the original one along x_{π(k)}, so a
relabelled spline potential stays exact.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp

from ._perm import as_perm
from ._quadrature import DEFAULT_N, line_integral

__all__ = [
    "GAUGE_ZERO", "CallablePotential", "SumPotential", "VectorPotential", "curl_of", "gauge_pair",
    "periodic_line_integral",
]

#: the component a splitting's gauge sets to zero: A₂ (SE, 0-based 1), A₃ (DL, 0-based 2)
GAUGE_ZERO = {"se": 1, "dl": 2}
#: the components of A that form the pair: SE (A₁, A₃), DL (A₁, A₂)
_KEEP = {"se": (0, 2), "dl": (0, 1)}

Scalar = Callable[..., Any]


def periodic_line_integral(f: Callable[[Any], Any], lower: Any, upper: Any, period: float | None,
                           n: int = DEFAULT_N) -> jax.Array:
    """∫_lower^upper f(s) ds by the n-point Gauss–Legendre rule; for a ``period`` T (f T-periodic)
    as k·∫_lower^{lower+T} f + ∫_lower^{lower+r} f, upper = lower + kT + r, 0 ≤ r < T."""
    if period is None:
        return line_integral(f, lower, upper, n)
    T = float(period)
    k = jax.lax.stop_gradient(jnp.floor((upper - lower) / T))
    r = upper - lower - k * T  # ∂r/∂upper = 1
    return k * line_integral(f, lower, lower + T, n) + line_integral(f, lower, lower + r, n)


def gauge_pair(components: Sequence[Scalar], chi: Scalar, splitting: str) -> tuple[Scalar, Scalar]:
    """(A_i − ∂_iχ for i in the pair of ``splitting``), ∂_iχ by forward/reverse autodiff of χ."""
    A = tuple(components)

    def comp(i):
        dchi = jax.grad(chi, argnums=i)

        def P(x1, x2, x3):
            x1, x2, x3 = (jnp.asarray(v, float) for v in (x1, x2, x3))
            return jnp.asarray(A[i](x1, x2, x3), float) - dchi(x1, x2, x3)

        P.__name__ = f"{'FG'[splitting == 'dl']}{i + 1}_gauge"
        return P

    return tuple(comp(i) for i in _KEEP[splitting])


class VectorPotential:
    """A vector potential A = (A₁, A₂, A₃) in the field's coordinates, ∇×A = a (unit Jacobian).

    Contract (subclasses):

    * :meth:`components` — three JAX scalar callables A_i(x1, x2, x3), traceable, differentiable;
    * :attr:`periods` — per axis the period T of A along it (A(x + T e_k) = A(x)), or None;
    * :meth:`antiderivative` — χ_k with ∂χ_k/∂x_k = A_k and χ_k = 0 on x_k = c (may be exact;
      the default is the periodic-aware Gauss–Legendre rule);
    * :attr:`exact_gauge` — True if :meth:`antiderivative` is exact (then the pairs reproduce ∇×A to
      rounding); :attr:`description` — one line for ``Field.potential_method``.

    :meth:`gauge` (the pair of a splitting) and :meth:`relabel` are written once here.
    """

    periods: tuple[float | None, float | None, float | None] = (None, None, None)
    exact_gauge: bool = False
    description: str = "vector potential"

    def components(self) -> tuple[Scalar, Scalar, Scalar]:
        raise NotImplementedError

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N) -> Scalar:
        """χ(x) = ∫_c^{x_k} A_k(…, s, …) ds (periodic-aware Gauss–Legendre, n nodes)."""
        Ak, T = self.components()[k], self.periods[k]

        def chi(x1, x2, x3):
            x = [jnp.asarray(v, float) for v in (x1, x2, x3)]

            def integrand(s):
                y = list(x)
                y[k] = s
                return Ak(*y)

            return periodic_line_integral(integrand, jnp.asarray(c, float), x[k], T, n)

        return chi

    def gauge(self, splitting: str, origin: Sequence[float], n: int = DEFAULT_N) -> tuple[Scalar, Scalar]:
        """The SE (F¹, F³) or DL (G¹, G²) pair of A: A − ∇χ with χ the antiderivative of A_k along
        x_k from origin_k (k = 2 for SE, 3 for DL; module docstring)."""
        k = GAUGE_ZERO[splitting]
        chi = self.antiderivative(k, float(origin[k]), n)
        return gauge_pair(self.components(), chi, splitting)

    def relabel(self, pi: Any) -> VectorPotential:
        """Ã(x) = sgn π · A(x·π⁻¹)·π, the potential of the relabelled field ã(x) = a(x·π⁻¹)·π."""
        pi = as_perm(pi)
        return self if pi.is_identity else RelabelledPotential(self, pi)

    def __call__(self, x: Any) -> jax.Array:
        """A(x) for a point x of shape (3,)."""
        x = jnp.asarray(x, float)
        return jnp.stack([jnp.asarray(c(x[0], x[1], x[2]), float) for c in self.components()])


class CallablePotential(VectorPotential):
    """A from three JAX scalar callables (χ by the periodic-aware Gauss–Legendre rule)."""

    def __init__(self, components: Sequence[Scalar], periods: Sequence[float | None] = (None,) * 3,
                 description: str = "vector potential"):
        comps = tuple(components)
        if len(comps) != 3 or not all(callable(c) or c == 0 for c in comps):
            raise ValueError("a vector potential needs three scalar callables (or 0)")
        self._components = tuple(c if callable(c) else _zero for c in comps)
        self._zero_axes = tuple(not callable(c) for c in comps)
        self.periods = _check_periods(periods)
        self.description = description

    def components(self):
        return self._components

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N) -> Scalar:
        if self._zero_axes[k]:  # A_k ≡ 0: χ = 0, the pair is read off A
            return _zero
        return super().antiderivative(k, c, n)


class RelabelledPotential(VectorPotential):
    """Ã(x) = sgn π · A(x·π⁻¹)·π for a base potential A and a permutation π.

    Ã_k(x) = s·A_{π(k)}(y) with y = x·π⁻¹ (y_j = x_{π⁻¹(j)}), so y_{π(k)} = x_k and the
    antiderivative of Ã_k along x_k is s·χ_{π(k)}(y) — exact when the base's is."""

    def __init__(self, base: VectorPotential, pi: Any):
        self.base, self.pi = base, as_perm(pi)
        self._idx, self._inv = list(self.pi.index), list(self.pi.inverse().index)
        self._sign = float(self.pi.sign)
        self.periods = tuple(base.periods[k] for k in self._idx)
        self.exact_gauge = base.exact_gauge
        self.description = base.description

    def _pull(self, g: Scalar, scale: float) -> Scalar:
        inv = self._inv

        def h(x1, x2, x3):
            x = (x1, x2, x3)
            return scale * g(x[inv[0]], x[inv[1]], x[inv[2]])

        return h

    def components(self):
        base = self.base.components()
        return tuple(self._pull(base[m], self._sign) for m in self._idx)

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N) -> Scalar:
        return self._pull(self.base.antiderivative(self._idx[k], c, n), self._sign)

    def relabel(self, pi: Any) -> VectorPotential:
        # ρ (this one) then π: sgn π sgn ρ · A(x·π⁻¹·ρ⁻¹)·ρ·π, the base relabelled by ρ∘π
        # (tested against relabelling the field twice)
        return self.base.relabel(self.pi * as_perm(pi))


class SumPotential(VectorPotential):
    """A = Σ_j A⁽ʲ⁾: the antiderivatives add, so the gauge is exact when every part's is
    (a spline of the smooth coils plus the exact potential of a singular filament ring)."""

    def __init__(self, parts: Sequence[VectorPotential], periods: Sequence[float | None] | None = None):
        self.parts = tuple(parts)
        if not self.parts or not all(isinstance(p, VectorPotential) for p in self.parts):
            raise TypeError("SumPotential needs one or more VectorPotential parts")
        self.periods = _check_periods(periods) if periods is not None else self.parts[0].periods
        self.exact_gauge = all(p.exact_gauge for p in self.parts)
        self.description = " + ".join(p.description for p in self.parts)

    def components(self):
        cs = [p.components() for p in self.parts]
        return tuple(_summed([c[i] for c in cs]) for i in range(3))

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N) -> Scalar:
        return _summed([p.antiderivative(k, c, n) for p in self.parts])

    def relabel(self, pi: Any) -> VectorPotential:
        pi = as_perm(pi)
        if pi.is_identity:
            return self
        periods = tuple(self.periods[k] for k in pi.index)
        return SumPotential([p.relabel(pi) for p in self.parts], periods)


def _summed(fns: Sequence[Scalar]) -> Scalar:
    def f(x1, x2, x3):
        return sum(g(x1, x2, x3) for g in fns)

    return f


def curl_of(A: Sequence[Scalar]) -> Callable[[jax.Array], jax.Array]:
    """x ↦ ∇×A(x) for three JAX scalar callables (one forward-mode Jacobian), x of shape (3,)."""
    comps = tuple(A)

    def vec(x):
        return jnp.stack([jnp.asarray(c(x[0], x[1], x[2]), float) for c in comps])

    def curl(x):
        d = jax.jacfwd(vec)(x)  # d[i, j] = ∂_j A_i
        return jnp.stack([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])

    return curl


def _zero(x1, x2, x3):
    return jnp.zeros(jnp.broadcast_shapes(jnp.shape(x1), jnp.shape(x2), jnp.shape(x3)))


def _check_periods(periods: Sequence[float | None]) -> tuple:
    p = tuple(periods)
    if len(p) != 3:
        raise ValueError(f"periods must give one entry per axis (3); got {periods!r}")
    out = []
    for T in p:
        if T is None:
            out.append(None)
            continue
        T = float(T)
        if not (T > 0 and T < float("inf")):
            raise ValueError(f"a period must be a positive finite number or None; got {T!r}")
        out.append(T)
    return tuple(out)

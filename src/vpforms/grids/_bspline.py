"""A 3-D tensor-product B-spline in JAX: evaluation under jit/vmap/jacfwd, exact antiderivatives.

A :class:`TensorSpline` is

    s(x₁, x₂, x₃) = Σ_{abc} c_{abc} B¹_a(x₁) B²_b(x₂) B³_c(x₃),

with, per axis, a knot vector t (non-uniform allowed), a degree k and optionally a period T. At a
point only (k₁+1)(k₂+1)(k₃+1) terms are non-zero. Per axis:

* the knot interval t_i ≤ x < t_{i+1} is i = #{knots ≤ x} − 1 (``jnp.searchsorted(t, x,
  side="right") − 1`` written as one compare-and-sum, clipped to k ≤ i ≤ m − 1);
* the k+1 non-zero basis functions B_{i−k..i}(x) are polynomials on the cell: the Cox–de Boor
  recursion, unrolled for the static degree, is run once per cell at construction on polynomials
  in y = x − t_i (:func:`cell_polynomials`), and evaluation is a Horner step per basis function
  (:func:`basis_functions` is the same recursion on numbers, kept as the reference);
* the coefficient block c[i₁−k₁.., i₂−k₂.., i₃−k₃..] comes from ``jax.lax.dynamic_slice`` and
  is contracted with the three basis vectors.

Derivatives. A custom JVP maps ∂/∂x_a to the evaluation of the derivative orders α + e_a (all
orders of one level in one call, sharing the interval search, the basis and the block), so
``jax.jacfwd``/``jax.grad``/``jax.hessian`` to any depth give the exact derivatives of the cell
polynomials (Newton solves differentiate B = ∇×A, i.e. A twice, and the gauge pairs three times)
in a compact program, and ∂_i∂_j s is the same computation whichever order it is reached in.

Domain. A periodic axis wraps x into its base period [t_k, t_k + T) (``jnp.mod``). Outside a
non-periodic axis's range [t_k, t_m] the value — and every derivative — is NaN: never a silent
polynomial extrapolation (the integrator turns NaN into a per-particle failure status).

Fitting (:meth:`TensorSpline.interpolate`) uses ``scipy.interpolate.make_interp_spline`` axis by
axis (not-a-knot ends; on a periodic axis scipy's periodic knots and one dense collocation solve
for all columns at once); :meth:`TensorSpline.antiderivative` is exact — the
antiderivative of a degree-k B-spline along one axis is a B-spline of degree k + 1 there. Along a
periodic axis the antiderivative is not periodic; it is written as

    ∫_c^x s dx = μ·(x − c) + Q(x),    μ = (1/T)∫_{t_k}^{t_k+T} s dx,    Q periodic,

both parts exact (:class:`PeriodicAntiderivative`), so it stays accurate for any x, however many
periods a field line has gone round.

The spline is a JAX pytree (knots, cell polynomials and coefficients are leaves; degrees and
periods are static), so ``jax.jit(f)(spline, x)`` passes its data at run time instead of baking it
into the program; :func:`evaluate` is the same evaluation as a pure function of those arrays.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero
from scipy.interpolate import BSpline, make_interp_spline

from .. import _config  # noqa: F401  (float64)
from ._masked import masked_axis_fit
from ._quasi import knots_of, quasi_coefficients

__all__ = [
    "PeriodicAntiderivative", "TensorSpline", "basis_functions", "cell_polynomials", "evaluate",
]


# --------------------------------------------------------------------------------- one axis
def basis_functions(t_local: jax.Array, k: int, x: jax.Array) -> jax.Array:
    """The k+1 non-zero B-splines B_{i−k..i}(x) of degree k on the interval [t_i, t_{i+1}).

    ``t_local`` holds the 2k knots t_{i−k+1}, …, t_{i+k}. Cox–de Boor in the triangular form of
    Piegl & Tiller (A2.2), unrolled for the static k; every denominator t_{i+r+1} − t_{i+1−j+r}
    spans [t_i, t_{i+1}], so it is positive whenever that interval is non-empty.
    """
    N = [jnp.ones_like(x)]
    left = [None] * (k + 1)
    right = [None] * (k + 1)
    for j in range(1, k + 1):
        left[j] = x - t_local[k - j]  # x − t_{i+1−j}
        right[j] = t_local[k - 1 + j] - x  # t_{i+j} − x
        saved = jnp.zeros_like(x)
        for r in range(j):
            temp = N[r] / (right[r + 1] + left[j - r])
            N[r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        N.append(saved)
    return jnp.stack(N)


def cell_polynomials(t: np.ndarray, k: int) -> np.ndarray:
    """Per knot interval [t_i, t_{i+1}), i = k … m − 1, the power-basis coefficients of its k+1
    non-zero B-splines in y = x − t_i: P[i − k, r, p] is the coefficient of y^p in B_{i−k+r}.

    Cox–de Boor (Piegl & Tiller A2.2) on polynomials in y, for all intervals at once (arrays over
    the intervals; a factor (a ± y) shifts the coefficients): every denominator
    t_{i+r+1} − t_{i+1−j+r} spans [t_i, t_{i+1}], positive when it is non-empty (empty intervals
    are never selected by the evaluation; their rows stay zero)."""
    t = np.asarray(t, dtype=float)
    m = t.size - k - 1
    i = np.arange(k, m)

    def times_y(p):  # p(y)·y: degree ≤ k throughout, the top coefficient is never shifted out
        return np.concatenate([np.zeros((p.shape[0], 1)), p[:, :-1]], axis=1)

    N = [np.zeros((i.size, k + 1)) for _ in range(k + 1)]
    N[0][:, 0] = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):  # empty intervals: zeroed below
        for j in range(1, k + 1):
            saved = np.zeros((i.size, k + 1))
            for r in range(j):
                temp = N[r] / (t[i + r + 1] - t[i + 1 - j + r])[:, None]
                # N_r ← saved + (t_{i+r+1} − x)·temp;  saved ← (x − t_{i+1−j+r})·temp, with x = t_i + y
                N[r] = saved + (t[i + r + 1] - t[i])[:, None] * temp - times_y(temp)
                saved = (t[i] - t[i + 1 - j + r])[:, None] * temp + times_y(temp)
            N[j] = saved
    P = np.stack(N, axis=1)
    P[~(t[i] < t[i + 1])] = 0.0
    return P


def _axis(t: jax.Array, P: jax.Array, k: int, period: float | None, x: jax.Array,
          orders: Sequence[int]) -> tuple[dict[int, jax.Array], jax.Array]:
    """({n: the n-th derivatives of the k+1 non-zero basis functions at the scalar x} for n in
    ``orders``, index of the first coefficient) of one axis: the cell's polynomials P[i − k],
    differentiated exactly, at y = x − t_i."""
    m = t.shape[0] - k - 1  # number of coefficients
    x, xs = wrapped(t, k, period, x, jnp)
    # the knot interval t_i ≤ x < t_{i+1}, k ≤ i ≤ m − 1 (the right end belongs to the last one)
    i = jnp.clip(jnp.sum(t <= xs).astype(jnp.int32) - 1, k, m - 1)
    y = x - jax.lax.dynamic_slice(t, (i,), (1,))[0]
    Pi = jax.lax.dynamic_slice(P, (i - k, jnp.int32(0), jnp.int32(0)), (1, k + 1, k + 1))[0]
    return {n: basis_derivative(Pi, y, k, n) for n in sorted(set(orders))}, i - k


def wrapped(t, k: int, period: float | None, x, xp):
    """(x for the basis, x for the interval search) on one axis, ``xp`` = numpy or jax.numpy:
    wrapped into the base period [t_k, t_k + T) on a periodic axis; else x itself for the search
    and NaN outside [t_k, t_m] for the basis (the value and every derivative NaN off the grid)."""
    lo = t[k]
    if period is not None:
        x = lo + xp.mod(x - lo, period)
        return x, x
    return xp.where((x >= lo) & (x <= t[t.shape[0] - k - 1]), x, xp.nan), x


def basis_derivative(Pi, y, k: int, n: int):
    """d^n/dy^n of the k+1 cell polynomials Pi[..., r, p] (coefficient of y^p) at y, by Horner:
    Σ_{p ≥ n} p!/(p − n)! P_p y^(p−n); shape (..., k+1). NumPy or JAX alike (y broadcast against
    Pi[..., 0]); NaN where y is NaN (off the grid), also for a constant."""
    if n > k:  # the cell polynomials have degree k
        return 0.0 * Pi[..., 0] + 0.0 * y
    N = math.perm(k, n) * Pi[..., k]
    for p in range(k - 1, n - 1, -1):
        N = N * y + math.perm(p, n) * Pi[..., p]
    return N + 0.0 * y if n == k else N


def _contract(knots, cells, degrees, periods, orders, coefficients, x1, x2, x3) -> jax.Array:
    """(∂^α s for α in ``orders``) at the scalar point, shape (len(orders), *rest): one interval
    search, one basis computation per axis and one coefficient block for all of them."""
    xs = (x1, x2, x3)
    Ns, starts = [], []
    for a in range(3):
        N, s = _axis(knots[a], cells[a], degrees[a], periods[a], xs[a], [o[a] for o in orders])
        Ns.append(N)
        starts.append(s)
    rest = coefficients.shape[3:]
    block = jax.lax.dynamic_slice(
        coefficients, (*starts, *(jnp.zeros_like(starts[0]) for _ in rest)),
        (*(d + 1 for d in degrees), *rest))
    out, partial = [], {}
    for o in orders:
        # Σ_abc c_abc N¹_a N²_b N³_c, contracted one axis at a time (shared partial sums)
        if o[0] not in partial:
            partial[o[0]] = jnp.tensordot(Ns[0][o[0]], block, axes=(0, 0))
        v = jnp.tensordot(Ns[1][o[1]], partial[o[0]], axes=(0, 0))
        out.append(jnp.tensordot(Ns[2][o[2]], v, axes=(0, 0)))
    return jnp.stack(out)


#: one trace per (degrees, periods, orders, shapes): nested derivatives re-enter this many times
_contract_cached = jax.jit(_contract, static_argnums=(2, 3, 4))


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def _spline(static, knots, cells, coefficients, x1, x2, x3):
    """(∂^α s(x1, x2, x3) for α in orders), static = (degrees, periods, orders). Its JVP along
    x_a evaluates the orders α + e_a — all of them in one call — so jacfwd/grad to any depth
    evaluate exact derivatives of the cell polynomials in a compact program (no autodiff through
    the arithmetic; one call per derivative level)."""
    return _contract_cached(knots, cells, *static, coefficients, x1, x2, x3)


def _spline_jvp(static, primals, tangents):
    knots, cells, coefficients, x1, x2, x3 = primals
    _, _, dcoef, *dx = tangents
    degrees, periods, orders = static
    out = _spline(static, knots, cells, coefficients, x1, x2, x3)
    dirs = [a for a in range(3) if type(dx[a]) is not SymbolicZero]
    terms = []
    if dirs:
        def up(o, a):
            return tuple(v + (b == a) for b, v in enumerate(o))

        higher = tuple(sorted({up(o, a) for o in orders for a in dirs}))
        D = _spline((degrees, periods, higher), knots, cells, coefficients, x1, x2, x3)
        where = {o: n for n, o in enumerate(higher)}
        # d(∂^α s) = Σ_a ∂^(α+e_a) s dx_a
        terms.append(jnp.stack([sum(D[where[up(o, a)]] * dx[a] for a in dirs) for o in orders]))
    if type(dcoef) is not SymbolicZero:  # linear in the coefficients (knots: not differentiated)
        terms.append(_contract(knots, cells, degrees, periods, orders, dcoef, x1, x2, x3))
    return out, sum(terms) if terms else jnp.zeros_like(out)


_spline.defjvp(_spline_jvp, symbolic_zeros=True)


def evaluate(knots: Sequence[jax.Array], cells: Sequence[jax.Array], degrees: Sequence[int],
             periods: Sequence[float | None], coefficients: jax.Array, x1: Any, x2: Any, x3: Any,
             orders: Sequence[Sequence[int]] = ((0, 0, 0),)) -> jax.Array:
    """The tensor-product spline's partial derivatives ∂^α s, α in ``orders`` ((0, 0, 0): the
    value), at the scalar point (x1, x2, x3): a pure function of its data (knots,
    :func:`cell_polynomials` of each axis, coefficients), differentiable in x and in the
    coefficients, to any order.

    ``coefficients`` has shape (m₁, m₂, m₃, *rest); the result has shape
    (len(orders), *rest)."""
    static = (tuple(int(d) for d in degrees), tuple(periods),
              tuple(tuple(int(v) for v in o) for o in orders))
    x1, x2, x3 = (jnp.asarray(v, jnp.float64) for v in (x1, x2, x3))
    return _spline(static, tuple(knots), tuple(cells), coefficients, x1, x2, x3)


def _vectorised(fn, x1, x2, x3):
    """fn of scalars applied to broadcast arrays (vmap over the flattened points)."""
    x1, x2, x3 = (jnp.asarray(v, jnp.float64) for v in (x1, x2, x3))
    if x1.ndim == 0 and x2.ndim == 0 and x3.ndim == 0:
        return fn(x1, x2, x3)
    b1, b2, b3 = jnp.broadcast_arrays(x1, x2, x3)
    out = jax.vmap(fn)(b1.ravel(), b2.ravel(), b3.ravel())
    return out.reshape(b1.shape + out.shape[1:])


_DEGREE_NAMES = {0: "constant", 1: "linear", 2: "quadratic", 3: "cubic", 4: "quartic", 5: "quintic"}


def degree_name(k: int) -> str:
    return _DEGREE_NAMES.get(k, f"degree-{k}")


# --------------------------------------------------------------------------------- the spline
class TensorSpline:
    """A 3-D tensor-product B-spline s(x₁, x₂, x₃) (module docstring).

    Parameters
    ----------
    knots:
        Three non-decreasing knot vectors t (non-uniform allowed).
    degrees:
        Three degrees k ≥ 0 (fitted splines have k ≥ 3; an antiderivative raises one by 1).
    coefficients:
        Shape (m₁, m₂, m₃) with m_a = len(t_a) − k_a − 1.
    periods:
        Per axis the period T (the axis is periodic: x is wrapped into [t_k, t_k + T), which must
        be the base interval [t_k, t_m]), or None (outside [t_k, t_m] the spline is NaN).
    """

    def __init__(self, knots: Sequence[Any], degrees: Sequence[int], coefficients: Any,
                 periods: Sequence[float | None] = (None, None, None)):
        if len(knots) != 3 or len(degrees) != 3 or len(periods) != 3:
            raise ValueError("a TensorSpline needs three knot vectors, degrees and periods")
        c = np.asarray(coefficients, dtype=float)
        if c.ndim < 3:
            raise ValueError(f"coefficients must have shape (m1, m2, m3, *rest); got {c.shape}")
        ts, ks, Ts = [], [], []
        for a in range(3):
            t = np.asarray(knots[a], dtype=float)
            k = int(degrees[a])
            if isinstance(degrees[a], bool) or k != degrees[a] or k < 0:
                raise ValueError(f"axis {a}: the degree must be an integer ≥ 0; got {degrees[a]!r}")
            if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                raise ValueError(f"axis {a}: knots must be a finite non-decreasing 1-D array")
            m = t.size - k - 1
            if m < 1 or c.shape[a] != m:
                raise ValueError(
                    f"axis {a}: {t.size} knots of degree {k} need {max(m, 0)} coefficients; "
                    f"got {c.shape[a]}")
            if not t[k] < t[m]:
                raise ValueError(f"axis {a}: the base interval [t_k, t_m] is empty")
            T = periods[a]
            if T is not None:
                T = float(T)
                if not (0 < T < np.inf) or abs((t[m] - t[k]) - T) > 1e-12 * T:
                    raise ValueError(
                        f"axis {a}: period {T!r} must equal the base interval length "
                        f"t_m − t_k = {t[m] - t[k]!r}")
            ts.append(t)
            ks.append(k)
            Ts.append(T)
        self.knots: tuple[jax.Array, ...] = tuple(jnp.asarray(t) for t in ts)
        #: per axis the power-basis polynomials of the k+1 B-splines of every knot interval
        self.cells: tuple[jax.Array, ...] = tuple(
            jnp.asarray(cell_polynomials(t, k)) for t, k in zip(ts, ks))
        self.degrees: tuple[int, int, int] = tuple(ks)  # type: ignore[assignment]
        self.periods: tuple[float | None, ...] = tuple(Ts)
        self.coefficients: jax.Array = jnp.asarray(c)

    # -- pytree -----------------------------------------------------------------------------
    def tree_flatten(self):
        return (self.knots, self.cells, self.coefficients), (self.degrees, self.periods)

    @classmethod
    def tree_unflatten(cls, aux, children):
        obj = object.__new__(cls)
        obj.knots, obj.cells, obj.coefficients = tuple(children[0]), tuple(children[1]), children[2]
        obj.degrees, obj.periods = aux
        return obj

    # -- properties -------------------------------------------------------------------------
    @property
    def periodic(self) -> tuple[bool, bool, bool]:
        return tuple(T is not None for T in self.periods)  # type: ignore[return-value]

    @property
    def shape(self) -> tuple[int, ...]:
        """The number of coefficients per axis."""
        return tuple(self.coefficients.shape)

    @property
    def domain(self) -> tuple[tuple[float, float], ...]:
        """Per axis the base interval [t_k, t_m] (one period for a periodic axis)."""
        out = []
        for t, k in zip(self.knots, self.degrees):
            t = np.asarray(t)
            out.append((float(t[k]), float(t[t.size - k - 1])))
        return tuple(out)

    def __repr__(self) -> str:
        axes = ", ".join(
            f"{m} coeffs deg {k}{' periodic' if T is not None else ''}"
            for m, k, T in zip(self.shape, self.degrees, self.periods))
        return f"TensorSpline({axes})"

    # -- evaluation -------------------------------------------------------------------------
    def _scalar(self, x1, x2, x3):
        return evaluate(self.knots, self.cells, self.degrees, self.periods, self.coefficients,
                        x1, x2, x3)[0]

    def __call__(self, x1: Any, x2: Any, x3: Any) -> jax.Array:
        """s at (x1, x2, x3): scalars (traceable, differentiable), or broadcast arrays."""
        return _vectorised(self._scalar, x1, x2, x3)

    # -- fitting ----------------------------------------------------------------------------
    @classmethod
    def interpolate(cls, nodes: Sequence[Any], values: Any,
                    periodic: Sequence[bool | float | None] = (False, False, False),
                    degree: int | Sequence[int] = 3, mask: Any = None, fit: str = "interpolate") -> TensorSpline:
        """The spline that interpolates ``values`` (n₁, n₂, n₃) at the tensor grid of ``nodes``.

        Per axis ``periodic`` is False/None (not-a-knot ends), True (uniform nodes covering one
        period without its endpoint: T = n·Δx) or a number, the period T (nodes in [x₀, x₀ + T),
        endpoint excluded). Fitted axis by axis with ``scipy.interpolate.make_interp_spline``
        (``bc_type="periodic"`` on a periodic axis, with the first value appended at x₀ + T).

        ``mask`` (bool, the grid's shape): the nodes whose values count (elsewhere ``values`` may be
        NaN); every grid line is fitted on its runs of kept nodes only, and the coefficients no
        run touches are NaN (:mod:`vpforms.grids._masked`): a grid that follows a domain.

        ``fit``: "interpolate" (the above), or "quasi" — the local quasi-interpolant of the same
        spline space (:mod:`vpforms.grids._quasi`: each coefficient from the k + 1 samples nearest
        it, exact for polynomials of degree k, an error that stays near its cause; with a mask, NaN
        where a stencil holds a left-out node). It does not pass through the samples.
        """
        if fit not in ("interpolate", "quasi"):
            raise ValueError(f"fit must be 'interpolate' or 'quasi', not {fit!r}")
        degrees = (degree,) * 3 if np.ndim(degree) == 0 else tuple(degree)
        if len(nodes) != 3 or len(periodic) != 3 or len(degrees) != 3:
            raise ValueError("interpolate needs three node arrays, periodic flags and degrees")
        c = np.asarray(values, dtype=float)
        shape = tuple(np.size(n) for n in nodes)
        if c.shape != shape:
            raise ValueError(f"values must have the grid's shape {shape}; got {c.shape}")
        keep = None if mask is None else np.asarray(mask, dtype=bool)
        if keep is not None and keep.shape != shape:
            raise ValueError(f"mask must have the grid's shape {shape}; got {keep.shape}")
        if not np.all(np.isfinite(c if keep is None else c[keep])):
            raise ValueError("values must be finite" + ("" if keep is None else " at the kept nodes"))
        knots, periods = [], []
        if fit == "quasi":
            xs = [np.asarray(n_, dtype=float) for n_ in nodes]
            for a in range(3):
                k = degrees[a]
                if isinstance(k, bool) or int(k) != k or k < 3:
                    raise ValueError(f"axis {a}: a fitted spline needs an integer degree ≥ 3; got {k!r}")
                if xs[a].ndim != 1 or not np.all(np.isfinite(xs[a])) or np.any(np.diff(xs[a]) <= 0):
                    raise ValueError(f"axis {a}: nodes must be a finite strictly increasing 1-D array")
                if xs[a].size < int(k) + 1:
                    raise ValueError(f"axis {a}: a degree-{k} quasi-interpolant needs ≥ {int(k) + 1} nodes; got {xs[a].size}")
                periods.append(_period(periodic[a], xs[a], a))
                knots.append(knots_of(xs[a], int(k), periods[a]))
            coef = quasi_coefficients(xs, np.where(np.isfinite(c), c, 0.0), knots, degrees, periods, keep)
            return cls(knots, degrees, coef, periods)
        for a in range(3):
            k = degrees[a]
            if isinstance(k, bool) or int(k) != k or k < 3:
                raise ValueError(f"axis {a}: a fitted spline needs an integer degree ≥ 3; got {k!r}")
            k = int(k)
            x = np.asarray(nodes[a], dtype=float)
            if x.ndim != 1 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
                raise ValueError(f"axis {a}: nodes must be a finite strictly increasing 1-D array")
            T = _period(periodic[a], x, a)
            if keep is not None:
                t, c, keep = _masked_axis(x, T, c, keep, k, a)
                knots.append(t)
                periods.append(T)
                continue
            if T is None:
                if x.size < k + 1:
                    raise ValueError(f"axis {a}: a degree-{k} spline needs ≥ {k + 1} nodes; "
                                     f"got {x.size}")
                spl = make_interp_spline(x, c, k=k, axis=a)
            else:
                if x.size < k:
                    raise ValueError(f"axis {a}: a periodic degree-{k} spline needs ≥ {k} nodes "
                                     f"per period; got {x.size}")
                t, c = _periodic_interpolation(x, T, c, k, a)
                knots.append(t)
                periods.append(T)
                continue
            c = np.moveaxis(np.asarray(spl.c), 0, a)  # scipy keeps the spline axis first
            knots.append(np.asarray(spl.t))
            periods.append(T)
        return cls(knots, degrees, c, periods)

    # -- exact antiderivative ---------------------------------------------------------------
    def antiderivative(self, axis: int, c: float) -> TensorSpline | PeriodicAntiderivative:
        """χ(x) = ∫_c^{x_axis} s(…, ξ, …) dξ, exact: a TensorSpline of degree + 1 on ``axis``;
        on a periodic axis a :class:`PeriodicAntiderivative` μ·(x − c) + Q(x) (module docstring).

        On a non-periodic axis c must lie in the spline's range (ValueError otherwise)."""
        if axis not in (0, 1, 2):
            raise ValueError(f"axis must be 0, 1 or 2; got {axis!r}")
        c = float(c)
        t = np.asarray(self.knots[axis])
        k, T = self.degrees[axis], self.periods[axis]
        m = t.size - k - 1
        lo, hi = float(t[k]), float(t[m])
        # NaN coefficients (a grid that follows a domain, vpforms.grids._masked) count as 0 here:
        # χ stays a smooth function, and ∂χ/∂x_axis is the spline wherever the spline is defined
        coef = np.nan_to_num(np.moveaxis(np.asarray(self.coefficients), axis, 0), nan=0.0)
        F = BSpline(t, coef, k, extrapolate=False).antiderivative()
        t2, k2 = np.asarray(F.t), F.k
        d = np.asarray(F.c)[: t2.size - k2 - 1]  # scipy pads c to len(t)

        def at(coefs, x):  # the n-d spline along `axis` at one x: an array over the other axes
            return BSpline(t2, coefs, k2, extrapolate=True)(x)

        def build(coefs, knots_a, deg_a):
            kn = list(self.knots)
            kn[axis] = knots_a
            dg = list(self.degrees)
            dg[axis] = deg_a
            return TensorSpline(kn, dg, np.moveaxis(coefs, 0, axis), self.periods)

        if T is None:
            if not lo <= c <= hi:
                raise ValueError(
                    f"the antiderivative's base point c = {c!r} on axis {axis} is outside the "
                    f"spline's range [{lo!r}, {hi!r}]; choose c on the grid (e.g. the field's "
                    "origin at the grid's centre)")
            # Σ_a B_a = 1 on the range: subtracting χ(c) from every coefficient makes χ(c) = 0
            return build(d - at(d, c)[None], t2, k2)
        mu = (at(d, hi) - at(d, lo)) / (hi - lo)  # the mean over one period, per other-axes coeff
        # Greville abscissae ξ_a: Σ_a ξ_a B_a(x) = x, so F − μ(x − lo) has coefficients d − μ(ξ − lo)
        xi = np.array([t2[a + 1: a + k2 + 1].mean() for a in range(d.shape[0])])
        q = d - mu[None] * (xi - lo).reshape((-1,) + (1,) * (d.ndim - 1))
        cw = lo + float(np.mod(c - lo, T))
        q = q - at(q, cw)[None]  # Q(c) = 0, so χ(c) = 0
        Q = build(q, t2, k2)
        M = build(mu[None], np.array([lo, hi]), 0)  # μ as a spline constant along `axis`
        return PeriodicAntiderivative(Q, M, axis, c)


def _periodic_interpolation(x: np.ndarray, T: float, y: np.ndarray, k: int, axis: int
                            ) -> tuple[np.ndarray, np.ndarray]:
    """(knots, coefficients) of the periodic degree-k interpolant of y along ``axis`` at the n
    nodes x of one period: scipy's periodic knots (``make_interp_spline(bc_type="periodic")`` on
    one column), then one dense n×n solve for every column at once (scipy solves column by
    column). The m = n + k coefficients satisfy c_{n+j} = c_j, j < k, so the collocation matrix
    folds the columns j ≥ n onto j − n."""
    n = x.size
    xx = np.append(x, x[0] + T)
    t = np.asarray(make_interp_spline(xx, np.zeros(n + 1), k=k, bc_type="periodic").t)
    D = BSpline.design_matrix(x, t, k).toarray()  # (n, n + k): B_j(x_i)
    M = D[:, :n].copy()
    M[:, :k] += D[:, n:]  # c_{n+j} = c_j
    Y = np.moveaxis(y, axis, 0)
    c = np.linalg.solve(M, Y.reshape(n, -1)).reshape(Y.shape)
    c = np.concatenate([c, c[:k]], axis=0)  # the k wrapped coefficients
    return t, np.moveaxis(c, 0, axis)


def _masked_axis(x: np.ndarray, T: float | None, c: np.ndarray, keep: np.ndarray, k: int, axis: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One axis of the masked interpolation: (knots, coefficients with NaN where untouched, the
    kept mask of the coefficients for the next axis)."""
    n = x.size
    if T is None:
        t = np.asarray(make_interp_spline(x, np.zeros(n), k=k).t)

        def full(Y):
            return np.asarray(make_interp_spline(x, Y, k=k, axis=0).c)
    else:
        t = _periodic_interpolation(x, T, np.zeros((n, 1)), k, 0)[0]

        def full(Y):
            return _periodic_interpolation(x, T, Y, k, 0)[1]
    Y = np.moveaxis(c, axis, 0)
    K = np.moveaxis(keep, axis, 0)
    C = masked_axis_fit(x, t, k, T, Y.reshape(n, -1), K.reshape(n, -1), full)
    C = np.moveaxis(C.reshape((C.shape[0],) + Y.shape[1:]), 0, axis)
    return t, C, np.isfinite(C)


def _period(flag: bool | float | None, x: np.ndarray, axis: int) -> float | None:
    """The period of a periodic axis from its flag (True: uniform nodes, T = n·Δx; a number: T)."""
    if flag is None or flag is False:
        return None
    if flag is True:
        if x.size < 2:
            raise ValueError(f"axis {axis}: cannot infer a period from {x.size} node(s)")
        h = (x[-1] - x[0]) / (x.size - 1)
        if np.max(np.abs(np.diff(x) - h)) > 1e-10 * abs(h):
            raise ValueError(f"axis {axis}: periodic=True needs uniform nodes; give the period")
        return float(h * x.size)
    T = float(flag)
    if not 0 < T < np.inf:
        raise ValueError(f"axis {axis}: the period must be positive and finite; got {flag!r}")
    if x[-1] - x[0] >= T:
        raise ValueError(
            f"axis {axis}: periodic nodes must cover one period without its endpoint "
            f"(x[-1] − x[0] = {x[-1] - x[0]!r} ≥ T = {T!r})")
    return T


class PeriodicAntiderivative:
    """χ(x) = μ(x)·(x_axis − c) + Q(x), the exact antiderivative of a spline along a periodic axis.

    μ (a spline constant along ``axis``: the mean over one period) and Q (periodic along ``axis``,
    Q(c) = 0) are :class:`TensorSpline`; ∂χ/∂x_axis = μ + (s − μ) = s exactly, at any x."""

    def __init__(self, Q: TensorSpline, M: TensorSpline, axis: int, c: float):
        self.Q, self.M, self.axis, self.c = Q, M, int(axis), float(c)

    def tree_flatten(self):
        return (self.Q, self.M), (self.axis, self.c)

    @classmethod
    def tree_unflatten(cls, aux, children):
        return cls(children[0], children[1], *aux)

    def _scalar(self, x1, x2, x3):
        x = (x1, x2, x3)
        return (x[self.axis] - self.c) * self.M._scalar(x1, x2, x3) + self.Q._scalar(x1, x2, x3)

    def __call__(self, x1: Any, x2: Any, x3: Any) -> jax.Array:
        return _vectorised(self._scalar, x1, x2, x3)

    def __repr__(self) -> str:
        return f"PeriodicAntiderivative(axis={self.axis}, c={self.c!r}, Q={self.Q!r})"


jax.tree_util.register_pytree_node(TensorSpline, TensorSpline.tree_flatten,
                                   TensorSpline.tree_unflatten)
jax.tree_util.register_pytree_node(PeriodicAntiderivative, PeriodicAntiderivative.tree_flatten,
                                   PeriodicAntiderivative.tree_unflatten)

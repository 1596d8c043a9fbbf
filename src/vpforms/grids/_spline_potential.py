"""A vector potential given by three tensor-product splines: the exact-gauge VectorPotential.

The covariant components A₁, A₂, A₃ are :class:`~vpforms.grids._bspline.TensorSpline`; the field
is a = ∇×A (unit Jacobian), divergence free as a function everywhere (the divergence of a curl;
at rounding level in floating point). The gauge integrals χ_k = ∫_c^{x_k} A_k dx_k of the SE/DL
pairs (:mod:`vpforms._vecpot`) are exact splines (:meth:`TensorSpline.antiderivative`), so the
pairs reproduce ∇×A to rounding — ``exact_gauge = True``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._quadrature import DEFAULT_N
from .._vecpot import VectorPotential
from ._bspline import TensorSpline, degree_name
from ._evaluate_np import curl_np

__all__ = ["SplinePotential"]

#: points per evaluation chunk (one compiled shape; bounds the vmap's memory)
_CHUNK = 4096


class SplinePotential(VectorPotential):
    """A = (A₁, A₂, A₃), three :class:`TensorSpline` (covariant components in the coordinates of
    the field: (u, φ, Z) of :mod:`vpforms.toroidal`, or Cartesian (x, y, z)).

    Parameters
    ----------
    splines:
        Three TensorSplines; along each axis they must agree on the period.
    description:
        One line for ``Field.potential_method``.
    """

    exact_gauge = True
    #: per component None (the spline), or the coefficients (a₀, a₁, a₂, a₃) of an affine function
    #: a₀ + a₁x₁ + a₂x₂ + a₃x₃ that the component *is* (its spline interpolates it, to rounding):
    #: then :meth:`components` and :meth:`antiderivative` use the affine function itself, exactly
    #: and without spline evaluations (the φ-time potential (0, K, −v), :mod:`vpforms.phitime`)
    affine: tuple = (None, None, None)

    def __init__(self, splines: Sequence[TensorSpline], description: str = ""):
        sp = tuple(splines)
        if len(sp) != 3 or not all(isinstance(s, TensorSpline) for s in sp):
            raise TypeError("a SplinePotential needs three TensorSplines")
        for a in range(3):
            Ts = {s.periods[a] for s in sp}
            if len(Ts) != 1:
                raise ValueError(f"the three splines disagree on the period of axis {a}: {Ts}")
        self.splines = sp
        self.periods = sp[0].periods
        self.description = description or "spline of A"
        self._anti: dict[tuple[int, float], Any] = {}

    # -- the VectorPotential contract -------------------------------------------------------
    def components(self):
        return tuple(s if a is None else _affine_callable(a) for s, a in zip(self.splines, self.affine))

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N):
        """χ_k = ∫_c^{x_k} A_k dx_k, exact (a spline; on a periodic axis μ·(x_k − c) + Q; an
        :attr:`affine` component's own antiderivative); ``n`` is ignored. Raises ValueError if c is
        off the grid on a non-periodic axis."""
        key = (int(k), float(c))
        if key not in self._anti:
            a = self.affine[k]
            self._anti[key] = (self.splines[k].antiderivative(k, float(c)) if a is None
                               else _affine_callable(a, k, float(c)))
        return self._anti[key]

    def __call__(self, x: Any) -> jax.Array:
        """A(x) for a point x of shape (3,) (traceable), or points (..., 3) → (..., 3)."""
        if isinstance(x, jax.core.Tracer) or np.ndim(x) == 1:
            x = jnp.asarray(x, float)
            if x.ndim == 1:
                return jnp.stack([s(x[0], x[1], x[2]) for s in self.splines])
            return _values_at(self.splines, x.reshape(-1, 3)).reshape(x.shape)
        return chunked(_values_at, self.splines, x)  # concrete points: numpy, in chunks

    def curl(self, x: Any) -> np.ndarray:
        """a = ∇×A (contravariant, unit Jacobian) at concrete points (..., 3) → (..., 3), NumPy:
        nothing compiled, whatever the grid's shape (:mod:`._evaluate_np`; a grid search builds a
        new shape every round)."""
        return curl_np(self.splines, x)

    # -- the grid ---------------------------------------------------------------------------
    @property
    def grid_box(self) -> tuple[tuple[float, float], ...]:
        """Per axis the covered range (the intersection over the components; one period
        [x₀, x₀ + T] on a periodic axis)."""
        doms = [s.domain for s in self.splines]
        return tuple((max(d[a][0] for d in doms), min(d[a][1] for d in doms)) for a in range(3))

    @property
    def center(self) -> tuple[float, float, float]:
        """The centre of :attr:`grid_box` (a good gauge origin for ``Field``)."""
        return tuple(0.5 * (lo + hi) for lo, hi in self.grid_box)  # type: ignore[return-value]

    def contains(self, points: Any) -> np.ndarray:
        """Whether each point (shape (3,) or (N, 3)) is covered: in range on every non-periodic
        axis (a periodic axis covers every x)."""
        p = np.asarray(points, dtype=float)
        if p.shape[-1:] != (3,):
            raise ValueError(f"points must have shape (3,) or (N, 3); got {p.shape}")
        ok = np.all(np.isfinite(p), axis=-1)
        for a, (lo, hi) in enumerate(self.grid_box):
            if self.periods[a] is None:
                ok &= (p[..., a] >= lo) & (p[..., a] <= hi)
        return ok

    def inside(self, x: Any) -> Any:
        """JAX predicate for one point x (3,): in range on every non-periodic axis."""
        ok = jnp.all(jnp.isfinite(x))
        for a, (lo, hi) in enumerate(self.grid_box):
            if self.periods[a] is None:
                ok = ok & (x[a] >= lo) & (x[a] <= hi)
        return ok

    def check_covers(self, points: Any, what: str = "point",
                     names: Sequence[str] = ("x1", "x2", "x3"), note: str = "") -> None:
        """ValueError naming the first point (shape (3,) or (N, 3)) the grid does not cover and
        the grid's ranges (``note`` is appended to the message)."""
        p = np.asarray(points, dtype=float)
        ok = np.atleast_1d(self.contains(p))
        if np.all(ok):
            return
        p2 = np.atleast_2d(p)
        i = int(np.flatnonzero(~ok)[0])
        ranges = ", ".join(
            f"{n} ∈ [{lo:.6g}, {hi:.6g}]" + (" (periodic)" if T is not None else "")
            for n, (lo, hi), T in zip(names, self.grid_box, self.periods))
        where = f" (index {i} of {len(p2)})" if p.ndim == 2 else ""
        raise ValueError(
            f"the {what} {tuple(float(v) for v in p2[i])}{where} is outside the grid of the "
            f"{self.description}: {ranges}{note}")

    # -- constructors -----------------------------------------------------------------------
    @classmethod
    def from_samples(cls, nodes: Sequence[Any], values: Any,
                     periodic: Sequence[bool | float | None] = (False, True, False),
                     degree: int = 3, description: str = "", mask: Any = None,
                     affine: Sequence[Any] = (None, None, None), fit: str = "interpolate") -> SplinePotential:
        """The interpolating splines of samples A_i at the tensor grid ``nodes`` (where ``mask``
        is given, on its kept nodes only: :meth:`TensorSpline.interpolate`).

        ``values`` has shape (3, n₁, n₂, n₃) (covariant components); ``periodic`` per axis as in
        :meth:`TensorSpline.interpolate` (True: uniform nodes, one period without the endpoint;
        a number: the period). ``affine``: per component None, or the (a₀, a₁, a₂, a₃) of an affine
        function the component is (zero slope along a periodic axis): its spline is written down
        instead of fitted — the interpolant of an affine function is itself, with the Greville
        abscissae as coefficients — and :attr:`affine` is set (its ``values`` are ignored). ``fit``:
        "interpolate" or "quasi" (:meth:`TensorSpline.interpolate`)."""
        v = np.asarray(values, dtype=float)
        shape = tuple(np.size(n) for n in nodes)
        if v.shape != (3, *shape):
            raise ValueError(f"values must have shape (3, *grid) = {(3, *shape)}; got {v.shape}")
        affine = tuple(None if a is None else tuple(float(c) for c in a) for a in affine)
        fitted = [i for i in range(3) if affine[i] is None]
        if not fitted:
            raise ValueError("at least one component must be fitted (all three are affine)")
        splines = [TensorSpline.interpolate(nodes, v[i], periodic, degree, mask, fit) if i in fitted else None
                   for i in range(3)]
        ref = splines[fitted[0]]
        for i in range(3):
            if splines[i] is None:
                splines[i] = _affine_spline(ref, affine[i])
        # the three components share their knot vectors (one object each: one constant under jit)
        for s in splines:
            s.knots, s.cells = ref.knots, ref.cells
        desc = description or (
            f"{degree_name(degree)} spline of A on a {'×'.join(map(str, shape))} grid")
        out = cls(splines, desc)
        if any(a is not None for a in affine):
            out.affine = affine
        return out

    @classmethod
    def from_potential(cls, A: VectorPotential | Callable[[Any], Any], nodes: Sequence[Any],
                       periodic: Sequence[bool | float | None] = (False, True, False),
                       degree: int = 3, description: str = "") -> SplinePotential:
        """Sample a vector potential (a :class:`VectorPotential` or a JAX function of a point of
        shape (3,)) on the tensor grid ``nodes`` (vectorised) and interpolate.

        A periodic flag True takes the period from ``A.periods`` where A has one."""
        grids = [np.asarray(n, dtype=float) for n in nodes]
        per = list(periodic)
        if isinstance(A, VectorPotential):
            for a in range(3):
                if per[a] is True and A.periods[a] is not None:
                    per[a] = A.periods[a]
        values = sample_on_grid(A, grids)
        return cls.from_samples(grids, values, per, degree, description)


def _affine_spline(like: TensorSpline, a: Sequence[float]) -> TensorSpline:
    """The spline a₀ + a₁x₁ + a₂x₂ + a₃x₃ on the knots of ``like``: x_i = Σ_j ξ_j B_j(x_i) with the
    Greville abscissae ξ_j = (t_{j+1} + … + t_{j+k})/k (Marsden's identity), so the coefficients are
    a₀ + Σ a_i ξ^(i) — the interpolant of the affine function, without a fit."""
    c = np.full(like.shape, float(a[0]))
    for i in range(3):
        if not a[i + 1]:
            continue
        if like.periods[i] is not None:
            raise ValueError(f"an affine component cannot grow along the periodic axis {i}")
        t, k = np.asarray(like.knots[i]), like.degrees[i]
        xi = np.array([t[j + 1: j + k + 1].mean() for j in range(like.shape[i])]) if k else t[:-1]
        c = c + a[i + 1] * xi.reshape([-1 if b == i else 1 for b in range(3)])
    return TensorSpline(like.knots, like.degrees, c, like.periods)


def affine_value(a: Sequence[float], x: Sequence[Any]) -> Any:
    """a₀ + a₁x₁ + a₂x₂ + a₃x₃ (JAX arrays or SymPy symbols; zero terms left out)."""
    return sum((a[i + 1] * x[i] for i in range(3) if a[i + 1]), a[0])


def affine_antiderivative(a: Sequence[float], k: int, x: Sequence[Any], c: Any) -> Any:
    """∫_c^{x_k} (a₀ + a·x) dx_k = (a₀ + Σ_{i≠k} a_i x_i)(x_k − c) + a_k (x_k² − c²)/2 (JAX or
    SymPy; the one formula of the JAX potential and of the generated C)."""
    rest = sum((a[i + 1] * x[i] for i in range(3) if i != k and a[i + 1]), a[0])
    return rest * (x[k] - c) + (a[k + 1] * (x[k] ** 2 - c**2) / 2 if a[k + 1] else 0)


def _affine_callable(a: Sequence[float], k: int | None = None, c: float = 0.0) -> Callable:
    """The affine component a (k None) or its antiderivative along axis k from c, as f(x1, x2, x3)."""
    a = tuple(float(t) for t in a)

    def f(x1, x2, x3):
        x = jnp.broadcast_arrays(*(jnp.asarray(t, float) for t in (x1, x2, x3)))
        out = affine_value(a, x) if k is None else affine_antiderivative(a, k, x, c)
        return out + jnp.zeros_like(x[0])

    return f


@jax.jit
def _values_at(splines, pts):
    return jax.vmap(lambda p: jnp.stack([s(p[0], p[1], p[2]) for s in splines]))(pts)


def chunked(fn: Callable[[Any, jax.Array], jax.Array], data: Any, x: Any) -> np.ndarray:
    """fn(data, points) for points (..., 3), evaluated in padded chunks of ``_CHUNK`` points (one
    compiled shape whatever the number of points); numpy out, shape (..., 3)."""
    p = np.asarray(x, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"points must have shape (..., 3); got {p.shape}")
    flat = p.reshape(-1, 3)
    n = len(flat)
    out = []
    for i in range(0, max(n, 1), _CHUNK):
        q = flat[i: i + _CHUNK]
        pad = _CHUNK - len(q)
        q = np.concatenate([q, np.repeat(q[-1:] if len(q) else np.zeros((1, 3)), pad, axis=0)])
        out.append(np.asarray(fn(data, jnp.asarray(q)))[: _CHUNK - pad])
    return np.concatenate(out).reshape(p.shape[:-1] + out[0].shape[1:])


@functools.partial(jax.jit, static_argnums=0)
def _apply(A, pts):
    return jax.vmap(lambda q: jnp.asarray(A(q), float))(pts)


def sample_on_grid(A: Callable[[Any], Any], nodes: Sequence[np.ndarray]) -> np.ndarray:
    """A(x) (x of shape (3,) → (3,)) at every node of a tensor grid: shape (3, n₁, n₂, n₃)."""
    mesh = np.meshgrid(*nodes, indexing="ij")
    pts = np.stack([m.ravel() for m in mesh], axis=-1)
    try:  # A as a static argument: one compilation per A, whatever the grid
        hash(A)
        fn = _apply
    except TypeError:
        local = jax.jit(jax.vmap(lambda q: jnp.asarray(A(q), float)))

        def fn(_, q):
            return local(q)
    out = chunked(fn, A, pts)
    if out.shape != (len(pts), 3):
        raise ValueError(f"A must map a point of shape (3,) to shape (3,); got {out.shape[1:]}")
    return np.moveaxis(out.reshape(*mesh[0].shape, 3), -1, 0)

"""Coils as smooth closed curves integrated by their quadrature rule — simsopt's ``BiotSavart`` (issue #38).

A closed curve γ(θ), θ ∈ [0, 1), carrying the current I has, by the Biot–Savart law,

    A(x) = (μ0 I/4π) ∮ γ'(θ) dθ / |x − γ(θ)|,     B(x) = (μ0 I/4π) ∮ γ'(θ) × (x − γ(θ)) dθ / |x − γ(θ)|³.

On n equally spaced points θ_k = k/n the trapezoidal rule — exponentially accurate for a smooth
periodic integrand, at a rate set by the distance to the curve over the point spacing — gives the
*current elements* w_k = I γ'(θ_k)/n at γ_k = γ(θ_k), and

    A(x) = (μ0/4π) Σ_k w_k / |x − γ_k|,     B(x) = (μ0/4π) Σ_k w_k × (x − γ_k) / |x − γ_k|³.

B is exactly ∇×A of the sum (∇(1/r) × w = w × r/r³ term by term), so a field built from this A is
exactly divergence free, and B is simsopt's ``BiotSavart`` on the same curves and quadrature points
to rounding: the rule simsopt uses (``biot_savart_kernel``), not an approximation of it. Compared
with a polyline through the same points (:class:`~vpforms.coils.CoilSet`, Hanson–Hirshman
segments), whose field differs from the smooth curve's by O(1/n²) (W7-X at simsopt's 96 points:
4e-4 of max |B| near the axis), the quadrature's error near the plasma is ≈ 1e-6 (simsopt's own
estimate there, stored with the device data).

Evaluation shares the segments' machinery (:mod:`vpforms.coils._segments`): sums over chunks of
elements (``lax.scan``), batches of points, derivatives in x as sums of the kernel's derivatives —
bounded memory for any number of elements, JAX-traceable and differentiable.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401  (float64)
from .._vecpot import VectorPotential
from ._coilset import _FLIP, _finite_scalar, _points, _rotation_z, evaluate_on_host
from ._segments import _MU0_4PI, _POINTS_CHUNK, chunked, segment_chunk, sum_over_points

__all__ = ["QuadratureCoils", "QuadraturePotential"]


def _element_kernel(with_A: bool, with_B: bool):
    """kernel(x, (γ (3, S), w (3, S))): [A, B] of one chunk of current elements at x (3,)."""

    def kernel(x, chunk):
        g, w = chunk
        d0, d1, d2 = x[0] - g[0], x[1] - g[1], x[2] - g[2]  # x − γ_k
        inv = 1.0 / jnp.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        out = []
        if with_A:
            out.append(_MU0_4PI * (w @ inv))  # (μ0/4π) Σ w_k / r_k
        if with_B:
            inv3 = inv * inv * inv
            c = jnp.stack([w[1] * d2 - w[2] * d1, w[2] * d0 - w[0] * d2, w[0] * d1 - w[1] * d0])  # w × (x − γ)
            out.append(_MU0_4PI * (c @ inv3))
        return out[0] if len(out) == 1 else jnp.stack(out)

    return kernel


_KERNELS = {(a, b): _element_kernel(a, b) for a, b in ((True, False), (False, True), (True, True))}


@partial(jax.jit, static_argnums=(3, 4, 5))
def _evaluate(points, gamma, weights, with_A, with_B, size):
    S = gamma.shape[0]
    if points.ndim == 2:  # the batch of points is ours: larger chunks (as the segments do)
        size = max(size, _POINTS_CHUNK)
    size = min(size, S)
    # padding: elements of zero weight 10⁶ m away, exactly 0 with finite derivatives
    chunks = chunked((gamma.T, weights.T), (jnp.asarray([[1e6], [0.0], [0.0]]), jnp.zeros((3, 1))), size)
    return sum_over_points(_KERNELS[(with_A, with_B)], points, chunks, size)


class QuadratureCoils:
    """Closed curves with currents, as current elements (γ_k, w_k = I γ'(θ_k)/n): module docstring.

    Parameters
    ----------
    points, tangents : array_like, shape (K, n, 3) or sequences of (n_c, 3) arrays
        Per coil the curve's points γ(θ_k) (m) and derivatives γ'(θ_k) = dγ/dθ (m per unit θ) at the
        n_c quadrature points θ_k = k/n_c of θ ∈ [0, 1).
    currents : sequence of float
        One current per coil (A), finite.
    nfp : int
        The number of field periods the set is meant to have (a description, not checked).
    stellsym : bool
        Whether the set is meant to be stellarator symmetric (a description, not checked).
    names : sequence of str, optional
        A name per coil.

    Notes
    -----
    ``B(x)`` and ``A(x)`` take a point (3,) or points (N, 3) in metres and return tesla and
    tesla-metres of that shape (JAX-traceable); :meth:`potential` is A as a
    :class:`QuadraturePotential` for :func:`vpforms.toroidal.toroidal_field` and the grids;
    ``points_per_coil`` are the γ_k (e.g. to test that a wire stays clear of a grid or domain).
    """

    def __init__(self, points: Any, tangents: Any, currents: Sequence[float], *, nfp: int = 1,
                 stellsym: bool = False, names: Sequence[str] | None = None):
        pts = [np.array(p, dtype=float) for p in points]
        tan = [np.array(t, dtype=float) for t in tangents]
        cur = [_finite_scalar(c, f"coil {k} current") for k, c in enumerate(currents)]
        if not pts or not (len(pts) == len(tan) == len(cur)):
            raise ValueError(f"need as many coils' points, tangents and currents (≥ 1); got {len(pts)}, "
                             f"{len(tan)}, {len(cur)}")
        for k, (p, t) in enumerate(zip(pts, tan)):
            if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 3 or t.shape != p.shape:
                raise ValueError(f"coil {k}: points and tangents must both have shape (n ≥ 3, 3); got "
                                 f"{p.shape} and {t.shape}")
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(t))):
                raise ValueError(f"coil {k}: points and tangents must be finite")
        if isinstance(nfp, bool) or not isinstance(nfp, (int, np.integer)) or nfp < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        self.points_per_coil = tuple(pts)
        self.currents = tuple(cur)
        self.names = tuple(names) if names is not None else ("",) * len(pts)
        self.nfp, self.stellsym = int(nfp), bool(stellsym)
        gamma = np.concatenate(pts)
        weights = np.concatenate([I * t / len(t) for I, t in zip(cur, tan)])  # w_k = I γ'(θ_k)/n
        self._elements = (jnp.asarray(gamma), jnp.asarray(weights))

    @classmethod
    def from_symmetry(cls, points: Sequence[Any], tangents: Sequence[Any], currents: Sequence[float], nfp: int,
                      stellsym: bool = False, names: Sequence[str] | None = None) -> QuadratureCoils:
        """The base curves repeated over the nfp periods (and mirrored, current reversed), in the
        order and with the signs of :meth:`vpforms.coils.CoilSet.from_symmetry` (simsopt's
        ``coils_via_symmetries``): points and tangents are both rotated (and flipped)."""
        names = list(names) if names is not None else [""] * len(points)
        P, T, I, N = [], [], [], []
        for k in range(int(nfp)):
            M = _rotation_z(2 * np.pi * k / nfp)
            for mats, sign in ((M, 1.0),) + (((M @ _FLIP), -1.0),) * bool(stellsym):
                P += [np.asarray(p, float) @ mats.T for p in points]
                T += [np.asarray(t, float) @ mats.T for t in tangents]
                I += [sign * float(c) for c in currents]
                N += names
        return cls(P, T, I, nfp=int(nfp), stellsym=bool(stellsym), names=N)

    def elements(self) -> tuple[jax.Array, jax.Array]:
        """(γ (K, 3), w (K, 3)): every current element of every coil, stacked."""
        return self._elements

    def B(self, x: Any) -> jax.Array:
        """B (T) at x (m) of shape (3,) or (N, 3), the same shape."""
        return _evaluate(_points(x), *self._elements, False, True, segment_chunk())

    def A(self, x: Any) -> jax.Array:
        """A (T·m, ∇×A = B exactly) at x (m) of shape (3,) or (N, 3), the same shape."""
        return _evaluate(_points(x), *self._elements, True, False, segment_chunk())

    def evaluate(self, x: Any, what: str = "B", *, backend: str = "auto") -> np.ndarray:
        """B (``what="B"``, T) or A (``"A"``, T·m) at many points x (m), (3,) or (N, 3), as NumPy:
        natively where a C compiler is found (generated C, OpenMP over the points, O(N + K)
        memory: :mod:`vpforms.backends.native.biot_savart`), else (or with ``backend="jax"``) by
        :meth:`B` / :meth:`A`; as :meth:`vpforms.coils.CoilSet.evaluate`."""
        return evaluate_on_host(self, x, what, backend)

    def potential(self) -> QuadraturePotential:
        """A as a Cartesian :class:`QuadraturePotential`."""
        return QuadraturePotential(self)

    def __len__(self) -> int:
        return len(self.points_per_coil)

    def __repr__(self) -> str:
        return (f"QuadratureCoils({len(self)} coils, {int(self._elements[0].shape[0])} current elements, "
                f"nfp={self.nfp}, stellsym={self.stellsym})")


class QuadraturePotential(VectorPotential):
    """The Cartesian A(x) of :class:`QuadratureCoils` as a :class:`~vpforms._vecpot.VectorPotential`
    (JAX backend: the native backend has no kernel for current elements)."""

    def __init__(self, coils: QuadratureCoils):
        if not isinstance(coils, QuadratureCoils):
            raise TypeError(f"QuadraturePotential needs QuadratureCoils; got {type(coils).__name__}")
        self.coils = coils
        self.periods = (None, None, None)
        self.description = (f"Biot–Savart vector potential of {len(coils)} coils by their quadrature "
                            f"({int(coils.elements()[0].shape[0])} current elements)")

    def __call__(self, x: Any) -> jax.Array:
        return self.coils.A(x)

    def components(self):
        def comp(i):
            def Ai(x1, x2, x3):
                x = jnp.stack(jnp.broadcast_arrays(*(jnp.asarray(v, float) for v in (x1, x2, x3))), axis=-1)
                return self.coils.A(x.reshape(-1, 3))[:, i].reshape(x.shape[:-1]) if x.ndim > 1 else self.coils.A(x)[i]

            Ai.__name__ = ("A_x", "A_y", "A_z")[i]
            return Ai

        return tuple(comp(i) for i in range(3))

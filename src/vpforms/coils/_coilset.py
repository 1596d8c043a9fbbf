"""Filamentary coils: :class:`Coil` (a closed polyline with a current) and :class:`CoilSet`.

A coil's field is the sum of the Hanson–Hirshman fields of its straight segments
(:mod:`vpforms.coils._segments`); a coil set stacks the segments of all its coils into three arrays
(starts, ends, currents) so that B and A at N points are one vectorised expression over N × S pairs.

Symmetries (:meth:`CoilSet.from_symmetry`): field periodicity is the rotation by 2π/nfp about the
z axis; stellarator symmetry is the map (R, φ, Z) → (R, −φ, −Z), in Cartesian coordinates
(x, y, z) → (x, −y, −z), the rotation by π about the x axis. A current distribution rotated by a
proper rotation M carries its field along, B'(Mx) = M B(x), which gives B_R even and B_φ, B_Z odd
under the map; stellarator symmetry asks for the opposite parities,

    B_R(R, −φ, −Z) = −B_R(R, φ, Z),   B_φ(R, −φ, −Z) = B_φ(R, φ, Z),   B_Z(R, −φ, −Z) = B_Z(R, φ, Z),

so the mirror image of a coil carries the reversed current, −B'(Mx) = −M B(x).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401  (float64)
from .._vecpot import VectorPotential
from ._segments import segments_A, segments_B

__all__ = ["Coil", "CoilPotential", "CoilSet"]


def _finite_scalar(value: Any, what: str) -> float:
    if isinstance(value, bool) or np.ndim(value) != 0:
        raise ValueError(f"{what} must be a real scalar; got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a real number; got {value!r}") from None
    if not np.isfinite(v):
        raise ValueError(f"{what} must be finite; got {v!r}")
    return v


class Coil:
    """A closed polyline of points x_0, …, x_{M−1} (m) carrying the current I (A).

    The polyline is closed automatically: its M segments are x_k → x_{k+1} and x_{M−1} → x_0. A last
    point exactly equal to the first (the MAKEGRID convention) is dropped, so either form gives the
    same coil. The current flows in the order of the points.

    Parameters
    ----------
    points : array_like, shape (M, 3)
        Vertices in Cartesian coordinates; at least 3 distinct points, all finite, no two
        consecutive points equal (zero-length segments).
    current : float
        Current in ampere (finite).
    group : int, optional
        The MAKEGRID group number (default 1).
    name : str, optional
        A single token without whitespace (MAKEGRID writes it after the group number).

    Raises
    ------
    ValueError
        Naming what is wrong: shape, non-finite coordinates or current, too few distinct points,
        a zero-length segment, a bad group or name.
    """

    __slots__ = ("current", "group", "name", "points")

    def __init__(self, points: Any, current: float, group: int = 1, name: str = ""):
        try:
            pts = np.array(points, dtype=float)
        except (TypeError, ValueError):
            raise ValueError("coil points must be an array of numbers of shape (M, 3)") from None
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"coil points must have shape (M, 3); got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            bad = int(np.argwhere(~np.isfinite(pts))[0, 0])
            raise ValueError(f"coil point {bad} is not finite: {pts[bad].tolist()}")
        if pts.shape[0] > 1 and np.array_equal(pts[0], pts[-1]):
            pts = pts[:-1]  # an explicit closing point
        if len(np.unique(pts, axis=0)) < 3:
            raise ValueError(f"a coil needs at least 3 distinct points; got {len(np.unique(pts, axis=0))}")
        steps = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
        if np.any(steps == 0):
            k = int(np.argmin(steps))
            raise ValueError(f"zero-length segment: coil points {k} and {(k + 1) % len(pts)} are equal ({pts[k].tolist()})")
        if isinstance(group, bool) or not isinstance(group, (int, np.integer)):
            raise ValueError(f"coil group must be an integer; got {group!r}")  # noqa: TRY004  (bad input: ValueError)
        if not isinstance(name, str) or (name and len(name.split()) != 1) or name != name.strip():
            raise ValueError(f"coil name must be a single token without whitespace; got {name!r}")
        pts.setflags(write=False)
        self.points = pts
        self.current = _finite_scalar(current, "coil current")
        self.group = int(group)
        self.name = name

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """(starts, ends), each (M, 3): the segments x_k → x_{k+1 mod M}."""
        return self.points, np.roll(self.points, -1, axis=0)

    def with_current(self, current: float) -> Coil:
        """The same polyline with another current."""
        return Coil(self.points, current, self.group, self.name)

    def __len__(self) -> int:
        return len(self.points)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Coil):
            return NotImplemented
        return (np.array_equal(self.points, other.points) and self.current == other.current
                and self.group == other.group and self.name == other.name)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        nm = f", name={self.name!r}" if self.name else ""
        return f"Coil({len(self.points)} points, current={self.current!r} A, group={self.group}{nm})"


def _rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: stellarator symmetry (R, φ, Z) → (R, −φ, −Z): (x, y, z) → (x, −y, −z)
_FLIP = np.diag([1.0, -1.0, -1.0])


class CoilSet:
    """A set of filamentary coils; B and A at points by the Hanson–Hirshman segment formulas.

    Parameters
    ----------
    coils : sequence of Coil
        At least one coil.
    nfp : int, optional
        Number of field periods the set is meant to have (a description: not checked; default 1).
    stellsym : bool, optional
        Whether the set is meant to be stellarator symmetric (a description; default False).

    Notes
    -----
    ``B(x)`` and ``A(x)`` accept a point of shape (3,) or points (N, 3) (m) and return B (T) and
    A (T·m) of the same shape; they are JAX-traceable (jit, vmap, jacfwd). ``A`` is a Cartesian
    vector potential with ∇×A = B, e.g. for :class:`vpforms.toroidal.ToroidalPotential`.
    :meth:`evaluate` gives either at many concrete points as NumPy, natively (generated C, bounded
    memory for any number of segments).
    """

    def __init__(self, coils: Iterable[Coil], nfp: int = 1, stellsym: bool = False):
        coils = tuple(coils)
        if not coils:
            raise ValueError("a coil set needs at least one coil")
        for k, c in enumerate(coils):
            if not isinstance(c, Coil):
                raise ValueError(f"coil {k} is not a Coil: {type(c).__name__}")  # noqa: TRY004
        if isinstance(nfp, bool) or not isinstance(nfp, (int, np.integer)) or nfp < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        if not isinstance(stellsym, (bool, np.bool_)):
            raise ValueError(f"stellsym must be True or False; got {stellsym!r}")  # noqa: TRY004
        self.coils: tuple[Coil, ...] = coils
        self.nfp = int(nfp)
        self.stellsym = bool(stellsym)
        starts, ends = zip(*(c.segments() for c in coils))
        currents = [np.full(len(c), c.current) for c in coils]
        self._segments = (jnp.asarray(np.concatenate(starts)), jnp.asarray(np.concatenate(ends)),
                          jnp.asarray(np.concatenate(currents)))

    @classmethod
    def from_symmetry(cls, base_coils: Sequence[Coil], nfp: int, stellsym: bool = False) -> CoilSet:
        """The coil set of ``base_coils`` repeated over the nfp field periods (and mirrored).

        For k = 0, …, nfp−1 every base coil rotated by 2πk/nfp about the z axis; with ``stellsym``
        also its stellarator-symmetric image (R, φ, Z) → (R, −φ, −Z), i.e. (x, y, z) → (x, −y, −z),
        with the current reversed (module docstring), rotated likewise. Order: for each k, the
        rotated base coils, then their rotated images. The base coils are those of one period (of
        one half-period with ``stellsym``): a base coil that is itself symmetric would be repeated.
        """
        base = tuple(base_coils)
        if not base or not all(isinstance(c, Coil) for c in base):
            raise ValueError("from_symmetry needs a non-empty sequence of Coil objects")
        if isinstance(nfp, bool) or not isinstance(nfp, (int, np.integer)) or nfp < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        coils = []
        for k in range(int(nfp)):
            M = _rotation_z(2 * np.pi * k / nfp)
            coils += [Coil(c.points @ M.T, c.current, c.group, c.name) for c in base]
            if stellsym:
                coils += [Coil(c.points @ (M @ _FLIP).T, -c.current, c.group, c.name) for c in base]
        return cls(coils, nfp=int(nfp), stellsym=bool(stellsym))

    def segments(self) -> tuple[jax.Array, jax.Array, jax.Array]:
        """(starts (S, 3), ends (S, 3), currents (S,)): every segment of every coil, stacked."""
        return self._segments

    def B(self, x: Any) -> jax.Array:
        """B (T) at x (m) of shape (3,) or (N, 3), the same shape."""
        return segments_B(_points(x), *self._segments)

    def A(self, x: Any) -> jax.Array:
        """A (T·m, ∇×A = B) at x (m) of shape (3,) or (N, 3), the same shape."""
        return segments_A(_points(x), *self._segments)

    def evaluate(self, x: Any, what: str = "B", *, backend: str = "auto") -> np.ndarray:
        """B (``what="B"``, T) or A (``"A"``, T·m) at many points x (m) of shape (3,) or (N, 3), the
        same shape, as a NumPy array: the host-side evaluator of grids, checks and references.

        ``backend="native"`` (the default ``"auto"`` where a C compiler and cffi are found): the
        generated C of :mod:`vpforms.backends.native.biot_savart` — the same segment formulas,
        OpenMP over the points, nothing stored per point-segment pair (memory O(N + S) for any
        number of segments; ~2 ns per pair for B, ~3.5 ns for A on one core:
        ``benchmarks/peers/results_biot_savart.md``). ``"jax"``: :meth:`B` / :meth:`A` (compiled
        per shape of ``x``). Both equal to rounding (tests/test_biot_savart_native.py)."""
        return evaluate_on_host(self, x, what, backend)

    def potential(self) -> CoilPotential:
        """A as a :class:`CoilPotential` (Cartesian): ``Field.from_vector_potential(coils.potential(),
        box)`` traces the coils directly; :func:`vpforms.toroidal.toroidal_field` (coils, box) in
        (u = R²/2, φ, Z)."""
        return CoilPotential(self)

    def __len__(self) -> int:
        return len(self.coils)

    def __iter__(self) -> Iterator[Coil]:
        return iter(self.coils)

    def __getitem__(self, k: int) -> Coil:
        return self.coils[k]

    def __repr__(self) -> str:
        n_seg = int(self._segments[0].shape[0])
        return f"CoilSet({len(self.coils)} coils, {n_seg} segments, nfp={self.nfp}, stellsym={self.stellsym})"


class CoilPotential(VectorPotential):
    """The Cartesian vector potential A(x) of a :class:`CoilSet` (Hanson–Hirshman segments, ∇×A = B),
    as a :class:`~vpforms._vecpot.VectorPotential`: the field of
    ``Field.from_vector_potential(CoilPotential(coils), box)`` is B itself, traced directly
    (Biot–Savart, no grid), its pairs by the Gauss–Legendre gauge integral of A. The native backend
    evaluates the segments in generated C with the coils passed at run time
    (:mod:`vpforms.backends.native.codegen.coils`); so does it in toroidal coordinates, where
    :class:`vpforms.toroidal.ToroidalPotential` wraps this potential."""

    def __init__(self, coils: CoilSet):
        if not isinstance(coils, CoilSet):
            raise TypeError(f"CoilPotential needs a CoilSet; got {type(coils).__name__}")
        self.coils = coils
        self.periods = (None, None, None)
        n_seg = int(coils.segments()[0].shape[0])
        self.description = f"Biot–Savart vector potential of {len(coils)} coils ({n_seg} segments)"

    def __call__(self, x: Any) -> jax.Array:
        """A (T·m) at x of shape (3,) or (N, 3), one pass over the segments."""
        return self.coils.A(x)

    def components(self):
        segs = self.coils.segments()

        def comp(i):
            def Ai(x1, x2, x3):
                x = jnp.stack(jnp.broadcast_arrays(*(jnp.asarray(v, float) for v in (x1, x2, x3))), axis=-1)
                if x.ndim == 1:
                    return segments_A(x, *segs)[i]
                return segments_A(x.reshape(-1, 3), *segs)[:, i].reshape(x.shape[:-1])

            Ai.__name__ = ("A_x", "A_y", "A_z")[i]
            return Ai

        return tuple(comp(i) for i in range(3))


#: the native host evaluator: ``evaluate`` (coils, points (N, 3), what) → (N, 3) and ``available``
#: () → (bool, why), registered by :mod:`vpforms.backends.native.biot_savart` — whose code generator
#: imports this module, so this one cannot import it (imports flow one way: tests/test_imports.py);
#: ``import vpforms`` loads it (vpforms.native → vpforms.backends)
NATIVE: dict[str, Any] = {}


def evaluate_on_host(coils: Any, x: Any, what: str, backend: str) -> np.ndarray:
    """``coils.evaluate`` (:class:`CoilSet`, :class:`~vpforms.coils.QuadratureCoils`): A or B at
    the points x as NumPy, natively where the backend allows, else by the coils' JAX ``A``/``B``."""
    if what not in ("A", "B"):
        raise ValueError(f"what must be 'A' or 'B'; got {what!r}")
    if backend not in ("auto", "native", "jax"):
        raise ValueError(f"backend must be 'auto', 'native' or 'jax'; got {backend!r}")
    pts = np.asarray(x, dtype=np.float64)
    if pts.ndim not in (1, 2) or pts.shape[-1] != 3:
        raise ValueError(f"points must have shape (3,) or (N, 3); got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    native, ok = NATIVE.get("evaluate"), False
    if backend != "jax":
        ok, why = NATIVE["available"]() if native else (False, "vpforms.backends is not loaded")
        if backend == "native" and not ok:
            raise RuntimeError(f"the native Biot–Savart evaluator is not available here: {why}")
    out = (native(coils, pts, what) if backend != "jax" and ok else
           np.asarray((coils.A if what == "A" else coils.B)(pts))).reshape(pts.shape)
    bad = ~np.all(np.isfinite(out.reshape(-1, 3)), axis=1)
    if np.any(bad):  # A and B are singular on a wire: a point there is named, never a NaN returned
        p = pts.reshape(-1, 3)[int(np.flatnonzero(bad)[0])]
        raise ValueError(f"{what} of the coils is not finite at the point ({p[0]:.9g}, {p[1]:.9g}, {p[2]:.9g}) m "
                         f"({int(bad.sum())} of {bad.size} points): it lies on a coil wire")
    return out


def _points(x: Any) -> Any:
    x = jnp.asarray(x, float)
    if x.ndim not in (1, 2) or x.shape[-1] != 3:
        raise ValueError(f"points must have shape (3,) or (N, 3); got {x.shape}")
    return x

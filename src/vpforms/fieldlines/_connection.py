"""Connection lengths: how far along the field each line runs to the wall, both ways (issue #38 item 4).

:func:`connection_length` traces every line to a wall with :func:`~vpforms.fieldlines.trace_to_wall`
twice — with the step h (forwards, along the flow ẋ = field for h > 0) and with −h (backwards) — and
reports per line the two connection lengths L_fwd, L_bwd, their sum L_c = L_fwd + L_bwd, the exit
points and, per direction, whether the line reached the wall at all: a line still inside after
n_steps reports the length it was traced as a *lower bound*, with its own status, and NaN as L_c.
:func:`start_grid` places the starting points on a regular (R, Z) grid of a section φ = φ₀ inside a
wall, optionally only in a band along it (the edge, where the lines do reach the wall).

The length is the arclength of the traced line in space, whatever the time of the field's flow:
``trace_to_wall`` integrates |ẋ| over t (:func:`vpforms.fieldlines._geometry.speed`: |ẋ| in Cartesian
coordinates, √((u̇/R)² + (R φ̇)² + Ż²) in (u = R²/2, φ, Z)). For a coil or device field, ẋ = B (the
time is in m/T, not a length: n·h is not L_c), so |ẋ| dt = |B| dt = ds; for a field of unit speed
(B/|B|) or φ as the time (B/B^φ) it is ds all the same.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._errors import RESULTS
from ..domains import ToroidalDomain
from .._polygon import Wall
from ._geometry import is_toroidal
from ._wall import WallHits, _cylindrical_np
from ._wall_chunks import trace_to_wall_chunks

__all__ = ["ConnectionLengths", "StartGrid", "connection_length", "start_grid",
           "WALL", "OPEN", "LEFT_FIELD", "FAILED", "NOT_TRACED", "STATUS_NAMES"]

#: the line reached the wall: its length is the connection length
WALL = 0
#: still inside the wall after n_steps: its length is a lower bound on the connection length
OPEN = 1
#: stopped by the field's own domain (a gridded field's grid) before the wall: a lower bound
LEFT_FIELD = 2
#: a step of the method failed: the length to the last good point, a lower bound
FAILED = 3
#: the backward direction of a ``both_ways=False`` run
NOT_TRACED = -1
#: each status in words
STATUS_NAMES = {WALL: "reached the wall", OPEN: "inside after n_steps (lower bound)",
                LEFT_FIELD: "left the field's domain first (lower bound)", FAILED: "a step failed (lower bound)",
                NOT_TRACED: "not traced"}


def _direction_status(hits: WallHits) -> np.ndarray:
    """The status (WALL, OPEN, LEFT_FIELD, FAILED) of each line of one direction's trace."""
    st = np.asarray(hits.status)
    return np.select([hits.hit, st == RESULTS.successful, st == RESULTS.left_domain], [WALL, OPEN, LEFT_FIELD],
                     FAILED).astype(np.int8)


@dataclass(frozen=True)
class ConnectionLengths:
    """Per line (arrays (N,)) the connection lengths to the wall of :func:`connection_length`.

    ``forward`` and ``backward`` are the two :class:`WallHits` (steps h and −h; ``backward`` None for
    ``both_ways=False``). Lengths are arclengths in space in the field's length unit (m for coil and
    device fields), by the trapezoid rule on |ẋ| at the steps' points plus the fraction of the exit
    step: O(h²) whatever the method's order.

    Attributes
    ----------
    x0 : numpy.ndarray
        (N, 3) the starting points in the field's coordinates.
    forward : WallHits
        The lines traced with h.
    backward : WallHits or None
        The lines traced with −h (None when only one way was traced).
    wall : Wall or ToroidalDomain
        The wall.
    toroidal : bool
        Whether the field's coordinates are (u = R²/2, φ, Z) (else Cartesian).
    wall_s : dict
        Seconds spent per direction ("forward", "backward"; on Dask both together, "both").
    where : str
        Where the lines ran ("in process", "Dask, 2 worker thread(s)").
    """

    x0: np.ndarray
    forward: WallHits
    backward: WallHits | None
    wall: Any
    toroidal: bool = True
    wall_s: dict = field(default_factory=dict)
    where: str = "in process"

    # ---------------------------------------------------------------- per direction
    @property
    def status_fwd(self) -> np.ndarray:
        """int8 (N,): WALL, OPEN, LEFT_FIELD or FAILED going forwards (:data:`STATUS_NAMES`)."""
        return _direction_status(self.forward)

    @property
    def status_bwd(self) -> np.ndarray:
        """int8 (N,): the same going backwards; NOT_TRACED everywhere for a one-way run."""
        if self.backward is None:
            return np.full(self.x0.shape[0], NOT_TRACED, np.int8)
        return _direction_status(self.backward)

    @property
    def length_fwd(self) -> np.ndarray:
        """The arclength traced forwards: L_fwd where the line reached the wall, else a lower bound."""
        return np.asarray(self.forward.connection_length, float)

    @property
    def length_bwd(self) -> np.ndarray:
        """The arclength traced backwards (0 for a one-way run)."""
        return np.zeros(self.x0.shape[0]) if self.backward is None else np.asarray(self.backward.connection_length,
                                                                                  float)

    @property
    def L_fwd(self) -> np.ndarray:
        """The forward connection length; NaN where the line did not reach the wall forwards."""
        return np.where(self.status_fwd == WALL, self.length_fwd, np.nan)

    @property
    def L_bwd(self) -> np.ndarray:
        """The backward connection length; NaN where it did not reach the wall backwards (or one-way)."""
        return np.where(self.status_bwd == WALL, self.length_bwd, np.nan)

    # ---------------------------------------------------------------- both
    @property
    def status(self) -> np.ndarray:
        """int8 (N,): WALL where the line reached the wall every way traced, else the worst of the two
        directions (FAILED > LEFT_FIELD > OPEN)."""
        return np.maximum(self.status_fwd, self.status_bwd)

    @property
    def reached(self) -> np.ndarray:
        """bool (N,): the line reached the wall every way traced (its L is the connection length)."""
        return self.status == WALL

    @property
    def unreached(self) -> np.ndarray:
        """bool (N,): status OPEN — no failure, but the wall not reached within n_steps (some way)."""
        return self.status == OPEN

    @property
    def L(self) -> np.ndarray:
        """L_c = L_fwd + L_bwd (L_fwd for a one-way run); NaN where a direction did not reach the wall."""
        return np.where(self.reached, self.length_fwd + self.length_bwd, np.nan)

    @property
    def traced(self) -> np.ndarray:
        """The arclength traced both ways: L where the line reached the wall, else a lower bound on L_c."""
        return self.length_fwd + self.length_bwd

    @property
    def both_ways(self) -> bool:
        return self.backward is not None

    def exit(self, direction: str = "forward") -> dict:
        """The exits of one direction: {"point" (N, 3) field coordinates, "R", "Z", "phi" (lifted),
        "transits"}; NaN where that direction did not reach the wall."""
        hits = {"forward": self.forward, "backward": self.backward}.get(direction)
        if hits is None:
            raise ValueError(f"direction must be 'forward' or 'backward' (of a both-ways run); got {direction!r}")
        return {"point": hits.exit_point, "R": hits.exit_RZ[:, 0], "Z": hits.exit_RZ[:, 1], "phi": hits.exit_phi,
                "transits": hits.transits}

    def summary(self) -> str:
        """How many lines reached the wall (each way and both), how many are lower bounds and why, and
        the median and range of L_c."""
        N = self.x0.shape[0]
        ways = "both ways" if self.both_ways else "forwards"
        s = self.status
        parts = [f"{N} line(s) traced {ways} to the wall ({self.forward.n_steps} steps of h = {abs(self.forward.h):g}"
                 f" at most each way, {self.where}): {int(self.reached.sum())} reached it"
                 + (f" (forwards {int((self.status_fwd == WALL).sum())}, backwards {int((self.status_bwd == WALL).sum())})"
                    if self.both_ways else "")]
        for code in (OPEN, LEFT_FIELD, FAILED):
            k = int((s == code).sum())
            if k:
                parts.append(f"{k} {STATUS_NAMES[code]}")
        out = "; ".join(parts) + "."
        if self.reached.any():
            L = self.L[self.reached]
            out += f" L_c: median {np.median(L):.4g}, min {L.min():.4g}, max {L.max():.4g}."
        if (~self.reached).any():
            out += f" Lower bounds (not reached): L_c > {np.min(self.traced[~self.reached]):.4g} at least."
        return out

    def to_csv(self, path: str) -> None:
        """One row per line: line, R0, phi0, Z0, L (empty where not reached), L_fwd, L_bwd (empty where
        that way did not reach the wall), status_fwd, status_bwd (:data:`STATUS_NAMES`), the lengths
        traced each way, the exits' R, Z, lifted φ and transits each way (empty where none)."""
        R0, phi0 = _cylindrical_np(self.x0, self.toroidal)
        cols = {"line": np.arange(self.x0.shape[0]), "R0": R0, "phi0": phi0, "Z0": self.x0[:, 2], "L": self.L,
                "L_fwd": self.L_fwd, "L_bwd": self.L_bwd, "status_fwd": self.status_fwd,
                "status_bwd": self.status_bwd, "length_fwd": self.length_fwd, "length_bwd": self.length_bwd}
        for d in ("forward", "backward") if self.both_ways else ("forward",):
            e = self.exit(d)
            tag = "fwd" if d == "forward" else "bwd"
            cols.update({f"exit_R_{tag}": e["R"], f"exit_Z_{tag}": e["Z"], f"exit_phi_{tag}": e["phi"],
                         f"transits_{tag}": e["transits"]})
        with open(path, "w", encoding="utf-8") as f:
            f.write(",".join(cols) + "\n")
            data = np.column_stack([np.asarray(v, float) for v in cols.values()])
            ints = {"line", "status_fwd", "status_bwd"}
            for row in data:
                f.write(",".join("" if not math.isfinite(v) else (str(int(v)) if k in ints else repr(float(v)))
                                 for k, v in zip(cols, row)) + "\n")


def connection_length(method: Any, x0: Any, h: float, n_steps: int, wall: Wall | ToroidalDomain, *,
                      both_ways: bool = True, backend: str = "auto", client: Any = None,
                      builder: Callable[[], Any] | None = None, chunk_lines: int | None = None, t0: float = 0.0,
                      progress: bool | str = "auto") -> ConnectionLengths:
    """The connection length of each field line to ``wall``: traced forwards (step h) and backwards
    (step −h) until it leaves the wall, at most ``n_steps`` steps each way.

    Parameters
    ----------
    method
        A vpforms method of a field (:func:`vpforms.fieldlines.trace_to_wall`: Cartesian, or (u, φ, Z)).
    x0
        (N, 3) or (3,) starting points in the field's coordinates, inside the wall (else a ValueError
        naming the first one outside).
    h
        The step (> 0: "forwards" is along the flow ẋ = field; the backward trace uses −h).
    n_steps
        The most steps per line and direction: a line still inside after them has status OPEN and
        its length traced is a lower bound, never reported as L_c.
    wall
        A :class:`Wall` or a :class:`vpforms.domains.ToroidalDomain` (e.g.
        :func:`vpforms.problems.devices.divertor_wall`).
    both_ways
        Trace backwards too (default); False: forwards only (then L = L_fwd).
    backend
        "auto", "native" or "jax", as for :func:`trace_to_wall`; chosen once, for every line and
        both directions.
    client
        None: in this process. A worker count (an int: a Dask ``LocalCluster`` of that many
        processes, one thread each, closed at the end), "local", "tcp://…" or a
        ``dask.distributed.Client`` (left open): the lines in chunks, both directions' chunks
        submitted together, each chunk one :func:`trace_to_wall` call on a worker. Natively the
        result equals the in-process one bit for bit (a line's trace depends only on its own state).
    builder
        For ``client``, when the method's field has no JSON spec (a spline of coils, a device's grid:
        :func:`vpforms.problems.devices.grid_field`): a picklable zero-argument callable that builds
        the same method in each worker, once per process (:mod:`vpforms._dask`).
    chunk_lines
        Lines per chunk on Dask (default: about four chunks per worker thread).
    t0
        The start time.
    progress
        Progress bars (in process) or chunk lines (Dask) on stderr: True, False or "auto".

    Returns
    -------
    ConnectionLengths
        L_fwd, L_bwd, L = L_fwd + L_bwd, per-direction statuses (WALL, OPEN, LEFT_FIELD, FAILED), the
        lengths traced (lower bounds where not WALL), the exits.

    Notes
    -----
    The length is the arclength in space (module docstring): the trapezoid rule on |ẋ| at the step
    points plus the fraction of the exit step, O(h²) (tests: a helix in a field with B_R = α/R whose
    length to a plane is a closed form, error ratio 4 as h halves). Backwards, the same method steps
    with −h: a symmetric method (any composition of order ≥ 2) retraces its own forward steps,
    Ψ_{−h} = Ψ_h⁻¹ to the solver's tolerance, so the backward trace from a forward point passes
    through the start (tested).
    """
    if not isinstance(both_ways, bool):
        raise TypeError(f"both_ways must be True or False; got {both_ways!r}")
    h = float(h)
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"h must be finite and > 0 (the backward trace uses −h); got {h}")
    hs = [h, -h] if both_ways else [h]
    parts, info = trace_to_wall_chunks(method, x0, hs, n_steps, wall, t0=t0, chunk_particles=chunk_lines,
                                       client=client, backend=backend, progress=progress, builder=builder)
    names = ["forward", "backward"] if both_ways else ["forward"]
    wall_s = dict(zip(names, info["wall_s"])) if client is None else {"both": info["wall_s"][0]}
    return ConnectionLengths(x0=np.asarray(x0, float).reshape(-1, 3), forward=parts[0],
                             backward=parts[1] if both_ways else None, wall=wall,
                             toroidal=is_toroidal(method.field), wall_s=wall_s, where=info["where"])


# --------------------------------------------------------------------------------------------
# Starting points on a section
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StartGrid:
    """Starting points on a regular (R, Z) grid of the section φ = φ₀ (:func:`start_grid`).

    Attributes
    ----------
    x0 : numpy.ndarray
        (M, 3) the points in the field's coordinates ((u = R²/2, φ₀, Z) or Cartesian).
    R : numpy.ndarray
        (n_R,) the grid's R nodes.
    Z : numpy.ndarray
        (n_Z,) the grid's Z nodes.
    index : numpy.ndarray
        (M, 2) each point's (i_Z, i_R) on the grid.
    phi0 : float
        The section's angle.
    spacing : float
        The grid spacing (the same in R and Z).
    """

    x0: np.ndarray
    R: np.ndarray
    Z: np.ndarray
    index: np.ndarray
    phi0: float
    spacing: float

    def image(self, values: Any) -> np.ndarray:
        """(n_Z, n_R) array of one value per point (NaN off the points): for ``pcolormesh``."""
        v = np.asarray(values, float).reshape(-1)
        if v.size != self.index.shape[0]:
            raise ValueError(f"image needs one value per point ({self.index.shape[0]}); got {v.size}")
        out = np.full((self.Z.size, self.R.size), np.nan)
        out[self.index[:, 0], self.index[:, 1]] = v
        return out


def start_grid(wall: Wall | ToroidalDomain, n: int, *, phi0: float = 0.0, depth: float | None = None,
               toroidal: bool = True) -> StartGrid:
    """About ``n`` starting points on a square grid of the section φ = φ₀ inside ``wall``: all of its
    inside (``depth`` None) or the band within ``depth`` of the wall (0 < −signed distance ≤ depth:
    the edge, where lines reach the wall; the core's closed surfaces never do and only cost n_steps).

    The spacing δ = √(band area / n), the area measured on a 400 × 400 grid of the wall's bounds; the
    number of points is n to within the band's boundary cells. Points closer to the wall than
    1e-9 of its size are left out (a start on the wall has no exit step).

    Parameters
    ----------
    wall
        A :class:`Wall` or a :class:`vpforms.domains.ToroidalDomain` (its polygon at φ₀).
    n
        The number of points wanted (≥ 1).
    phi0
        The section's angle.
    depth
        The band's width inside the wall (> 0), in the wall's length unit; None: the whole inside.
    toroidal
        Points in (u = R²/2, φ, Z) (default) or Cartesian (x₁, x₂, x₃) with the major axis x₃.
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n must be an integer ≥ 1; got {n!r}")
    if depth is not None and not (math.isfinite(float(depth)) and float(depth) > 0):
        raise ValueError(f"depth must be > 0 (the band's width inside the wall) or None; got {depth!r}")
    if isinstance(wall, ToroidalDomain):
        poly = wall.wall_at(float(phi0))
    elif isinstance(wall, Wall):
        poly = wall
    else:
        raise TypeError(f"wall must be a Wall or a ToroidalDomain; got {type(wall).__name__}")
    r0, r1, z0, z1 = poly.bounds
    tiny = 1e-9 * max(abs(r0), abs(r1), abs(z0), abs(z1))

    def band(R, Z):
        d = np.asarray(poly.signed_distance(R, Z))
        keep = d < -tiny
        return keep if depth is None else keep & (d >= -float(depth))

    Rf, Zf = np.meshgrid(np.linspace(r0, r1, 400), np.linspace(z0, z1, 400))
    frac = float(np.mean(band(Rf, Zf)))
    if frac == 0.0:
        raise ValueError(f"no point of the band of depth {depth} inside {poly!r} at φ = {phi0:g}")
    delta = math.sqrt(frac * (r1 - r0) * (z1 - z0) / int(n))
    R, Z = _nodes(r0, r1, delta), _nodes(z0, z1, delta)
    RR, ZZ = np.meshgrid(R, Z)
    k = band(RR, ZZ) & (RR > 0)
    iz, ir = np.nonzero(k)
    Rp, Zp = RR[k], ZZ[k]
    if toroidal:
        x0 = np.stack([Rp**2 / 2, np.full_like(Rp, phi0), Zp], axis=1)
    else:
        x0 = np.stack([Rp * math.cos(phi0), Rp * math.sin(phi0), Zp], axis=1)
    return StartGrid(x0=x0, R=R, Z=Z, index=np.stack([iz, ir], axis=1), phi0=float(phi0), spacing=delta)


def _nodes(a: float, b: float, delta: float) -> np.ndarray:
    """Nodes of spacing δ in [a, b], centred (symmetric about (a + b)/2: a wall symmetric in Z gives
    nodes symmetric in Z)."""
    m = int(math.floor((b - a) / delta)) + 1
    return (a + b) / 2 + delta * (np.arange(m) - (m - 1) / 2)

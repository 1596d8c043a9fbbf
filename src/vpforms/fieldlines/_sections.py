"""Poincaré sections at φ = const of toroidal fields, in (R, Z) (issue #21, item 1)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._integrate import _check_run
from ..diagnostics._surfaces import Plane, ToroidalAngle
from ..diagnostics.poincare import PoincareSection, _section_on
from ._domain import check_starts
from ._geometry import is_toroidal

__all__ = ["ToroidalSection", "toroidal_section", "section_surface"]


@dataclass(frozen=True)
class ToroidalSection:
    """The crossings of the half-planes φ = φ₀ + k·2π/nfp by field lines, in cylindrical (R, Z).

    ``R``, ``Z`` (M,) the crossing points; ``line`` (M,) the index of the field line;
    ``transit`` (M,) the crossing's number along its line (0, 1, 2, … in the order met);
    ``phi`` (M,) the half-plane crossed, reduced to [0, 2π); ``t`` (M,) the crossing time;
    ``status`` (N,) the per-line RESULTS code; ``section`` the underlying
    :class:`~vpforms.diagnostics.PoincareSection` (points in the field's own coordinates, step,
    θ, the located-by fallback flags, counts, dropped).
    """

    R: np.ndarray
    Z: np.ndarray
    line: np.ndarray
    transit: np.ndarray
    phi: np.ndarray
    t: np.ndarray
    status: np.ndarray
    phi0: float
    nfp: int
    section: PoincareSection

    def __len__(self) -> int:
        return int(self.R.size)

    def of_line(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(R, Z) of line i's crossings, in transit order."""
        k = self.line == i
        return self.R[k], self.Z[k]

    def before(self, t_stop: np.ndarray) -> "ToroidalSection":
        """The crossings of each line i at times t < t_stop[i] (e.g. ``WallHits.t_exit``; NaN or
        +inf: all of that line's crossings)."""
        stop = np.where(np.isfinite(t_stop), t_stop, np.inf)
        k = self.t < stop[self.line]
        return ToroidalSection(R=self.R[k], Z=self.Z[k], line=self.line[k], transit=self.transit[k], phi=self.phi[k],
                               t=self.t[k], status=self.status, phi0=self.phi0, nfp=self.nfp, section=self.section)

    def to_csv(self, path: str) -> None:
        """Write line, transit, phi, t, R, Z (one row per crossing).

        ``phi`` is the section's angle, the crossed half-plane's φ modulo the field period
        P = 2π/nfp, in [0, P): a crossing located a rounding error below a multiple of P (φ =
        2π − 1e-16, which ``np.mod`` leaves at 2π − 1e-16 or rounds to 2π) is the section φ = 0,
        so values within 1e-9·P of P are written as 0 — every row of the section φ₀ reads φ₀, never
        0 for some and 6.283185 for others (issue #41)."""
        P = 2 * math.pi / int(self.nfp)
        phi = np.mod(np.asarray(self.phi, dtype=np.float64), P)
        phi[phi >= P * (1.0 - 1e-9)] = 0.0  # np.mod may also return P itself for a tiny negative φ
        data = np.column_stack([self.line, self.transit, phi, self.t, self.R, self.Z])
        np.savetxt(path, data, delimiter=",", header="line,transit,phi,t,R,Z", comments="",
                   fmt=["%d", "%d"] + ["%.17g"] * 4)


def section_surface(field: Any, phi: float, nfp: int):
    """The section surface φ = phi (+ k·2π/nfp) in the field's coordinates: the plane x₂ = φ of the
    coordinates (u, φ, Z), or the half-planes atan2(x₂, x₁) = φ of Cartesian ones."""
    if isinstance(nfp, bool) or int(nfp) != nfp or int(nfp) < 1:
        raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
    if not math.isfinite(float(phi)):
        raise ValueError(f"phi must be a finite angle; got {phi!r}")
    P = 2 * math.pi / int(nfp)
    phi0 = float(phi) % P
    if is_toroidal(field):
        return Plane(1, phi0, P)
    return ToroidalAngle(phi0, int(nfp))


def toroidal_section(method: Any, x0: Any, h: float, n_steps: int, phi: float = 0.0, nfp: int = 1, *,
                     direction: int = 0, max_crossings: int | None = None, interpolation: str = "step",
                     t0: float = 0.0, chunk_size: int | None = None,
                     progress: bool | str = "auto", backend: str = "auto") -> ToroidalSection:
    """Crossings of φ = phi (mod 2π/nfp) by the field lines from x0, located on the method's step family.

    Works for fields in Cartesian coordinates (major axis x₃, φ = atan2(x₂, x₁)) and in the toroidal
    coordinates (u = R²/2, φ, Z) of :mod:`vpforms.toroidal`; x0 is in the field's coordinates.
    ``direction`` +1 counts crossings with φ increasing, −1 decreasing, 0 (default) both — a field
    line crosses in the direction of B^φ. A crossing inside the step x_n → x_{n+1} is located on the
    method's own family θ ↦ Ψ_{θh}(x_n) (:func:`~vpforms.diagnostics.poincare_section`: the error is
    the method's local error O(h^{p+1})). For Cartesian fields a step must turn by less than π about
    the major axis (always the case for a step that follows the field).

    The result's ``transit`` numbers a line's crossings from 0; with nfp > 1 a line crosses nfp
    half-planes per toroidal turn. ``backend`` as for :func:`~vpforms.diagnostics.poincare_section`
    (``"auto"``: native where the method can be generated; ``section.backend`` says which ran).
    A start with R = 0 or outside the field's box or domain is refused before any step.
    """
    if direction not in (-1, 0, 1):
        raise ValueError(f"direction must be -1, 0 or +1, got {direction}")
    if interpolation not in ("step", "linear"):
        raise ValueError(f"interpolation must be 'step' or 'linear', got {interpolation!r}")
    field = getattr(method, "field", None)
    surface = section_surface(field, phi, nfp)
    pts, _, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    if field is not None:  # R > 0 and in the field's box or domain, before any step
        check_starts(field, pts, "line")
    axis = 1 if isinstance(surface, Plane) else -1
    sec = _section_on(method, pts, h, n_steps, surface, direction, max_crossings, interpolation, t0, chunk_size,
                      progress, f"section φ = {surface.value:.4g}",
                      {"axis": axis, "value": surface.value, "period": surface.period}, backend)
    p = sec.points
    if isinstance(surface, Plane):
        R, Z, ph = np.sqrt(2.0 * p[:, 0]), p[:, 2], p[:, 1]
    else:
        R, Z, ph = np.hypot(p[:, 0], p[:, 1]), p[:, 2], np.arctan2(p[:, 1], p[:, 0])
    # number each line's crossings 0, 1, 2, … (the section's rows are sorted by line, then step)
    transit = np.zeros(sec.particle.size, dtype=np.int64)
    if sec.particle.size:
        start = np.r_[0, np.flatnonzero(np.diff(sec.particle)) + 1]
        first = np.repeat(start, np.diff(np.r_[start, sec.particle.size]))
        transit = np.arange(sec.particle.size) - first
    return ToroidalSection(R=R, Z=Z, line=sec.particle, transit=transit, phi=np.mod(ph, 2 * math.pi), t=sec.t,
                           status=sec.status, phi0=surface.value, nfp=int(nfp), section=sec)

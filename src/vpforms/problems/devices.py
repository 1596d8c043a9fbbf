"""Field lines of real stellarators — W7-X, NCSX, HSX — traced directly on their coils (issue #38).

The coils are those simsopt ships (:func:`vpforms.coils.device`: closed polylines at simsopt's
quadrature points, ``n_points`` per coil to refine), and the field is their Hanson–Hirshman B = ∇×A
in the toroidal coordinates x = (u = R²/2, φ, Z) of unit Jacobian (:func:`vpforms.toroidal.toroidal_field`
of the coil set): no grid, exactly divergence free, periodic in φ with period 2π/nfp.

* ``box`` — a rectangle in (R, Z) (as u = R²/2) around the plasma at every φ: the range of the
  magnetic axis R(φ), Z(φ) over a period (:func:`vpforms.coils.device_axis`) widened by the
  device's ``margin``. The cross-sections turn from a bean to a triangle over a period and the
  coils hug them, so a rectangle that holds the plasma at every φ also holds coil filaments —
  for W7-X certainly: the box is where samples and plots go, not a wall. A domain that follows
  the plasma is issue #38's ``vpforms.domains``.
* ``axis_guess`` — the axis point (R, Z) on φ = 0 (from the axis data).
* ``x0`` — five points on the outboard midplane of φ = 0 (Z = 0) at 10 %, 30 %, 50 %, 70 %, 90 % of
  the distance ``edge`` from the axis to the outermost closed surface there; the sampler draws
  between 5 % and 95 % of it. ``edge`` was measured with simsopt's ``compute_fieldlines`` on its
  own ``BiotSavart`` (tol 1e-9; 40, 25, 20 transits for HSX, NCSX, W7-X; 16 lines from the axis
  outward): the largest offset whose line stays on a thin closed curve of the section (HSX 0.07 m:
  the line at 0.08 m leaves within 25 transits; NCSX 0.075 m: beyond it the lines spread over a
  wide band and leave past 0.14 m; W7-X 0.25 m: closed curves to 0.24 m, the lines at 0.27 and
  0.30 m lie in the 5/5 island chain, R ∈ [6.20, 6.25] m on the section, as issue #38 reports).

Known limit (issue #38): on W7-X's box ``vpforms.scheme(problem.field, "SE+SE")`` refuses the field
with a ``PotentialError`` — the SE pair built by the Gauss–Legendre gauge integral of A does not
reproduce B (relative error 15.8 at R = 5.46 m, φ = 0.99, Z = 0.98 m, next to a coil filament) —
after about 5 minutes of checking (1.1 GB peak). The field itself (``problem.field(x)``) is exact;
tracing needs a domain that keeps away from the coils.
"""

from __future__ import annotations

from functools import lru_cache, partial

import numpy as np

from ..coils import device, device_axis, device_data
from ..toroidal import box_from_cylindrical, to_toroidal, toroidal_field
from ._base import Problem

__all__ = ["default", "make"]

SOURCE = ("vacuum field of the device's filamentary coils as shipped by simsopt (simsopt.configs.get_data; "
          "benchmarks/peers/make_devices.py), Hanson–Hirshman segments traced directly, no grid")

#: per device: the distance from the axis to the outermost closed surface on the outboard midplane of
#: φ = 0, and the margin around the axis' (R, Z) range that makes the box (m; module docstring)
_GEOMETRY = {
    "w7x": {"edge": 0.25, "margin": 1.0},
    "ncsx": {"edge": 0.075, "margin": 0.5},
    "hsx": {"edge": 0.07, "margin": 0.3},
}


def _box(axis, nfp: int, margin: float) -> tuple:
    """The (u, φ, Z) box: the axis' R and Z ranges over a period widened by ``margin``, φ over one period."""
    phi = np.linspace(0, 2 * np.pi / nfp, 181)
    R, Z = axis(phi)
    return box_from_cylindrical((R.min() - margin, R.max() + margin), (0.0, 2 * np.pi / nfp),
                                (Z.min() - margin, Z.max() + margin))


def _midplane(R_axis: float, offsets) -> np.ndarray:
    offsets = np.asarray(offsets, dtype=float)
    return np.asarray(to_toroidal(np.c_[R_axis + offsets, np.zeros_like(offsets), np.zeros_like(offsets)]))


def make(name: str, *, n_points: int | None = None) -> Problem:
    """The field lines of the device ``name`` (``"w7x"``, ``"ncsx"``, ``"hsx"``) traced on its coils
    with ``n_points`` points per coil (default simsopt's quadrature count; the field then differs from
    the smooth coils' by ≈ 4e-4 (W7-X), 2e-4 (NCSX), 4e-5 (HSX) of max |B|, falling as 1/n_points²).
    Module docstring for the box, axis guess and initial conditions."""
    coils = device(name, n_points)
    key = device_data(name)["name"]  # the canonical name ("W7-X" → "w7x")
    axis, geo = device_axis(key), _GEOMETRY[key]
    R0, Z0 = (float(v) for v in axis(0.0))
    edge = geo["edge"]
    field = toroidal_field(coils, _box(axis, coils.nfp, geo["margin"]), name=key)
    n_seg = int(coils.segments()[0].shape[0])
    return Problem(
        name=key, field=field,
        params={"device": key, "n_points": n_points, "segments": n_seg, "nfp": coils.nfp, "edge": edge},
        x0=_midplane(R0, edge * np.array([0.1, 0.3, 0.5, 0.7, 0.9])),
        invariants={}, invariant_exprs={}, source=SOURCE,
        periodic=(None, 2 * np.pi / coils.nfp, None), box=field.box,
        description=f"{key} coils ({len(coils)} coils, {n_seg} segments): field lines in (u = R²/2, φ, Z)",
        sampler=partial(_sample_midplane, R0, 0.05 * edge, 0.95 * edge),
        axis_guess=(R0, Z0),
    )


def _sample_midplane(R_axis: float, lo: float, hi: float, rng: np.random.Generator, n: int) -> np.ndarray:
    return _midplane(R_axis, rng.uniform(lo, hi, n)) if n else np.zeros((0, 3))


@lru_cache(maxsize=None)
def default(name: str) -> Problem:
    """The cached default problem of the device ``name`` (built on first use)."""
    return make(name)

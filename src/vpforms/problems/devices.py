"""Field lines of real stellarators — W7-X, NCSX, HSX — traced directly on their coils (issue #38).

The coils are those simsopt ships (:func:`vpforms.coils.device`: closed polylines at simsopt's
quadrature points, ``n_points`` per coil to refine), and the field is their Hanson–Hirshman B = ∇×A
in the toroidal coordinates x = (u = R²/2, φ, Z) of unit Jacobian (:func:`vpforms.toroidal.toroidal_field`
of the coil set): no grid, exactly divergence free, periodic in φ with period 2π/nfp.

* ``domain`` — the device's default domain (:func:`vpforms.coils.device_domain`): a VMEC-form
  boundary fitted to the last closed flux surface (simsopt's field-line tracer) and moved outward
  by a margin (W7-X: to hold the 5/5 island chain), clear of every coil filament
  (``trace_to_wall(method, x0, h, n, problem.domain)`` stops the lines that leave it);
* ``box`` — the domain's (R, Z) bounds over a period widened by 5 % of its R extent (as u = R²/2).
  The cross-sections turn from a bean to a triangle over a period and the coils hug them, so a
  rectangle that holds the plasma at every φ still holds coil filaments — for W7-X certainly: the
  box is where samples and plots go, the domain is the wall.
* ``axis_guess`` — the axis point (R, Z) on φ = 0 (from the axis data).
* ``x0`` — five points on the outboard midplane of φ = 0 (Z = 0) at 10 %, 30 %, 50 %, 70 %, 90 % of
  the distance ``edge`` from the axis to the outermost closed surface there; the sampler draws
  between 5 % and 95 % of it. ``edge`` was measured with simsopt's ``compute_fieldlines`` on its
  own ``BiotSavart`` (tol 1e-9; 40, 25, 20 transits for HSX, NCSX, W7-X; 16 lines from the axis
  outward): the largest offset whose line stays on a thin closed curve of the section (HSX 0.07 m:
  the line at 0.08 m leaves within 25 transits; NCSX 0.075 m: beyond it the lines spread over a
  wide band and leave past 0.14 m; W7-X 0.25 m: closed curves to 0.24 m, the lines at 0.27 and
  0.30 m lie in the 5/5 island chain, R ∈ [6.20, 6.25] m on the section, as issue #38 reports).

The field's own :attr:`~vpforms.Field.domain` is the problem's domain: its construction checks and
the check of a method's potentials sample the domain, not the box (on W7-X's box,
``vpforms.scheme`` refused the field: the SE pair built by the Gauss–Legendre gauge integral of A
does not reproduce B next to a coil filament inside the box). That check reconstructs B from
second derivatives at 512 points × 32 Gauss nodes of 4 800 segments: minutes (memory bounded);
whether the quadrature pair passes it on the whole default domain, whose edge is 0.12 m from the
coils, is not yet measured (issue #38).
"""

from __future__ import annotations

from functools import lru_cache, partial

import numpy as np

from ..coils import device, device_axis, device_data, device_domain
from ..domains import ToroidalDomain
from ..phitime import phi_time_field
from ..toroidal import box_from_cylindrical, to_toroidal, toroidal_field
from ._base import Problem
from .coil_fields import spline_coil_field

__all__ = ["DIVERTOR_INSET", "GRID", "PHI_TIME_INSET", "default", "divertor_wall", "grid_box", "grid_field", "make",
           "phi_time_grid_field"]

SOURCE = ("vacuum field of the device's filamentary coils as shipped by simsopt (simsopt.configs.get_data; "
          "benchmarks/peers/make_devices.py), Hanson–Hirshman segments traced directly, no grid")

#: per device: the distance from the axis to the outermost closed surface on the outboard midplane of
#: φ = 0 (m; module docstring)
EDGE = {"w7x": 0.25, "ncsx": 0.075, "hsx": 0.07}

#: the box's margin around the domain's (R, Z) bounds, as a fraction of the domain's R extent
BOX_MARGIN = 0.05


def _box(key: str, nfp: int) -> tuple:
    """The (u, φ, Z) box: :func:`grid_box` (as u = R²/2), φ over one period."""
    R, Z = grid_box(key)
    return box_from_cylindrical(R, (0.0, 2 * np.pi / nfp), Z)


def _midplane(R_axis: float, offsets) -> np.ndarray:
    offsets = np.asarray(offsets, dtype=float)
    return np.asarray(to_toroidal(np.c_[R_axis + offsets, np.zeros_like(offsets), np.zeros_like(offsets)]))


def make(name: str, *, n_points: int | None = None) -> Problem:
    """The field lines of the device ``name`` (``"w7x"``, ``"ncsx"``, ``"hsx"``) traced on its coils
    with ``n_points`` points per coil (default simsopt's quadrature count; the field then differs from
    the smooth coils' by ≈ 4e-4 (W7-X), 2e-4 (NCSX), 4e-5 (HSX) of max |B|, falling as 1/n_points²).
    Module docstring for the domain, box, axis guess and initial conditions."""
    coils = device(name, n_points)
    key = device_data(name)["name"]  # the canonical name ("W7-X" → "w7x")
    axis, domain, edge = device_axis(key), device_domain(key), EDGE[key]
    R0, Z0 = (float(v) for v in axis(0.0))
    field = toroidal_field(coils, _box(key, coils.nfp), name=key, domain=domain)
    n_seg = int(coils.segments()[0].shape[0])
    return Problem(
        name=key, field=field,
        params={"device": key, "n_points": n_points, "segments": n_seg, "nfp": coils.nfp, "edge": edge},
        x0=_midplane(R0, edge * np.array([0.1, 0.3, 0.5, 0.7, 0.9])),
        invariants={}, invariant_exprs={}, source=SOURCE,
        periodic=(None, 2 * np.pi / coils.nfp, None), box=field.box,
        description=f"{key} coils ({len(coils)} coils, {n_seg} segments): field lines in (u = R²/2, φ, Z)",
        sampler=partial(_sample_midplane, R0, 0.05 * edge, 0.95 * edge),
        axis_guess=(R0, Z0), domain=domain,
    )


def _sample_midplane(R_axis: float, lo: float, hi: float, rng: np.random.Generator, n: int) -> np.ndarray:
    return _midplane(R_axis, rng.uniform(lo, hi, n)) if n else np.zeros((0, 3))


#: the default grid (n_R, n_φ, n_Z) of :func:`grid_field`: W7-X's B error at 400 points of its
#: domain ≤ 1.3e-3 of max |B| (the domain's edge, 0.12 m from the coils), ≤ 2e-5 deeper than
#: 0.3 m; built in ≈ 25 s of CPU
GRID = (48, 96, 48)


def grid_box(name: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """The (R, Z) box of the device's grids: its default domain's bounds widened by BOX_MARGIN of
    the R extent (coil wires in it are left out by the grid that follows the domain)."""
    r0, r1, z0, z1 = device_domain(name).bounds
    pad = BOX_MARGIN * (r1 - r0)
    return (r0 - pad, r1 + pad), (z0 - pad, z1 + pad)


@lru_cache(maxsize=4)
def grid_field(name: str, grid: tuple[int, int, int] = GRID, degree: int = 3, rule: str = "quadrature",
               n_points: int | None = None, fit: str = "interpolate") -> tuple:
    """(field, spline_error): the device's coils (``rule``: "quadrature" — simsopt's field —, or
    "polyline") splined on a ``grid`` = (n_R, n_φ, n_Z) grid of :func:`grid_box` over one period
    that follows the default domain (:func:`vpforms.problems.coil_fields.spline_coil_field`), in
    (u = R²/2, φ, Z), every backend (the native one included). spline_error is max |B_spline − B|
    / max |B| at 400 seeded points of the domain (the worst sit at its edge, nearest the coils).
    ``fit="quasi"``: the local quasi-interpolant instead, sampled within its reach of the domain's
    cells (coils inside that reach; NaN farther out):
    :func:`~vpforms.problems.coil_fields.spline_coil_field`.
    Cached per arguments within a process."""
    key = device_data(name)["name"]
    R, Z = grid_box(key)
    n_R, n_phi, n_Z = (int(g) for g in grid)
    return spline_coil_field(device(key, n_points, rule=rule), R, Z, n_R=n_R, n_phi=n_phi, n_Z=n_Z,
                             name=f"{key} ({rule} coils, {n_R}x{n_phi}x{n_Z} grid)", domain=device_domain(key),
                             degree=degree, fit=fit)


@lru_cache(maxsize=None)
def default(name: str) -> Problem:
    """The cached default problem of the device ``name`` (built on first use)."""
    return make(name)


#: per device: how far (m) :func:`divertor_wall` moves the default domain inward by default. W7-X's
#: default domain lies 0.29 m outside the surface fitted to a line 0.24 m from the axis (just inside
#: the last closed surface; ``device_data("w7x")["domain"]``): 0.24 m inward puts the wall 0.05 m
#: outside that surface, through the 5/5 island chain (O-points 0.045 m outside it on the outboard
#: midplane of φ = 0)
DIVERTOR_INSET = {"w7x": 0.24}


def divertor_wall(name: str = "w7x", inset: float | None = None) -> ToroidalDomain:
    """A simple divertor-like wall: the device's default domain moved inward by ``inset`` (m; default
    :data:`DIVERTOR_INSET`) along its in-plane normals, on each of its planes — a smooth wall that
    cuts into the edge island chain, so that the lines of the islands and outside them reach it
    after finite connection lengths while the closed surfaces inside never do.

    A *model*, not the W7-X divertor: the real one is ten divertor units (target plates and baffles,
    above and below the plasma in each field period) that cut the 5/5 islands only in some toroidal
    and poloidal sectors; here the wall cuts the chain all round, at one distance from the fitted
    surface (which itself is within 1.5 cm of a flux surface).

    Raises
    ------
    ValueError
        An unknown device, no default inset for it, an inset that is not > 0 or so large that a plane's
        boundary would fold (the domain's validation names the plane).
    """
    key = device_data(name)["name"]
    if inset is None:
        if key not in DIVERTOR_INSET:
            raise ValueError(f"{key}: no default divertor inset (known: {', '.join(DIVERTOR_INSET)}); give inset= (m)")
        inset = DIVERTOR_INSET[key]
    return _inset_domain(key, inset, "divertor-like wall")


def _inset_domain(key: str, inset: float, what: str) -> ToroidalDomain:
    """The default domain of ``key`` moved ``inset`` m inward along its in-plane normals."""
    inset = float(inset)
    if not (np.isfinite(inset) and inset > 0):
        raise ValueError(f"inset must be > 0 (m, inward); got {inset}")
    dom = device_domain(key)
    R, Z = dom.R, dom.Z  # (planes, vertices), open polygons of the same orientation
    tR = np.roll(R, -1, axis=1) - np.roll(R, 1, axis=1)  # the tangent by central differences
    tZ = np.roll(Z, -1, axis=1) - np.roll(Z, 1, axis=1)
    orient = np.sign(np.sum(R * np.roll(Z, -1, axis=1) - np.roll(R, -1, axis=1) * Z, axis=1))[:, None]  # shoelace
    t = np.hypot(tR, tZ)
    nR, nZ = orient * tZ / t, -orient * tR / t  # the outward normal
    return ToroidalDomain(dom.phis, R - inset * nR, Z - inset * nZ, nfp=dom.nfp,
                          name=f"{key} {what} (default domain moved {inset:g} m inward)")


#: per device: how far (m) :func:`phi_time_grid_field` moves the default domain inward for φ as the
#: time. W7-X: B^φ changes sign within the default domain's 0.12 m of the coils, not on the domain
#: moved 0.1 m in, which still holds the 5/5 island chain (0.19 m outside the fitted surface)
PHI_TIME_INSET = {"w7x": 0.1}

#: the default grids (n_R, n_φ, n_Z) of A and (n_v, n_φ, n_Z) of K of :func:`phi_time_grid_field`
PHI_TIME_GRIDS = ((64, 128, 64), (64, 96, 64))


@lru_cache(maxsize=4)
def phi_time_grid_field(name: str, grid: tuple[int, int, int] = PHI_TIME_GRIDS[0],
                        grid_K: tuple[int, int, int] = PHI_TIME_GRIDS[1], inset: float | None = None,
                        degree: int = 5, fit: str = "quasi", degree_K: int | None = None,
                        fit_K: str = "interpolate") -> tuple:
    """(φ-time field, A's spline error): the device's field lines with φ as the time
    (:func:`vpforms.phitime.phi_time_field`) — the spline of A of :func:`grid_field` (``grid``,
    ``degree``, ``fit``), and K fitted on a ``grid_K`` grid (``degree_K``, default ``degree``;
    ``fit_K``) of the image of the default domain moved ``inset`` m inward (default
    :data:`PHI_TIME_INSET`), where B^φ keeps its sign (on the box, next to the coils, it does not).
    The field runs natively; its steps advance φ by exactly h with
    :func:`vpforms.phitime.phi_time_scheme`, so that sections are step ends. Map points with
    :func:`vpforms.phitime.to_phi_time` / :func:`~vpforms.phitime.from_phi_time`. Where the
    device's B^φ < 0 (W7-X) φ increases backwards along B: the same curves, and the sections of
    stellarator-symmetric devices are those of a tracer along B with Z negated. Cached per
    arguments within a process.

    The defaults are what the sections need (issue #38, measured on W7-X): A of **degree 5** —
    K = A'_φ(U, φ, Z) carries ∂_φχ, χ = ∫ A_u du, one degree less smooth in φ than A, so a cubic A
    makes K only C¹ across A's φ knots and no grid of K converges to it (the b error along the lines
    stayed at ~1e-4 from a 64 × 128 × 64 grid of K to 96 × 256 × 96; with a quintic A it falls as
    the grid of K is refined) — fitted by the local quasi-interpolant (``fit="quasi"``: the
    interpolant of degree 5 rings next to the coils; within reach of the default domain's cells
    only, the box's coils inside that reach), and K interpolated at degree 5 on the image
    (its quasi-interpolant leaves the cells next to the image's edge undefined).

    Raises
    ------
    ValueError
        No default inset for the device (give ``inset``).
    vpforms.phitime.PhiTimeError
        B^φ changes sign on the inset domain (a larger inset), or a cross-section is not convex
        along R.
    """
    key = device_data(name)["name"]
    if inset is None:
        if key not in PHI_TIME_INSET:
            raise ValueError(f"{key}: no default φ-time inset (known: {', '.join(PHI_TIME_INSET)}); give inset= (m)")
        inset = PHI_TIME_INSET[key]
    field, err = grid_field(key, tuple(grid), degree=degree, fit=fit)
    dom = _inset_domain(key, inset, "φ-time domain")
    k_K = degree if degree_K is None else int(degree_K)
    pf = phi_time_field(field, grid=tuple(grid_K), domain=dom, degree=k_K, fit=fit_K,
                        name=f"{key} φ-time (A {'x'.join(map(str, grid))} degree {degree} {fit}, "
                             f"K {'x'.join(map(str, grid_K))} degree {k_K} {fit_K})")
    return pf, err

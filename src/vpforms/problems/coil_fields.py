"""Field lines of the two coil sets of :mod:`vpforms.coils.library`, as problems (issue #20).

Both are vacuum magnetic fields of filamentary coils, traced in the toroidal coordinates
x = (u = R²/2, φ, Z) of unit Jacobian (:mod:`vpforms.toroidal`), and both are *exactly* divergence
free: the field is the curl of a vector potential, never an interpolated B.

* ``coil_stellarator`` — the classical l = 2, m = 5 stellarator (:func:`~vpforms.coils.l2_stellarator`):
  20 TF coils and two helical windings. The coils' Hanson–Hirshman A is sampled on an (R, φ, Z)
  grid over one field period and interpolated by a C² cubic spline in (u, φ, Z)
  (:func:`vpforms.grids.cylindrical_potential`); B = ∇×A of the spline, so the SE/DL pairs of all 36
  cases are exact splines. Magnetic axis at (R, Z) = (0.983112, 0) m at φ = 0, ι ≈ 0.31–0.40
  for lines 0.02–0.16 m outboard of it, confined region ending 0.17–0.18 m out (measured by
  tracing the coils directly; see :func:`~vpforms.coils.l2_stellarator`).
* ``coil_tokamak`` — the circular tokamak (:func:`~vpforms.coils.circular_tokamak`): 16 TF coils
  (splined as above over one of the 16 field periods) plus the plasma current as an exact
  circular filament ring at R0 (:class:`~vpforms.coils._ring.CircularRingPotential`, elliptic
  integrals): the ring is the magnetic axis and singular, so it is not splined (a spline would
  smear the singularity over the grid). Nested flux surfaces around the ring with q ≈ 0.5 at
  0.1 m to ≈ 4 at 0.3 m (the coil set's measured q; the exact ring has the same q to the
  polygon's O(1/M²)).

The default initial conditions are points on the outboard midplane (Z = 0, φ = 0) inside the
region of closed surfaces. The spline's own interpolation error (the difference between the
traced field and the coils' field) is reported in ``problem.params["spline_error"]``: max |B_spline −
B_coils| / max |B_coils| at points between the grid nodes.
"""

from __future__ import annotations

from functools import lru_cache

import jax
import numpy as np
from scipy.ndimage import maximum_filter
from scipy.spatial import cKDTree

from .._phases import phase
from .._vecpot import SumPotential, curl_of
from ..coils import CoilSet, circular_tokamak, l2_stellarator
from ..coils._ring import CircularRingPotential
from ..domains import ToroidalDomain
from ..grids import cylindrical_potential
from ..grids._quasi import quasi_reach
from ..grids._tolerance import DEFAULT_MAX_MEMORY, refine_to_tol, spline_nbytes
from ..toroidal import cartesian_field, to_toroidal, toroidal_field
from ._base import Problem

__all__ = ["default_stellarator", "default_tokamak", "make_stellarator", "make_tokamak"]

SOURCE = ("vacuum field of filamentary coils (Hanson & Hirshman, Phys. Plasmas 9, 4410 (2002)), "
          "A splined on a grid, B = curl A; coil sets built in vpforms.coils.library")


def _coil_values(coils, xyz, what) -> np.ndarray:
    """A or B of ``coils`` at the points xyz (N, 3) as NumPy: natively for a :class:`CoilSet` or
    :class:`~vpforms.coils.QuadratureCoils` (their ``evaluate``), else by its JAX ``A``/``B``."""
    if hasattr(coils, "evaluate"):
        return coils.evaluate(xyz, what)
    return np.asarray(coils.A(xyz) if what == "A" else coils.B(xyz))


def _sample_A(coils, R, phi, Z, mask=None) -> np.ndarray:
    """Physical cylindrical (A_R, A_φ, A_Z) of the coils at the grid nodes, shape (3, nR, nφ, nZ);
    where ``mask`` is given, at its kept nodes only (NaN elsewhere)."""
    RR, PP, ZZ = np.meshgrid(R, phi, Z, indexing="ij")
    keep = np.ones(RR.shape, bool) if mask is None else np.asarray(mask, bool)
    xyz = np.stack([RR[keep] * np.cos(PP[keep]), RR[keep] * np.sin(PP[keep]), ZZ[keep]], axis=-1)
    A = np.full(RR.shape + (3,), np.nan)
    A[keep] = _coil_values(coils, xyz, "A")
    c, s = np.cos(PP), np.sin(PP)
    return np.stack([A[..., 0] * c + A[..., 1] * s, -A[..., 0] * s + A[..., 1] * c, A[..., 2]])


def _spline_error(field, coils, extra_B, box_R, box_Z, nfp, seed=0, n=400, domain=None) -> float:
    """max |B_spline − B_coils| / max |B_coils| at seeded random points of the box (of the
    ``domain`` where one is given: uniform in its volume); ``field``: (u, φ, Z) points (n, 3) → the
    contravariant field there (a Field, or a SplinePotential's ``curl``)."""
    rng = np.random.default_rng(seed)
    if domain is None:
        pts = np.c_[rng.uniform(*box_R, n), rng.uniform(0, 2 * np.pi / nfp, n), rng.uniform(*box_Z, n)]
    else:
        pts = domain.sample(n, seed)
    xyz = pts[:, [0, 1, 2]].copy()
    xyz[:, 0], xyz[:, 1] = pts[:, 0] * np.cos(pts[:, 1]), pts[:, 0] * np.sin(pts[:, 1])
    B = _coil_values(coils, xyz, "B") + (0 if extra_B is None else extra_B(xyz))
    p = to_toroidal(xyz)
    return float(np.max(np.abs(np.asarray(cartesian_field(field(p), p)) - B)) / np.max(np.abs(B)))


def _x0(R_axis: float, offsets) -> np.ndarray:
    return np.asarray(to_toroidal(np.c_[R_axis + np.asarray(offsets), np.zeros(len(offsets)),
                                        np.zeros(len(offsets))]))


def spline_coil_field(coils: CoilSet, R: tuple, Z: tuple, *, n_R: int | None = None, n_phi: int | None = None,
                      n_Z: int | None = None, name: str = "coils", margin: float = 0.02,
                      domain: ToroidalDomain | None = None, pad: int = 2, degree: int = 3,
                      clearance: float | None = None, tol: float | None = None,
                      region: ToroidalDomain | None = None, max_memory: float = DEFAULT_MAX_MEMORY,
                      n_check: int = 1000, fit: str = "interpolate") -> tuple:
    """The field lines of a coil set in (u = R²/2, φ, Z): the coils' vector potential sampled on an
    n_R × n_phi × n_Z grid of the (R, Z) box over one field period and splined (exact
    antiderivatives, B = ∇×A exactly divergence free); returns (field, spline_error) with
    spline_error = max|B_spline − B_coils|/max|B_coils| at 400 seeded points of the box less
    ``margin`` (in the units of R and Z) on each side.

    With a ``domain`` (:class:`vpforms.domains.ToroidalDomain`, inside the box): a grid that
    follows it — A is sampled and fitted only on the nodes of the cells that meet the domain
    (dilated by ``pad`` nodes: :meth:`~vpforms.domains.ToroidalDomain.node_mask`) and on the
    whole φ line through each of them, but never within ``clearance`` of a coil wire (default: the
    smallest distance from those dilated cells' nodes to a wire: no node nearer a wire than they are), so coil wires elsewhere in
    the box never enter the fit. Whole φ lines: a stellarator's cross-section moves over a period
    (W7-X's by 0.7 m in R), so an (R, Z) node is in the domain for part of the period only, and
    lines cut into many short runs cost a fit each (4–8× the build time on W7-X at 96 planes)
    for no loss of accuracy inside the domain (measured on W7-X at 48 × 96 × 48: B errors ≤ 1.5e-5
    deeper than 0.3 m either way); nearer its edge the whole lines' nodes close to the wires cost
    accuracy (2e-3 instead of 2e-4 at 0.15–0.3 m; 4e-2 instead of 5e-3 at the edge). The field's :attr:`~vpforms.Field.domain`
    is the domain (its potentials are checked there, starting points must lie in it; a line
    that leaves it meets NaN cells, a non-finite step — trace with
    :func:`vpforms.fieldlines.trace_to_wall` and the domain to stop lines at it), and
    spline_error is measured at 400 points of the domain. ``degree``: the spline's degree per
    axis (≥ 3). ``coils``: a :class:`~vpforms.coils.CoilSet` or
    :class:`~vpforms.coils.QuadratureCoils` (``A(x)``, ``B(x)``, ``nfp``).

    ``tol`` (issue #39): the grid is chosen instead of given — :func:`vpforms.grids.refine_to_tol`
    builds grids (from ``n_R × n_phi × n_Z``, default 24 × 16 × 24) until max|B_spline −
    B_coils|/max|B_coils| at ``n_check`` seeded points of ``region`` (a
    :class:`~vpforms.domains.ToroidalDomain`: where the lines are; default ``domain``, else the box
    less ``margin``) is ≤ tol, each grid within ``max_memory`` bytes of coefficients;
    ``field.grid_choice`` (:class:`vpforms.grids.GridChoice`) reports the grid, the estimate and
    every round. Degree 5 reaches a given tol with far fewer nodes than degree 3 on coil fields (l = 2
    stellarator, on a 0.145 m tube about the axis: degree 5 reaches 1e-7 on 47 × 52 × 37 nodes, 2.4 MiB;
    degree 3 needs 97 × 64 × 75 nodes, 11 MiB, for 1e-6: ``benchmarks/peers/results_tol_grids.md``). Without ``tol`` the grid is 40 × 32 × 40 unless given.

    ``fit="quasi"`` (issue #38): the local quasi-interpolant of the same spline
    (:mod:`vpforms.grids._quasi`) on the **whole box**, coil wires inside it included — each
    coefficient from the k + 1 samples nearest it, so the large errors next to a wire stay in the
    cells there instead of spreading along the grid lines (the interpolant's, which is why the
    default grid follows the domain). With a ``domain`` (and no ``tol``) A is sampled and fitted only
    on the nodes within reach of the cells that meet it (:func:`~vpforms.grids._quasi.quasi_reach`:
    7 at degree 5), plane by plane
    (:meth:`~vpforms.domains.ToroidalDomain.node_mask`: the quasi-interpolant is local along φ too,
    so no whole φ lines) — every coefficient of a cell that meets the domain is the whole box's, to
    the bit, and the cells farther out are NaN (W7-X, 96 × 192 × 96: 1 144 200 nodes, 65 % of the
    box's, the coils' A sampled in 5.2–5.7 s instead of 8.1); with ``tol`` it is fitted on the whole box (a
    coarser sub-grid of the refinement would need a wider margin). W7-X, degree 5, inside the last
    closed surface: B error 1.1e-7 on 96 × 192 × 96 (the interpolant of the grid that follows the
    domain: 4e-6 at degree 3)."""
    if fit not in ("interpolate", "quasi"):
        raise ValueError(f"fit must be 'interpolate' or 'quasi', not {fit!r}")
    fit_kind = fit  # (the name `fit` is the fitting step below)
    nfp = coils.nfp
    if domain is not None:
        domain.check_within(R, Z, f"the grid of {name}")
    inner_R, inner_Z = (R[0] + margin, R[1] - margin), (Z[0] + margin, Z[1] - margin)

    def sample(g):  # A on the n_R × n_φ × n_Z grid (at the mask's nodes where a domain is given)
        Rn, Zn = np.linspace(*R, g[0]), np.linspace(*Z, g[2])
        phin = 2 * np.pi / nfp * np.arange(g[1]) / g[1]
        if domain is None or (fit_kind == "quasi" and tol is not None):
            mask = None
        elif fit_kind == "quasi":  # the nodes a cell's coefficients use (7 at degree 5)
            reach = max(quasi_reach(Rn, degree, None), quasi_reach(phin, degree, 2 * np.pi / nfp),
                        quasi_reach(Zn, degree, None))
            # a tensor stencil: the cube of that half-width about each kept node (node_mask's own
            # pad grows along one axis at a time per step, a diamond)
            mask = maximum_filter(domain.node_mask(Rn, phin, Zn, pad=0), size=2 * reach + 1,
                                  mode=("constant", "wrap", "constant"))
        else:
            mask = _domain_mask(coils, domain, Rn, phin, Zn, pad, clearance, name)
        with phase(f"sampling the vector potential of {name} at "  # issue #41: said, timed
                   f"{Rn.size * phin.size * Zn.size if mask is None else int(mask.sum()):,} grid nodes"):
            return (Rn, phin, Zn), _sample_A(coils, Rn, phin, Zn, mask), mask

    def fit(data, sub):  # the spline of those samples on the sub-grid sub (slices of the nodes)
        (Rn, phin, Zn), A, mask = data
        with phase(f"fitting the {Rn[sub[0]].size}×{phin[sub[1]].size}×{Zn[sub[2]].size} spline of A"):
            return cylindrical_potential(Rn[sub[0]], phin[sub[1]], Zn[sub[2]], nfp=nfp, A=A[(slice(None), *sub)],
                                         source=f"{name} coils", mask=None if mask is None else mask[sub],
                                         degree=degree, fit=fit_kind)[0]

    if tol is None:
        grid = (n_R or 40, n_phi or 32, n_Z or 40)
        pot = fit(sample(grid), (slice(None),) * 3)
    else:  # issue #39: the grid from the tolerance (vpforms.grids.refine_to_tol)
        where = region if region is not None else domain
        label = (f"the region {where.name!r}" if where is not None else
                 f"the box R ∈ [{inner_R[0]:g}, {inner_R[1]:g}], Z ∈ [{inner_Z[0]:g}, {inner_Z[1]:g}]")

        pot, choice = refine_to_tol(
            sample, fit, lambda pot: _spline_error(pot.curl, coils, None, inner_R, inner_Z, nfp, seed=1, n=n_check,
                                                   domain=where),
            (n_R or 25, n_phi or 16, n_Z or 25), degree=degree, tol=tol, periodic=(False, True, False),
            memory=spline_nbytes, max_memory=max_memory, n_check=n_check, region=label,
            what=f"spline of A of {name}")
    field = _coil_field(pot, nfp, name, domain)
    if tol is not None:
        field.grid_choice = choice
    with phase("measuring the spline's error against the coils at 400 points"):
        # the spline's curl in NumPy (the field's own B = ∇×A, not compiled again for this grid)
        err = _spline_error(pot.curl, coils, None, inner_R, inner_Z, nfp, domain=domain)
    return field, err


def _coil_field(pot, nfp, name, domain):
    """The field of :func:`spline_coil_field` from its spline of A."""
    field = toroidal_field(pot, pot.grid_box, nfp=nfp, name=name, origin=pot.center, domain=domain)
    # field.inside stays the grid's box test (native kernels emit that one): a step onto a cell
    # outside the domain's grid is non-finite (NaN coefficients), a reported failure; lines are
    # stopped at the domain itself by trace_to_wall(…, domain)
    field.domain_check, field.inside = _covers(pot), pot.inside
    if domain is not None:
        field.domain_check = lambda points: domain.check_points(points, toroidal=True)
    return field


def wire_points(coils, spacing: float = 0.01) -> np.ndarray:
    """Points (M, 3) along every coil wire no farther apart than ``spacing`` (m): the polylines'
    segments (a :class:`~vpforms.coils.CoilSet`) or the chords between a
    :class:`~vpforms.coils.QuadratureCoils`' points (within the curve's sagitta of it: ≤ 1 mm on
    the devices' curves), each subdivided evenly."""
    if hasattr(coils, "elements"):
        pts = coils.points_per_coil
        starts = np.concatenate(pts)
        ends = np.concatenate([np.roll(p, -1, axis=0) for p in pts])
    else:
        starts, ends = (np.asarray(a) for a in coils.segments()[:2])
    n = int(np.ceil(np.max(np.linalg.norm(ends - starts, axis=1)) / spacing))
    s = np.arange(n)[:, None, None] / n
    return (starts[None] + s * (ends - starts)[None]).reshape(-1, 3)


def _domain_mask(coils, domain: ToroidalDomain, R, phi, Z, pad: int, clearance: float | None, name: str) -> np.ndarray:
    """The nodes of a grid that follows ``domain`` (:func:`spline_coil_field`): the dilated cells
    that meet it, their whole φ lines, less the nodes within ``clearance`` of a wire."""
    near_domain = domain.node_mask(R, phi, Z, pad=pad)
    RR, PP, ZZ = np.meshgrid(R, phi, Z, indexing="ij")
    xyz = np.stack([RR * np.cos(PP), RR * np.sin(PP), ZZ], axis=-1).reshape(-1, 3)
    d_wire = cKDTree(wire_points(coils)).query(xyz)[0].reshape(RR.shape)
    if clearance is None:
        clearance = float(np.min(d_wire[near_domain]))
    if not (isinstance(clearance, (int, float)) and np.isfinite(clearance) and clearance >= 0):
        raise ValueError(f"clearance must be a distance ≥ 0 (m); got {clearance!r}")
    keep = near_domain.any(axis=1, keepdims=True) & (d_wire >= clearance)
    if np.any(near_domain & ~keep):
        i = np.argwhere(near_domain & ~keep)[0]
        raise ValueError(f"{name}: a coil wire lies within clearance = {clearance:.3g} m of the grid node "
                         f"(R, φ, Z) = ({R[i[0]]:.6g}, {phi[i[1]]:.6g}, {Z[i[2]]:.6g}) next to the domain: "
                         "lower the clearance or use a domain farther from the coils")
    return keep


def make_stellarator(*, n_R: int = 40, n_phi: int = 32, n_Z: int = 40, R: tuple = (0.80, 1.18),
                     Z: tuple = (-0.18, 0.18), **coil_params) -> Problem:
    """The l = 2 stellarator's field lines (module docstring); ``coil_params`` go to
    :func:`vpforms.coils.l2_stellarator`, the grid is n_R × n_phi × n_Z nodes over one period."""
    coils = l2_stellarator(**coil_params)
    nfp = coils.nfp
    field, err = spline_coil_field(coils, R, Z, n_R=n_R, n_phi=n_phi, n_Z=n_Z, name="coil_stellarator")
    return Problem(
        name="coil_stellarator", field=field,
        params={"grid": f"{n_R}x{n_phi}x{n_Z}", "spline_error": err, "nfp": nfp, **coil_params},
        x0=_x0(0.983112, [0.02, 0.04, 0.08, 0.12, 0.14]),
        invariants={}, invariant_exprs={}, source=SOURCE,
        periodic=(None, 2 * np.pi / nfp, None), box=field.box,
        description="l = 2, m = 5 stellarator coils: field lines in (u = R²/2, φ, Z)",
        sampler=_midplane_sampler(0.983112, 0.02, 0.14),
        axis_guess=(0.983112, 0.0),
    )


def make_tokamak(*, n_R: int = 48, n_phi: int = 12, n_Z: int = 48, R: tuple = (0.58, 1.42),
                 Z: tuple = (-0.40, 0.40), **coil_params) -> Problem:
    """The circular tokamak's field lines (module docstring): its TF (and VF) coils splined, its
    plasma-current ring exact; ``coil_params`` go to :func:`vpforms.coils.circular_tokamak`."""
    all_coils = circular_tokamak(**coil_params)
    ring = [c for c in all_coils if c.name == "plasma"]
    if len(ring) != 1:
        raise RuntimeError(f"expected one plasma-current ring in the coil set; found {len(ring)}")
    rest = CoilSet([c for c in all_coils if c is not ring[0]], nfp=all_coils.nfp)
    pts = np.asarray(ring[0].points)
    # the circle the ring polygon is inscribed in
    R_ring, z_ring = float(np.max(np.hypot(pts[:, 0], pts[:, 1]))), float(np.mean(pts[:, 2]))
    exact_ring = CircularRingPotential(R_ring, float(ring[0].current), z_ring)
    nfp = rest.nfp
    Rn, Zn = np.linspace(*R, n_R), np.linspace(*Z, n_Z)
    phin = 2 * np.pi / nfp * np.arange(n_phi) / n_phi
    pot, _ = cylindrical_potential(Rn, phin, Zn, nfp=nfp, A=_sample_A(rest, Rn, phin, Zn),
                                   source="circular_tokamak TF coils")
    A = SumPotential([pot, exact_ring], periods=pot.periods)
    field = toroidal_field(A, pot.grid_box, nfp=nfp, name="coil_tokamak", origin=pot.center)
    field.domain_check, field.inside = _covers(pot), pot.inside
    err = _spline_error(field, rest, _ring_B(exact_ring), (0.7, 1.3), (-0.3, 0.3), nfp)
    return Problem(
        name="coil_tokamak", field=field,
        params={"grid": f"{n_R}x{n_phi}x{n_Z}", "spline_error": err, "nfp": nfp, **coil_params},
        x0=_x0(R_ring, [0.10, 0.15, 0.20, 0.25, 0.30]),
        invariants={}, invariant_exprs={}, source=SOURCE,
        periodic=(None, 2 * np.pi / nfp, None), box=pot.grid_box,
        description="circular tokamak coils + exact plasma ring: field lines in (u = R²/2, φ, Z)",
        sampler=_midplane_sampler(R_ring, 0.10, 0.30),
        axis_guess=(R_ring, z_ring),
    )


def _ring_B(ring: CircularRingPotential):
    """Cartesian B of the exact ring (curl of its covariant potential, back in Cartesian)."""
    curl = jax.jit(jax.vmap(curl_of(ring.components())))

    def B(xyz):
        p = to_toroidal(xyz)
        return np.asarray(cartesian_field(curl(p), p))

    return B


def _covers(pot):
    def check(points):
        pot.check_covers(points, what="starting point", names=("u", "φ", "Z"))

    return check


def _midplane_sampler(R_axis: float, lo: float, hi: float):
    def sample(rng, n):
        return _x0(R_axis, rng.uniform(lo, hi, n)) if n else np.zeros((0, 3))

    return sample


@lru_cache(maxsize=1)
def default_stellarator() -> Problem:
    return make_stellarator()


@lru_cache(maxsize=1)
def default_tokamak() -> Problem:
    return make_tokamak()


"""Gridded magnetic fields as vpforms Fields: a spline of A on an (R, φ, Z) or (x, y, z) grid.

Toroidal grids (mgrid files, :func:`cylindrical_potential`) are used in the unit-Jacobian
coordinates (u = R²/2, φ, Z) of :mod:`vpforms.toroidal`: the covariant components

    A_u = A_R / R,    A_φ = R A_φ^(phys),    A_Z = A_Z

are interpolated at the nodes u_i = R_i²/2 (non-uniform in u), φ periodic with period 2π/nfp, and
B = ∇×A is exactly divergence free as a function. Where only B is given, A is built in the gauge

    A_u = 0,   A_Z = −∫_{u₀}^{u} a^φ du',   A_φ = ∫_{u₀}^{u} a^Z du' − ∫_{Z₀}^{Z} a^u(u₀, φ, Z') dZ'

(a = (R B_R, B_φ/R, B_Z) contravariant, u₀ = R_min²/2, Z₀ = Z_min), each line integral exact for
the cubic spline of the B samples along the grid line. Its curl is (a^u, a^φ, a^Z) exactly when
∇·a = 0: ∂_φA_Z − ∂_ZA_φ = −∫(∂_φa^φ + ∂_Za^Z) du' + a^u(u₀) = a^u, −∂_uA_Z = a^φ,
∂_uA_φ = a^Z. A B that is not divergence free on the grid cannot be represented exactly by a
curl: the mismatch max |∇×A − B| / max |B| at the grid nodes is measured and reported.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import make_interp_spline

from ..fields import Field
from ..toroidal import toroidal_field
from ._bspline import degree_name
from ._spline_potential import SplinePotential
from .mgrid import GridFileError, MGrid, read_mgrid

__all__ = [
    "CURL_MISMATCH_LIMIT", "CurlMismatchError", "GridReport", "GridWarning", "cartesian_grid_field",
    "cylindrical_potential", "gridded_field",
]

_TOROIDAL_NAMES = ("u = R²/2", "φ", "Z")


class GridWarning(UserWarning):
    """A gridded field built from B alone (A in a stated gauge, with the measured mismatch)."""


class CurlMismatchError(ValueError):
    """The B of a grid is not the curl of its A (:data:`CURL_MISMATCH_LIMIT`)."""


#: the largest max|∇×A − B| accepted from a grid that gives both, relative to the field's scale
#: (the smaller of max|B| and max|∇×A|): the spline's interpolation error of ∇×A at the nodes is far
#: below it on any usable grid (1e-3 on 16³ nodes); a corrupt value of B or A gives O(1) or more
CURL_MISMATCH_LIMIT = 0.05


@dataclass(frozen=True)
class GridReport:
    """How a gridded potential was built.

    Attributes
    ----------
    source:
        ``"A"`` (interpolated vector-potential samples) or ``"B"`` (A integrated from B).
    gauge:
        The gauge of A: ``"as given"`` or the formula used.
    curl_error:
        max |∇×A − B| / max |B| over the grid nodes (NaN when no B samples were given).
    message:
        One paragraph for people (also the warning's text when ``source == "B"``).
    """

    source: str
    gauge: str
    curl_error: float
    message: str

    def __str__(self) -> str:
        return self.message


_GAUGE_FROM_B = ("A_u = 0, A_Z = −∫_{u0}^{u} a^φ du, A_φ = ∫_{u0}^{u} a^Z du − ∫_{Z0}^{Z} "
                 "a^u(u0, φ, Z') dZ' (a = (R B_R, B_φ/R, B_Z), u0 = R_min²/2, Z0 = Z_min)")


def _cumulative(x: np.ndarray, y: np.ndarray, axis: int, k: int) -> np.ndarray:
    """∫_{x₀}^{x_i} y dx at the nodes along ``axis``: exact for the degree-k interpolating spline."""
    F = make_interp_spline(x, y, k=k, axis=axis).antiderivative()
    return F(x) - np.expand_dims(F(x[0]), axis)


def _check_axis(name: str, x: Any) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 1 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
        raise ValueError(f"the {name} nodes must be a finite strictly increasing 1-D array")
    return x


def cylindrical_potential(R: Any, phi: Any, Z: Any, *, nfp: int = 1, A: Any = None,
                          B: Any = None, degree: int = 3, source: str = "grid",
                          warn: bool = True, curl_tol: float | None = CURL_MISMATCH_LIMIT,
                          mask: Any = None, fit: str = "interpolate") -> tuple[SplinePotential, GridReport]:
    """The spline potential in (u = R²/2, φ, Z) of a field sampled on a cylindrical grid.

    Parameters
    ----------
    R, phi, Z:
        Node arrays; R > 0; ``phi`` covers one field period 2π/nfp without its endpoint (uniform
        or not; one plane means axisymmetric).
    A, B:
        Physical cylindrical components (A_R, A_φ, A_Z) / (B_R, B_φ, B_Z), shape
        (3, len(R), len(phi), len(Z)). With A, its covariant components are interpolated (B,
        if given, is compared with ∇×A at the nodes: a :class:`CurlMismatchError` names the node
        where they differ by more than ``curl_tol`` (default :data:`CURL_MISMATCH_LIMIT`; None:
        no check) times the field's scale); with B alone, A is integrated along grid lines in
        the gauge of the module docstring and a :class:`GridWarning` reports the mismatch.
    source:
        A name for messages (the file).
    mask:
        Bool (len(R), len(phi), len(Z)): the nodes a grid that follows a domain keeps
        (:meth:`vpforms.domains.ToroidalDomain.node_mask`; with ``A`` only): A may be NaN
        elsewhere, each grid line is fitted on its runs of kept nodes, and the spline is NaN on
        the cells they do not cover (:mod:`vpforms.grids._masked`).
    fit:
        "interpolate" (the interpolating spline) or "quasi": the local quasi-interpolant of the
        same spline (:mod:`vpforms.grids._quasi`) — for samples next to singularities (coil wires
        in the box), whose errors the interpolant spreads along whole grid lines.

    Returns
    -------
    (SplinePotential, GridReport)
    """
    R, phi, Z = _check_axis("R", R), _check_axis("φ", phi), _check_axis("Z", Z)
    if not R[0] > 0:
        raise ValueError(f"{source}: R must be > 0 (got R_min = {R[0]!r})")
    if isinstance(nfp, bool) or int(nfp) != nfp or nfp < 1:
        raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
    T = 2 * np.pi / int(nfp)
    shape = (3, R.size, phi.size, Z.size)
    keep = None if mask is None else np.asarray(mask, dtype=bool)
    if keep is not None and (keep.shape != shape[1:] or A is None or B is not None or phi.size == 1):
        raise ValueError(f"{source}: a mask needs A alone (no B), more than one φ plane and the grid's "
                         f"shape {shape[1:]}; got mask {keep.shape}, A {'given' if A is not None else 'None'}, "
                         f"B {'given' if B is not None else 'None'}, {phi.size} plane(s)")
    A = None if A is None else np.asarray(A, dtype=float)
    B = None if B is None else np.asarray(B, dtype=float)
    for what, arr in (("A", A), ("B", B)):
        if arr is not None:
            if arr.shape != shape:
                raise ValueError(f"{source}: {what} must have shape (3, nR, nφ, nZ) = {shape}; "
                                 f"got {arr.shape}")
            kept = np.ones(arr.shape[1:], bool) if keep is None else keep
            if not np.all(np.isfinite(arr[:, kept])):
                c, i, k, j = (int(v) for v in np.argwhere(~np.isfinite(arr) & kept[None])[0])
                raise ValueError(f"{source}: {what} has a non-finite value ({arr[c, i, k, j]}) in "
                                 f"{what}_{'RφZ'[c]} at the node R = {_g(R[i])}, φ = {_g(phi[k])}, "
                                 f"Z = {_g(Z[j])} (a coil wire through the grid?)")
    if A is None and B is None:
        raise ValueError("give the vector potential A or the field B on the grid")
    if phi.size == 1:  # axisymmetric: constant in φ — any number of identical planes is exact
        phi = phi[0] + T * np.arange(degree + 1) / (degree + 1)
        A = None if A is None else np.repeat(A, degree + 1, axis=2)
        B = None if B is None else np.repeat(B, degree + 1, axis=2)
    for name, n, need in (("R", R.size, degree + 1), ("φ", phi.size, degree),
                          ("Z", Z.size, degree + 1)):
        if n < need:
            raise ValueError(f"{source}: a {degree_name(degree)} spline needs ≥ {need} {name} "
                             f"nodes; the grid has {n}")
    u = 0.5 * R * R
    Rb = R[:, None, None]
    if A is not None:
        cov = np.stack([A[0] / Rb, Rb * A[1], A[2]])  # (A_R/R, R A_φ, A_Z)
        how, gauge = "A", "as given"
    else:
        a_u, a_phi, a_Z = Rb * B[0], B[1] / Rb, B[2]  # contravariant (u̇, φ̇, Ż)
        I_phi = _cumulative(u, a_phi, 0, degree)  # ∫_{u0}^{u} a^φ du'
        I_Z = _cumulative(u, a_Z, 0, degree)  # ∫_{u0}^{u} a^Z du'
        J = _cumulative(Z, a_u[0], 1, degree)  # ∫_{Z0}^{Z} a^u(u0, φ, Z') dZ'
        cov = np.stack([np.zeros_like(a_u), I_Z - J[None], -I_phi])
        how, gauge = "B", _GAUGE_FROM_B
    grid = "×".join(map(str, (R.size, phi.size, Z.size)))
    desc = (f"{degree_name(degree)} spline of A on a {grid} (u = R²/2, φ, Z) grid"
            + (" (A integrated from B)" if how == "B" else ""))
    if keep is not None:
        desc += f" (on the {int(keep.sum())} of {keep.size} nodes of a domain)"
    if fit == "quasi":
        desc += " (local quasi-interpolant)"
    pot = SplinePotential.from_samples((u, phi, Z), cov, periodic=(False, T, False),
                                       degree=degree, description=desc, mask=keep, fit=fit)
    #: the (R, φ, Z) box of the grid (for messages)
    pot.cylindrical_box = ((float(R[0]), float(R[-1])), (float(phi[0]), float(phi[0] + T)),
                           (float(Z[0]), float(Z[-1])))
    check = curl_tol if (A is not None and B is not None) else None
    err = float("nan") if B is None else _curl_mismatch(pot, u, phi, Z, B, check, source)
    if how == "A":
        msg = (f"{source}: {desc}; the vector potential was given"
               + ("" if B is None else f"; max|∇×A − B|/max|B| at the grid nodes = {err:.3g}"))
    else:
        msg = (f"{source}: the file has no vector potential (ar_/ap_/az_), so A was built from B "
               f"by integrating along grid lines in the gauge {gauge}; max|∇×A − B|/max|B| at "
               f"the grid nodes = {err:.3g}. A B that is not divergence free on the grid cannot "
               "be represented exactly as a curl: this number measures that mismatch together "
               "with the spline's interpolation error.")
        if warn:
            warnings.warn(msg, GridWarning, stacklevel=2)
    return pot, GridReport(how, gauge, err, msg)


def _node_curls(pot: SplinePotential, u: np.ndarray, phi: np.ndarray, Z: np.ndarray,
                B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nodes (N, 3) in (u, φ, Z), ∇×A of the spline and the given B at them (N, 3) in physical
    cylindrical components (B_R, B_φ, B_Z)), nodes in the order of B's (R, φ, Z) axes."""
    mesh = np.meshgrid(u, phi, Z, indexing="ij")
    pts = np.stack([m.ravel() for m in mesh], axis=-1)
    a = pot.curl(pts)  # contravariant (a^u, a^φ, a^Z)
    R = np.sqrt(2.0 * pts[:, 0])
    Bs = np.stack([a[:, 0] / R, a[:, 1] * R, a[:, 2]], axis=-1)  # (B_R, B_φ, B_Z)
    return pts, Bs, np.moveaxis(B, 0, -1).reshape(-1, 3)


def _curl_mismatch(pot: SplinePotential, u: np.ndarray, phi: np.ndarray, Z: np.ndarray,
                   B: np.ndarray, tol: float | None = None, source: str = "grid") -> float:
    """max |∇×A − B| / max |B| over the nodes, in physical cylindrical components.

    With ``tol``: :class:`CurlMismatchError` when max |∇×A − B| > tol · min(max |B|, max |∇×A|) —
    the smaller scale, so that one absurd value of either (B = 1e300 in a cell) cannot set the
    scale it is measured against — naming the node where they differ most."""
    pts, Bs, Bn = _node_curls(pot, u, phi, Z, B)
    diff = np.max(np.abs(Bs - Bn), axis=1)
    tiny = np.finfo(float).tiny
    err = float(np.max(diff) / max(float(np.max(np.abs(Bn))), tiny))
    if tol is not None:
        scale = max(min(float(np.max(np.abs(Bn))), float(np.max(np.abs(Bs)))), tiny)
        n = int(np.argmax(diff))
        if diff[n] > tol * scale:
            raise CurlMismatchError(
                f"{source}: B disagrees with ∇×A of the interpolated vector potential at the node R = "
                f"{_g(np.sqrt(2 * pts[n, 0]))}, φ = {_g(pts[n, 1])}, Z = {_g(pts[n, 2])}: B = ({', '.join(map(_g, Bn[n]))}), "
                f"∇×A = ({', '.join(map(_g, Bs[n]))}), |∇×A − B| = {diff[n]:.3g} > {tol:g} × {scale:.3g} "
                f"(CURL_MISMATCH_LIMIT × the field's scale): the file's A and B are not one field (a corrupt "
                "value?); gridded_field(..., use_A=False) builds A from B alone")
    return err


def _g(v: float) -> str:
    return f"{float(v):.6g}"




def gridded_field(source: MGrid | str | os.PathLike, currents: Sequence[float] | None = None, *,
                  extcur: Sequence[float] | None = None, use_A: bool = True, degree: int = 3,
                  name: str | None = None, box: Any = None, **kw: Any) -> Field:
    """The field-line flow of an mgrid (an :class:`MGrid` or a file) as a vpforms Field in the
    toroidal coordinates (u = R²/2, φ, Z) of :mod:`vpforms.toroidal`.

    The coil groups are summed with :meth:`MGrid.total` (``currents`` / ``extcur``). The file's
    vector potential is interpolated when it has one (``use_A``), else A is integrated from B
    (:func:`cylindrical_potential`: a :class:`GridWarning` says so, with the mismatch); when the file
    has both, a B that is not ∇×A (beyond :data:`CURL_MISMATCH_LIMIT`) is a :class:`GridFileError`
    naming the file, the coil group and the node. ``box``
    defaults to the grid's (u, φ, Z) box, the gauge origin to the grid's centre; further keywords
    go to :meth:`vpforms.Field.from_vector_potential`.

    The Field carries ``grid_potential`` (the SplinePotential), ``grid_report``
    (:class:`GridReport`) and ``check_covers(points)`` (ValueError for a point off the grid).
    Outside the grid the field is NaN (a per-particle failure in the integrator).
    """
    label = "mgrid"
    if not isinstance(source, MGrid):
        label = os.fspath(source)
        source = read_mgrid(source)
    mg = source
    B = np.transpose(mg.total(currents, extcur=extcur), (0, 3, 1, 2))  # (3, ir, kp, jz)
    A = None
    if use_A and mg.A is not None:
        A = np.transpose(mg.total(currents, extcur=extcur, potential=True), (0, 3, 1, 2))
    try:
        pot, report = cylindrical_potential(mg.R, mg.phi, mg.Z, nfp=mg.nfp, A=A, B=B, degree=degree,
                                            source=label, warn=False)
    except CurlMismatchError as exc:
        raise GridFileError(_mismatched_group(mg, label, degree, exc)) from None
    if report.source == "B":
        warnings.warn(report.message, GridWarning, stacklevel=2)
    kw.setdefault("origin", pot.center)
    field = toroidal_field(pot, box if box is not None else pot.grid_box, nfp=mg.nfp,
                           name=name or f"mgrid field ({os.path.basename(label)})", **kw)
    return _attach(field, pot, report, _TOROIDAL_NAMES)


def _mismatched_group(mg: MGrid, label: str, degree: int, exc: CurlMismatchError) -> str:
    """The message of a summed field whose B is not ∇×A, naming the first coil group whose own B
    is not the curl of its own A (the sum's message when each group alone passes)."""
    for g in range(mg.nextcur):
        A = np.transpose(mg.A[g], (0, 3, 1, 2))
        B = np.transpose(mg.B[g], (0, 3, 1, 2))
        try:
            cylindrical_potential(mg.R, mg.phi, mg.Z, nfp=mg.nfp, A=A, B=B, degree=degree,
                                  source=f"{label}, coil group {g + 1} ({mg.names[g]})", warn=False)
        except CurlMismatchError as group_exc:
            return str(group_exc)
    return str(exc)


def cartesian_grid_field(nodes: Sequence[Any], A: Any, *, degree: int = 3,
                         name: str = "gridded field", box: Any = None, **kw: Any) -> Field:
    """The field ∇×A of Cartesian samples A (shape (3, n₁, n₂, n₃)) on the tensor grid
    ``nodes`` (nothing periodic), as a vpforms Field (box: the grid's; gauge origin: its
    centre; further keywords go to :meth:`vpforms.Field.from_vector_potential`)."""
    pot = SplinePotential.from_samples(nodes, A, periodic=(False, False, False), degree=degree)
    kw.setdefault("origin", pot.center)
    field = Field.from_vector_potential(pot, box=box if box is not None else pot.grid_box,
                                        name=name, **kw)
    msg = f"{pot.description}; the vector potential was given"
    return _attach(field, pot, GridReport("A", "as given", float("nan"), msg), ("x", "y", "z"))


def _attach(field: Field, pot: SplinePotential, report: GridReport, names: Sequence[str]) -> Field:
    field.grid_potential = pot
    field.grid_report = report

    cyl = getattr(pot, "cylindrical_box", None)
    note = "" if cyl is None else f" (R ∈ [{cyl[0][0]:.6g}, {cyl[0][1]:.6g}])"

    def check_covers(points: Any) -> None:
        """ValueError naming the first point (shape (3,) or (N, 3)) the grid does not cover."""
        pot.check_covers(points, what="starting point", names=names, note=note)

    field.check_covers = check_covers
    field.domain_check = check_covers  # integrate() refuses starting points off the grid
    field.inside = pot.inside  # a line that leaves the grid stops with RESULTS.left_domain
    return field

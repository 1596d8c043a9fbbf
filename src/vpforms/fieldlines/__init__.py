"""Field-line studies of toroidal fields (issue #21): what a fusion user does with a traced field.

* :func:`toroidal_section` — Poincaré sections at φ = φ₀ (mod 2π/nfp) in (R, Z), for fields in
  Cartesian coordinates (major axis x₃) or in the toroidal coordinates (u = R²/2, φ, Z) of
  :mod:`vpforms.toroidal`, crossings located on the method's own step family;
* :func:`return_map` — the φ-return map P of a method, differentiable (exact Jacobian of the discrete
  map); :func:`magnetic_axis` (fixed point of P, its type and ι from the tangent map),
  :func:`island_chain` / :func:`scan_fixed_points` / :func:`find_fixed_point` (O- and X-points of
  Pᵐ, Greene's residue);
* :func:`rotational_transform` / :func:`iota_profile` — ι (and q) of traced lines by weighted
  Birkhoff averages (super-polynomial convergence on invariant tori), with an error estimate;
* :class:`Wall` / :func:`trace_to_wall` — an (R, Z) polygon wall: lines stop where they leave it
  (status ``left_domain``), with the exit point on the wall, the connection length and transits;
* :func:`connection_length` — each line traced both ways to a wall: L_c = L_fwd + L_bwd, or a
  lower bound with its own status where the wall is not reached; in process or on Dask workers;
  :func:`start_grid` — starting points on an (R, Z) grid of a section, near the wall.

Every study takes any vpforms method (``step_with_status``) of the field, so it inherits the
method's exact volume preservation: invariant circles of the discrete map stay thin.
"""

from __future__ import annotations

from ._connection import ConnectionLengths, StartGrid, connection_length, start_grid
from ._fixedpoints import FixedPoint, find_fixed_point, magnetic_axis
from ._geometry import cylindrical, is_toroidal
from ._islands import island_chain, scan_fixed_points
from ._iota import AxisCurve, Iota, axis_curve, birkhoff_weight, iota_profile, rotational_transform
from ._returnmap import ReturnMap, return_map
from ._sections import ToroidalSection, toroidal_section
from ._wall import Wall, WallHits, trace_to_wall

__all__ = [
    "AxisCurve",
    "ConnectionLengths",
    "FixedPoint",
    "Iota",
    "ReturnMap",
    "StartGrid",
    "ToroidalSection",
    "Wall",
    "WallHits",
    "axis_curve",
    "birkhoff_weight",
    "connection_length",
    "cylindrical",
    "find_fixed_point",
    "iota_profile",
    "is_toroidal",
    "island_chain",
    "magnetic_axis",
    "return_map",
    "rotational_transform",
    "scan_fixed_points",
    "start_grid",
    "toroidal_section",
    "trace_to_wall",
]

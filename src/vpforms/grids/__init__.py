"""Gridded magnetic fields: splines of the vector potential A, exactly divergence-free B = ∇×A.

A field known on a grid (an mgrid file of STELLOPT's MAKEGRID, samples of A on an (R, φ, Z) or
(x, y, z) grid) becomes a vpforms :class:`~vpforms.Field` by interpolating the *vector potential*
A — not B — with a C² tensor-product spline (cubic by default) and taking B = ∇×A analytically:
B is then exactly divergence free as a function everywhere (the divergence of a curl; at rounding
level in floating point), which is what the volume-preserving methods need, and the SE/DL pairs
of :mod:`vpforms._vecpot` are exact splines too (the antiderivative of a B-spline along one axis is
a B-spline of one degree more), so ``exact_gauge`` holds. Interpolating B instead would make ∇·B
an O(h³) interpolation error that no volume-preserving integrator can undo.

What was chosen, and why:

* **Own JAX tensor B-spline** (:class:`TensorSpline`): it must run under ``jax.jit``,
  ``jax.vmap`` and ``jax.jacfwd``/``jax.grad`` to second and third order (Newton solves
  differentiate B = ∇×A), and later be evaluated by generated C with its data passed at run time —
  so evaluation is a pure function of arrays (knots, per-cell basis polynomials, coefficients;
  :func:`~vpforms.grids._bspline.evaluate`; the spline is a pytree). Per axis: the knot interval
  by ``jnp.searchsorted``, the degree+1 non-zero B-splines as polynomials of the cell (Cox–de Boor
  run once per cell at construction), the coefficient block by ``jax.lax.dynamic_slice``. A custom
  JVP maps ∂/∂x_a to the derivative order + e_a, so every derivative is the exact derivative of
  the cell polynomial with a compact program. Periodic axes (φ) wrap; outside a non-periodic
  axis's range the value and every derivative are NaN, never an extrapolation.
* **scipy only for fitting** (``make_interp_spline`` axis by axis: not-a-knot or periodic ends;
  ``BSpline.antiderivative``); non-uniform knots are allowed, since toroidal grids are interpolated
  in u = R²/2 (:mod:`vpforms.toroidal`) at the nodes u_i = R_i²/2.
* **netCDF through scipy.io** (:mod:`vpforms.grids.mgrid`): NetCDF3 classic/64-bit offset without
  a new dependency; NetCDF4 files are read when h5netcdf or netCDF4 happens to be installed.
* **Files with B only**: A is integrated along grid lines in a stated gauge, and the mismatch
  max |∇×A − B| / max |B| at the nodes is returned (:class:`GridReport`) and warned about
  (:class:`GridWarning`): a B that is not divergence free on the grid cannot be represented exactly.

Public API: :class:`TensorSpline`, :class:`PeriodicAntiderivative`, :class:`SplinePotential`,
:class:`MGrid`, :func:`read_mgrid`, :func:`write_mgrid`, :class:`GridFileError`,
:func:`cylindrical_potential`, :func:`gridded_field`, :func:`cartesian_grid_field`,
:class:`GridReport`, :class:`GridWarning`; :func:`refine_to_tol`, :class:`GridChoice` (a grid from a
tolerance: issue #39).
"""

from .. import _config  # noqa: F401  (float64)
from ._bspline import PeriodicAntiderivative, TensorSpline
from ._field import (
    GridReport,
    GridWarning,
    cartesian_grid_field,
    cylindrical_potential,
    gridded_field,
)
from ._spline_potential import SplinePotential
from ._tolerance import GridChoice, GridRound, refine_to_tol
from .mgrid import GridFileError, MGrid, read_mgrid, write_mgrid

__all__ = [
    "GridChoice",
    "GridFileError",
    "GridReport",
    "GridRound",
    "GridWarning",
    "MGrid",
    "PeriodicAntiderivative",
    "SplinePotential",
    "TensorSpline",
    "cartesian_grid_field",
    "cylindrical_potential",
    "gridded_field",
    "read_mgrid",
    "refine_to_tol",
    "write_mgrid",
]

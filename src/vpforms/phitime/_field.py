"""The φ-time field of a vector potential, and the point maps (u, φ, Z) ↔ (v, φ, Z)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

from .._fieldops import _lambdify_scalar
from .._phases import phase
from .._quadrature import DEFAULT_N
from .._vecpot import CallablePotential, VectorPotential
from ..fields import Field
from ..toroidal import ToroidalPotential
from ._coordinates import PhiTimeCoordinates, PhiTimePotential
from ._spline import spline_phi_time_field
from ._symbolic import NoClosedForm, is_sympy_potential, symbolic_phi_time_field

__all__ = ["from_phi_time", "phi_time_field", "to_phi_time"]

Scalar = Callable[..., Any]


def phi_time_field(A: VectorPotential | Callable[[Any], Any], box: Any = None, *, nfp: int | None = None,
                   u_ref: float | None = None, inverse: Scalar | None = None, a_u: str = "auto",
                   margin: float = 0.02, n_check: int = 17, name: str = "phi-time field",
                   symbols: Sequence[sp.Symbol] | None = None, grid: Sequence[int] | None = None,
                   degree: int = 3, level_v: str | None = None, domain: Any = None, **kw: Any) -> Field:
    """The field-line flow of ∇×A with φ as the time, as a :class:`~vpforms.Field` in (v, φ, Z).

    ``A``: a (u, φ, Z) :class:`~vpforms._vecpot.VectorPotential` (e.g.
    ``vpforms.toroidal.ToroidalPotential(A_cartesian, nfp)``) or a Cartesian A(x) (wrapped in one,
    with ``nfp``); ``box``: the (u, φ, Z) box (:func:`vpforms.toroidal.box_from_cylindrical`) on which
    B^φ keeps one sign (else :class:`PhiTimeError`, checked on an ``n_check``³ grid) — the Newton
    bracket of U and the domain of the field. ``u_ref``: the base of χ = ∫_{u_ref}^u A_u (default
    the u midpoint; with a ``domain``, the domain's centroid curve u_c(φ)); ``a_u``: "auto" (χ = 0 if A_u vanishes to 1e-14 relative on the grid, else
    quadrature), "zero" or "quadrature"; ``inverse``: a closed-form U(v, φ, Z) (checked) instead of
    Newton; ``margin``: the fraction of the v range dropped at each end of the (v, φ, Z) box.
    Further keywords go to :meth:`vpforms.Field.from_vector_potential` (``origin`` defaults to
    (v_mid, φ_min, Z_mid) of the (v, φ, Z) box).

    ``A`` may also be a :class:`~vpforms.Field` in (u, φ, Z) made from one vector potential (e.g.
    :func:`vpforms.toroidal.toroidal_field` of a spline of A, or ``spline_coil_field``): its potential
    is used.

    ``domain`` (a :class:`~vpforms.domains.ToroidalDomain`, issue #38): φ as the time on a region
    that follows the plasma instead of the box — B^φ's sign is required there only (a real
    stellarator's box holds coils, next to which B^φ changes sign), U is bracketed by the domain's
    chords, and with a ``grid`` K is fitted on the domain's image only
    (:class:`PhiTimeCoordinates`, :mod:`vpforms.phitime._spline`). Each horizontal line of a
    cross-section must meet it in one interval.

    ``level_v`` ("auto", "yes", "no"; default "auto" with a ``grid``, else "no"): subtract the residual
    gauge χ₀(φ, Z) = ∫_{Z_mid}^Z A_Z(u_ref, φ, Z') dZ' so that v = 0 on the surface u = u_ref. A's own
    gauge (Biot–Savart's, a spline's) can make v(u, φ, Z) so ragged in (φ, Z) that the largest (v, φ, Z)
    rectangle in the image of the box misses lines inside it; levelled, v is the toroidal flux from
    u = u_ref and the rectangle is nearly the whole box.

    ``grid`` = (n_v, n_φ, n_Z): K is sampled on that tensor grid of the (v, φ, Z) box and splined
    (degree ``degree``), so the field is a spline field that **runs natively** whatever A is (a spline
    of A, coils): :mod:`vpforms.phitime._spline`. It is still exactly divergence free; it differs
    from the exact φ-time field by the interpolation error of K, ``field.phi_time_spline_error``.
    ``tol=`` (with ``region=``, ``max_memory=``; :func:`~vpforms.phitime.spline_phi_time_field`)
    chooses that grid from a tolerance on b instead (``grid``, if given, is the first one tried).

    ``A`` may also be three **SymPy expressions** (A_u, A_φ, A_Z) in ``symbols`` = (u, φ, Z) (default:
    its free symbols named u, phi, Z; :func:`toroidal_potential_exprs` converts a Cartesian one;
    ``nfp`` the period 2π/nfp of φ, default 1). Then χ, U and K are found by SymPy where it can
    (:mod:`vpforms.phitime._symbolic`) and the field is a closed-form :meth:`~vpforms.Field.from_sympy`
    field: every backend steps it, the native C kernels included. Where SymPy finds no χ or U within
    its budget, the field is built from the lambdified potential as above (JAX only) and a
    ``UserWarning`` says why; ``inverse`` and ``a_u`` apply to that path only.

    The result has ``coordinates`` "phi-time (v, φ, Z) …", ``periods`` (None, 2π/nfp, None) for a
    φ-periodic A, ``phi_time`` the :class:`PhiTimeCoordinates` (for :func:`to_phi_time`,
    :func:`from_phi_time`) and, for a callable A, ``inside`` (a step that leaves the image of the u
    interval stops with ``RESULTS.left_domain``; a closed-form U is defined beyond it).
    """
    if isinstance(A, Field):
        As = [a for a in A._vector_potentials if isinstance(a, VectorPotential)]
        if len(As) != 1:
            raise TypeError(f"the field {A.name!r} is not made from one (u, φ, Z) vector potential "
                            "(Field.from_vector_potential / toroidal_field); pass A itself")
        A = As[0]
    if box is None:  # a spline of A: its grid's (u, φ, Z) box
        if not hasattr(A, "grid_box"):
            raise TypeError("give the (u, φ, Z) box (vpforms.toroidal.box_from_cylindrical); only a "
                            "spline of A has a default box (its grid's)")
        box = A.grid_box
    if is_sympy_potential(A):
        syms = _toroidal_symbols(A, symbols)
        period = 2 * np.pi / (1 if nfp is None else int(nfp))
        if grid is None and domain is None:  # a grid or a domain: the lambdified potential, Newton's U
            try:
                return symbolic_phi_time_field(tuple(A), syms, box, period=period, u_ref=u_ref,
                                               margin=margin, n_check=n_check, name=name, **kw)
            except NoClosedForm as why:
                warnings.warn(f"φ-time field {name!r}: no closed form ({why}); it is built from the "
                              "lambdified potential with U by Newton and runs on the JAX backend only",
                              stacklevel=2)
        A = CallablePotential([_lambdify_scalar(sp.sympify(a), syms) for a in A], (None, period, None))
        nfp = None
    elif symbols is not None:
        raise ValueError("symbols is for a SymPy vector potential; A is not three SymPy expressions")
    if not isinstance(A, VectorPotential):
        A = ToroidalPotential(A, 1 if nfp is None else nfp)
    elif nfp is not None:
        raise ValueError("nfp is the potential's (ToroidalPotential(A, nfp)); do not pass it again")
    splined = grid is not None or kw.get("tol") is not None
    level_v = ("auto" if splined else "no") if level_v is None else level_v
    with phase("the φ-time coordinates (gauge, the sign of B^φ on the box or domain, the v range)"):  # ~3 s on a spline A
        coords = PhiTimeCoordinates(A, box, u_ref=u_ref, inverse=inverse, a_u=a_u, level_v=level_v, margin=margin,
                                    n_check=n_check, quadrature_n=kw.get("quadrature_n", DEFAULT_N), domain=domain)
    if splined:
        return spline_phi_time_field(coords, grid, degree=degree, name=name, **kw)
    C = PhiTimePotential(coords)
    yb = coords.ybox
    kw.setdefault("origin", (0.5 * (yb[0][0] + yb[0][1]), yb[1][0], 0.5 * (yb[2][0] + yb[2][1])))
    if coords.domain is not None:  # the checks sample the domain's image, not its bounding box
        kw.setdefault("sampler", coords.domain_points)
    field = Field.from_vector_potential(C, box=yb, name=name, **kw)
    field.coordinates = coords.describe()
    field.periods = (None, coords.period, None)
    field.phi_time = coords
    field.inside = coords.inside
    return field


def _toroidal_symbols(A: Sequence[Any], symbols: Sequence[sp.Symbol] | None) -> tuple:
    """``symbols`` checked, or the free symbols of ``A`` named u, phi (or φ), Z."""
    free = set().union(*(sp.sympify(a).free_symbols for a in A))
    if symbols is None:
        by_name = {str(s): s for s in free}
        names = ("u", "phi" if "phi" in by_name else "φ", "Z")
        if not set(by_name) <= set(names):
            raise ValueError(f"give symbols=(u, phi, Z) for the SymPy vector potential: its free symbols "
                             f"are {sorted(by_name)}")
        return tuple(by_name.get(n, sp.Symbol(n, real=True)) for n in names)
    syms = tuple(symbols)
    if len(syms) != 3 or not all(isinstance(s, sp.Symbol) for s in syms) or len(set(syms)) != 3:
        raise ValueError(f"symbols must be three distinct SymPy symbols (u, φ, Z); got {symbols!r}")
    extra = free - set(syms)
    if extra:
        raise ValueError(f"the vector potential has free symbols {sorted(map(str, extra))} besides "
                         f"(u, φ, Z) = {tuple(map(str, syms))}: substitute their values")
    return syms


def _coords_of(obj: Any) -> PhiTimeCoordinates:
    for o in (obj, getattr(obj, "phi_time", None), getattr(getattr(obj, "field", None), "phi_time", None)):
        if isinstance(o, PhiTimeCoordinates):
            return o
        if isinstance(getattr(o, "phi_time", None), PhiTimeCoordinates):
            return o.phi_time
    raise TypeError(f"expected a phi-time field, method or PhiTimeCoordinates; got {type(obj).__name__}")


def to_phi_time(field_or_map: Any, x_uphiz: Any) -> jax.Array:
    """(u, φ, Z) → (v, φ, Z) for points of shape (..., 3) (``field_or_map``: a φ-time field, a method
    on one, or its :class:`PhiTimeCoordinates`); traceable (jit, vmap)."""
    c = _coords_of(field_or_map)
    x = jnp.asarray(x_uphiz, float)
    return c._to(x.reshape(-1, 3)).reshape(x.shape)


def from_phi_time(field_or_map: Any, y_vphiz: Any) -> jax.Array:
    """(v, φ, Z) → (u, φ, Z) for points of shape (..., 3); NaN in u off the box's u interval."""
    c = _coords_of(field_or_map)
    y = jnp.asarray(y_vphiz, float)
    return c._from(y.reshape(-1, 3)).reshape(y.shape)

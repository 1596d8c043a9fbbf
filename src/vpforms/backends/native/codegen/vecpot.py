"""Fields given by a vector potential of run-time data, as SymPy: splines of A and filament coils.

A field built by :meth:`vpforms.Field.from_vector_potential` from a spline of A
(:class:`vpforms.grids.SplinePotential`, :mod:`.splines`) or from filament coils
(:class:`vpforms.coils.CoilPotential`, Cartesian or in toroidal coordinates, :mod:`.coils`) or a
circular filament ring (:mod:`.ring`) —
relabelled or summed (:mod:`vpforms._vecpot`) — has its A as SymPy atoms in G.x, so the field is
a = ∇×A of the atoms and the SE/DL pairs are A − ∇χ with χ the potential's own antiderivative as
JAX takes it: exact for a spline, the periodic-aware Gauss–Legendre rule of the same nodes for
coils (:class:`vpforms._quadrature.GLSum`, loops over the nodes in C).
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from ...._vecpot import GAUGE_ZERO, RelabelledPotential, SumPotential, VectorPotential
from ....grids._spline_potential import SplinePotential
from ....symbolic import _symbols as G
from .coils import coil_exprs
from .ring import ring_exprs
from .splines import spline_exprs

__all__ = ["vecpot_field_exprs", "vecpot_pair", "vecpot_reason"]


class _Exprs:
    """A vector potential as SymPy in G.x: ``components`` and ``antiderivative(k, c, n)`` (None
    where it is not generated)."""

    def __init__(self, components, antiderivative):
        self.components, self.antiderivative = components, antiderivative


def _pot_exprs(A: Any) -> _Exprs | str:
    """The SymPy form of a vector potential of splines or coils, or why there is none."""
    x = G.x
    if isinstance(A, SplinePotential):
        return _Exprs(*spline_exprs(A, x))
    got = coil_exprs(A, x)
    if got is None:
        got = ring_exprs(A, x)
    if got is not None:
        return _Exprs(*got)
    if isinstance(A, RelabelledPotential):  # Ã_k(x) = s·A_{π(k)}(x·π⁻¹), χ̃_k = s·χ_{π(k)}(x·π⁻¹)
        base = _pot_exprs(A.base)
        if isinstance(base, str):
            return base
        sub = {x[j]: x[A._inv[j]] for j in range(3)}
        s = sp.Integer(int(A._sign))

        def pull(e):
            return None if e is None else s * sp.sympify(e).xreplace(sub)

        return _Exprs(tuple(pull(base.components[m]) for m in A._idx),
                      lambda k, c, n: pull(base.antiderivative(A._idx[k], c, n)))
    if isinstance(A, SumPotential):
        parts = [_pot_exprs(p) for p in A.parts]
        for p in parts:
            if isinstance(p, str):
                return p

        def anti(k, c, n):
            terms = [p.antiderivative(k, c, n) for p in parts]
            return None if any(t is None for t in terms) else sp.Add(*terms)

        return _Exprs(tuple(sp.Add(*(p.components[i] for p in parts)) for i in range(3)), anti)
    return (f"its vector potential ({getattr(A, 'description', type(A).__name__)}) is neither a "
            "spline nor coils; native evaluates splines of A (vpforms.grids), filament coils "
            "(vpforms.coils.CoilPotential), circular rings and SymPy fields only")


def _vector_potential(field: Any) -> VectorPotential | None:
    """The vector potential the field's pairs are built from (as ``Field._gauge_potentials``)."""
    objs = [A for A in getattr(field, "_vector_potentials", ()) if isinstance(A, VectorPotential)]
    if not objs or getattr(field, "exprs", None) is not None:
        return None
    return next((A for A in objs if A.exact_gauge), objs[0])


def vecpot_reason(field: Any) -> str | None:
    """None if ``field`` is a callable field of a vector potential native can evaluate (then
    :func:`vecpot_pair`, :func:`vecpot_field_exprs` apply), else why not."""
    A = _vector_potential(field)
    if A is None:
        return "field was given as a JAX callable; build it with Field.from_sympy"
    got = _pot_exprs(A)
    return got if isinstance(got, str) else None


def vecpot_field_exprs(field: Any) -> tuple:
    """a = ∇×A (as :func:`vpforms._vecpot.curl_of`) in G.x, from the atoms."""
    A = _pot_exprs(_vector_potential(field)).components
    x = G.x
    return (sp.diff(A[2], x[1]) - sp.diff(A[1], x[2]), sp.diff(A[0], x[2]) - sp.diff(A[2], x[0]),
            sp.diff(A[1], x[0]) - sp.diff(A[0], x[1]))


def vecpot_pair(field: Any, splitting: str) -> tuple | str:
    """The SE (F¹, F³) or DL (G¹, G²) pair A − ∇χ, χ = ∫_{c_k}^{x_k} A_k with c = the field's
    origin, as :meth:`vpforms._vecpot.VectorPotential.gauge` (exact for splines, the field's
    Gauss–Legendre rule for coils); or why there is none."""
    A = _pot_exprs(_vector_potential(field))
    k = GAUGE_ZERO[splitting]
    chi = A.antiderivative(k, float(field.origin[k]), int(field.quadrature_n))
    if chi is None:
        return f"the {splitting.upper()} gauge integral of this potential is not generated natively"
    keep = (0, 2) if splitting == "se" else (0, 1)
    return tuple(A.components[i] - sp.diff(chi, G.x[i]) for i in keep)

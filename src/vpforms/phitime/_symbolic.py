"""φ-time in closed form: a SymPy vector potential gives the φ-time field as SymPy expressions, so
that every backend — the native C kernels included — steps it (issue #24, items 1 and 3).

The construction is the one of :mod:`vpforms.phitime`, done by SymPy where it can be:

1. the gauge A'_u = 0: χ = ∫_{u_ref}^u A_u du (``sympy.integrate``; χ = 0 when A_u ≡ 0);
2. v = −s·A'_Z and its inverse u = U(v, φ, Z) by ``sympy.solve`` — each candidate root is checked
   numerically (V(U(y)) = v on the (v, φ, Z) box, :meth:`PhiTimeCoordinates._check_inverse`);
3. K = s·A'_φ(U(v, φ, Z), φ, Z) and b = (−∂_Z K, 1, ∂_v K) = ∇×(0, K, −v) in (v, φ, Z), built by
   :meth:`vpforms.Field.from_sympy` with the vector potential (0, K, −v), so that the pair of every
   case is its closed-form gauge (C_v = 0 along v, −v(Z − c) along Z: the φ-exact cases need no
   quadrature) and the native backend generates C for it.

For the axisymmetric part of a tokamak, B^φ = g/R² = g/(2u) and A'_Z = −(g/2) ln(2u): v = g ln R,
U = e^{2v/g}/2 — a closed form, so the field-line study with φ as the time runs natively.

Every SymPy call is bounded by the deterministic budgets of :mod:`vpforms._budget` (χ only for an
A_u within MAX_INTEGRATE_OPS and :func:`~vpforms._budget.integration_obstacle`, U only for an
equation within MAX_SOLVE_OPS; the last guard stops a runaway call with BudgetError): when SymPy
finds no χ or no U in its budget,
:func:`vpforms.phitime.phi_time_field` builds the same field from the lambdified potential (U by
the safeguarded Newton solve, K a JAX callable) and says so in a warning: the field is then stepped
on the JAX backend only (``backend="native"`` refuses it with the reason).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import sympy as sp

from .._budget import (
    MAX_INTEGRATE_OPS,
    MAX_SOLVE_OPS,
    bounded_simplify,
    check_size,
    guarded,
    integration_obstacle,
)
from .._errors import BudgetError
from .._fieldops import _lambdify_scalar, _symbolic_zero
from .._vecpot import CallablePotential
from ..fields import Field
from ._coordinates import PhiTimeCoordinates

__all__ = ["NoClosedForm", "is_sympy_potential", "symbolic_phi_time_field", "toroidal_potential_exprs"]


class NoClosedForm(Exception):
    """SymPy found no closed form for χ or U within its budget (the reason is the message)."""


def toroidal_potential_exprs(A_cartesian: Sequence[Any], cartesian_symbols: Sequence[sp.Symbol],
                             toroidal_symbols: Sequence[sp.Symbol]) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """The covariant components (A_u, A_φ, A_Z) in (u = R²/2, φ, Z) of a Cartesian vector potential:

        A_u = A·∂x/∂u = (A_x cos φ + A_y sin φ)/R,   A_φ = A·∂x/∂φ = R(−A_x sin φ + A_y cos φ),
        A_Z = A_z,   with x = R cos φ, y = R sin φ, R = √(2u)

    (a one-form pulls back covariantly; ∇×A is then the flow (R B_R, B_φ/R, B_Z) of
    :mod:`vpforms.toroidal`). Each component is simplified within the budgets of
    :mod:`vpforms._budget`."""
    x, y, z = cartesian_symbols
    u, ph, Z = toroidal_symbols
    R = sp.sqrt(2 * u)
    Ax, Ay, Az = (sp.sympify(a) for a in A_cartesian)
    # R·A_R = x A_x + y A_y and A_φ = x A_y − y A_x, in Cartesian first (cancels ψ(x² + y²)/R²-type
    # factors there), then x = R c, y = R s reduced modulo c² + s² = 1
    comps = ((x * Ax + y * Ay) / (2 * u), x * Ay - y * Ax, Az)
    c, s_ = sp.Dummy("c"), sp.Dummy("s")
    sub = {x: R * c, y: R * s_, z: Z}
    out = []
    for e in comps:
        e = sp.cancel(sp.together(e)).xreplace(sub)
        red = _reduce_circle(e, c, s_)
        e = (e if red is None else red).xreplace({c: sp.cos(ph), s_: sp.sin(ph)})
        out.append(min([e, *bounded_simplify(e)], key=sp.count_ops))
    return tuple(out)


def _reduce_circle(e: sp.Expr, c: sp.Symbol, s: sp.Symbol) -> sp.Expr | None:
    """e with numerator and denominator reduced modulo c² + s² − 1 (None: not a rational function
    of c and s that SymPy can reduce)."""
    try:
        num, den = sp.fraction(sp.cancel(sp.together(e)))
        circle = [c**2 + s**2 - 1]
        num = sp.reduced(sp.expand(num), circle, c, s)[1]
        den = sp.reduced(sp.expand(den), circle, c, s)[1]
        return sp.cancel(num / den)
    except (sp.PolynomialError, sp.GeneratorsNeeded, sp.CoercionFailed, NotImplementedError):
        return None


def _free_name(base: str, taken: Sequence[sp.Symbol]) -> sp.Symbol:
    names = {str(s) for s in taken}
    name = base
    while name in names:
        name += "_"
    return sp.Symbol(name, real=True)


def _gauge_expr(Au: sp.Expr, u: sp.Symbol, u_ref: float) -> sp.Expr:
    """χ = ∫_{u_ref}^u A_u du in closed form, or NoClosedForm (also over the deterministic budgets
    MAX_INTEGRATE_OPS and :func:`~vpforms._budget.integration_obstacle`)."""
    n = sp.count_ops(Au)
    if n > MAX_INTEGRATE_OPS:
        raise NoClosedForm(f"A_u has {n} operations > MAX_INTEGRATE_OPS = {MAX_INTEGRATE_OPS} (vpforms._budget)")
    why = integration_obstacle(Au, u)
    if why is not None:
        raise NoClosedForm(f"∫ A_u du: {why} (budget of vpforms._budget)")
    try:
        chi = guarded("the gauge integral ∫ A_u du", sp.integrate, Au, (u, sp.nsimplify(u_ref), u))
    except (NotImplementedError, ValueError, TypeError) as err:
        if isinstance(err, BudgetError):
            raise
        raise NoClosedForm(f"sympy.integrate of A_u raised {type(err).__name__}") from None
    if chi.has(sp.Integral):
        raise NoClosedForm(f"SymPy finds no antiderivative of A_u = {Au} in u")
    return chi


def _inverse_candidates(V: sp.Expr, u: sp.Symbol, v: sp.Symbol) -> list[sp.Expr]:
    """The roots u = U(v, φ, Z) of V(u, φ, Z) = v that ``sympy.solve`` finds, or NoClosedForm (also
    for an equation over the deterministic budget MAX_SOLVE_OPS)."""
    n = sp.count_ops(V)
    if n > MAX_SOLVE_OPS:
        raise NoClosedForm(f"v = V(u, φ, Z) has {n} operations > MAX_SOLVE_OPS = {MAX_SOLVE_OPS} (vpforms._budget)")
    try:
        roots = guarded(f"solving v = {V} for u", sp.solve, sp.Eq(V, v), u, dict=False)
    except BudgetError:
        raise
    except (NotImplementedError, ValueError) as err:  # sympy: "multiple generators", no algorithm
        raise NoClosedForm(f"SymPy cannot solve v = {V} for u ({type(err).__name__})") from None
    roots = [r for r in roots if isinstance(r, sp.Expr) and not r.has(sp.I) and u not in r.free_symbols]
    if not roots:
        raise NoClosedForm(f"SymPy finds no real root u of v = {V}")
    return roots


def symbolic_phi_time_field(A: Sequence[Any], symbols: Sequence[sp.Symbol], box: Any, *, period: float,
                            u_ref: float | None = None, margin: float = 0.02, n_check: int = 17,
                            name: str = "phi-time field", **kw: Any) -> Field:
    """The φ-time field of a SymPy (u, φ, Z) vector potential in closed form (module docstring), or
    :class:`NoClosedForm`. :class:`~vpforms.phitime.PhiTimeError` where B^φ vanishes in the box."""
    u, ph, Z = symbols
    Au, Aph, AZ = (sp.sympify(a) for a in A)
    for i, a in enumerate((Au, Aph, AZ)):
        check_size(a, f"component {i + 1} of the vector potential")
    box_t = tuple(tuple(float(t) for t in b) for b in box)
    u_ref = 0.5 * (box_t[0][0] + box_t[0][1]) if u_ref is None else float(u_ref)

    # --- 1. the gauge A'_u = 0 ------------------------------------------------------------------
    if _symbolic_zero(Au, symbols, 0.0):
        chi, gauge = sp.Integer(0), "A_u = 0 (χ = 0)"
    else:
        chi = _gauge_expr(Au, u, u_ref)
        gauge = f"A_u removed by χ = ∫_{{u_ref}}^u A_u du in closed form (u_ref = {u_ref:.6g})"
    Aph_p, AZ_p = Aph - sp.diff(chi, ph), AZ - sp.diff(chi, Z)

    # --- 2. the sign of B^φ (and PhiTimeError where it vanishes): the numerical coordinates ------
    pot = CallablePotential([_lambdify_scalar(sp.Integer(0), symbols), _lambdify_scalar(Aph_p, symbols),
                             _lambdify_scalar(AZ_p, symbols)], (None, period, None))
    probe = PhiTimeCoordinates(pot, box_t, u_ref=u_ref, a_u="zero", margin=margin, n_check=n_check)
    s = probe.sign

    # --- 3. U in closed form, checked --------------------------------------------------------------
    v = _free_name("v", symbols)
    coords, last = None, None
    for U in _inverse_candidates(-s * AZ_p, u, v):
        try:
            Uf = _lambdify_scalar(U, (v, ph, Z))
            coords = PhiTimeCoordinates(pot, box_t, u_ref=u_ref, a_u="zero", margin=margin,
                                        n_check=n_check, inverse=Uf)
            break
        except ValueError as err:  # not the branch that inverts V on this box
            last = err
    if coords is None:
        raise NoClosedForm(f"no root of v = {-s * AZ_p} for u inverts it on the box ({last})")
    coords.gauge = gauge

    # --- 4. K and the field b = ∇×(0, K, −v) ---------------------------------------------------------
    K = s * Aph_p.xreplace({u: U})
    check_size(K, "the φ-time Hamiltonian K")
    b = (-sp.diff(K, Z), sp.Integer(1), sp.diff(K, v))
    yb = coords.ybox
    kw.setdefault("origin", (0.5 * (yb[0][0] + yb[0][1]), yb[1][0], 0.5 * (yb[2][0] + yb[2][1])))
    field = Field.from_sympy(b, (v, ph, Z), name=name, potentials={"A": (0, K, -v)}, box=yb, **kw)
    field.coordinates = coords.describe() + f"; K = {K} in closed form"
    field.periods = (None, coords.period, None)
    field.phi_time = coords
    return field


def is_sympy_potential(A: Any) -> bool:
    """Whether ``A`` is three SymPy expressions (the symbolic path of ``phi_time_field``)."""
    if isinstance(A, sp.MatrixBase):
        return len(A) == 3
    return (isinstance(A, (tuple, list)) and len(A) == 3
            and all(isinstance(a, (sp.Basic, int, float)) for a in A)
            and any(isinstance(a, sp.Expr) and a.free_symbols for a in A))


"""What a class supplies to the native backend: its generating map as SymPy expressions.

:class:`MapStage` is one solve of ((σ, Σ)·f^s_{φ,Φ})(x) (eq:volpot, :class:`vpforms.GeneratingMap`)
at a symbolic step ``h``: φ(Y₃, y₂, y₃), Φ(Y₃, Y₂, y₃) in the generic symbols of
:mod:`vpforms.symbolic._symbols`, the case, the sign, the Newton controls, and the field a(x) whose
Euler guess x + h a(x) starts the solves (the guess of every non-DL method; relabelling and
adjunction leave it unchanged, see :meth:`MapStage.relabel`).

:func:`class_stage` builds it for the representative methods whose potentials are symbolic:

* SE+SE (eq:case5): φ = y₂Y₃ + hF¹(y₃, y₂, Y₃), Φ = y₃Y₂ + hF³(y₃, Y₂, Y₃) from the field's
  SE potentials: closed form (``Field.se_potential_exprs``) or Gauss–Legendre quadrature of its
  components as :class:`~vpforms._quadrature.GLSum` expressions (:func:`potential_pair`), which
  the emitter turns into loops over the nodes;
* S1, S2 on linear fields: the SymPy recipes of :mod:`vpforms.symbolic.recipes` (the ones the JAX
  methods lambdify) with the matrix entries substituted;

and S1/S2 on nonlinear fields, Quispel's correction maps, as a :class:`CorrectionStage` (three
scalar equations, not a generating map) whose correction integral f_c is the one the JAX method
takes: its closed form, or the same Gauss–Legendre rule on the same integrand (a
:class:`~vpforms._quadrature.GLSum`, so on any field the emitter has expressions for: SymPy,
splines, coils); and the DL classes evaluated as their θ-stages (``fast=True``), as a
:class:`DLStage`. Otherwise the reason why not (the DL engine form: L_d has no closed form).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import sympy as sp

from ...._case import Case
from ...._methods._linear import LinearRecipeMethod
from ...._methods.correction import QuispelCorrection, correction_antiderivative, correction_integrand
from ...._methods.dl_dl import DLDL
from ...._methods.se_dl import SEDL
from ...._methods.se_se import SESE
from ...._potentials import _quadrature_potentials
from ...._quadrature import line_integral_expr
from ....symbolic import _symbols as G
from ....symbolic.recipes import flip_generic
from .cprinter import c_unsupported
from .data import DataRef
from .vecpot import vecpot_field_exprs, vecpot_pair, vecpot_reason

__all__ = ["CORR_C", "CORR_S", "DL_QPC", "CorrectionStage", "DLStage", "MapStage", "RK4Stage", "ThetaStage",
           "class_stage", "field_exprs", "field_reason", "potential_pair", "symbolic_reason"]


@dataclass(frozen=True)
class RK4Stage:
    """One classical RK4 step of ``field`` (explicit; no adjoint is generated)."""

    field: Any


@dataclass(frozen=True)
class MapStage:
    """X = ((σ, Σ)·f^s_{φ,Φ})(x) at step h (see the module docstring)."""

    phi: sp.Expr  # in G.Y[2], G.y[1], G.y[2], G.h
    Phi: sp.Expr  # in G.Y[2], G.Y[1], G.y[2], G.h
    case: Case
    sign: int
    newton: tuple[float, int, float]  # (tol, max_iter, twist_tol)
    field_exprs: tuple  # a(x) in G.x: the Euler guess is x + h a(x)

    def relabel(self, pi) -> MapStage:
        """(π, π)·map = (π∘σ, π∘Σ)·f (prop:permactalg); the guess x + h a(x) in the original
        coordinates: a_i(x) = ã_{π⁻¹(i)}(x·π) for the relabelled field ã the base was built on."""
        idx, inv = pi.index, pi.inverse().index
        sub = {G.x[j]: G.x[idx[j]] for j in range(3)}
        a = tuple(sp.sympify(self.field_exprs[inv[i]]).xreplace(sub) for i in range(3))
        return replace(self, case=self.case.relabel(pi), field_exprs=a)

    def adjoint(self) -> MapStage:
        """The map of Ψ*_h = (Ψ_{−h})⁻¹: the inverse (prop:permactvolpotinv: (Σ, σ)·f_{Φ·p, φ·p},
        same sign) of the map at −h. The Euler guess x + h a(x) of the adjoint is unchanged."""
        phi, Phi = (sp.sympify(e).xreplace({G.h: -G.h}) for e in (self.phi, self.Phi))
        nphi, nPhi = flip_generic(phi, Phi)
        return replace(self, phi=nphi, Phi=nPhi, case=self.case.switched())


@dataclass(frozen=True)
class CorrectionStage:
    """Quispel's correction map (t5vp / t5vps2, :class:`vpforms._methods.correction.QuispelCorrection`)
    as its three scalar equations in sequence, with the correction f_c = ∫_c^u w(s) ds:
    X = Ψ(x·π)·π⁻¹ where Ψ is the map at ``hsign``·h, or its inverse (``inverse``)."""

    a: tuple  # the field a(x) in G.x (of the field the correction map was built on)
    fc: sp.Expr  # f_c(x_i, u, x_k; c, h) in G.x[i], CORR_S (u), G.x[k], CORR_C (c), G.h
    roles: tuple[int, int, int]  # (i, j, k), 0-based
    newton: tuple[float, int, float]
    inverse: bool = False
    hsign: int = 1
    pi: Any = None  # conjugation π (None: identity)

    def relabel(self, pi) -> CorrectionStage:
        """(π, π)·Ψ: X = Ψ((x·π)·ρ)·ρ⁻¹·π⁻¹ = Ψ(x·(π∘ρ))·(π∘ρ)⁻¹ for the stage's own ρ."""
        return replace(self, pi=pi if self.pi is None else pi * self.pi)

    def adjoint(self) -> CorrectionStage:
        """Ψ*_h = (Ψ_{−h})⁻¹ (the conjugation stays)."""
        return replace(self, inverse=not self.inverse, hsign=-self.hsign)


#: the upper and lower limits of the correction integral :attr:`CorrectionStage.fc`
CORR_S, CORR_C = sp.Symbol("s_corr"), sp.Symbol("c_corr")

#: (q, p, c): the arguments of a θ-stage's Hamiltonian :attr:`ThetaStage.H`
DL_QPC = sp.symbols("q_dl p_dl c_dl")


@dataclass(frozen=True)
class ThetaStage:
    """One θ-stage (:func:`vpforms._methods._lagrangian.dl_stage`) of H(q, p; c) on the coordinates
    (x_q, x_p) with x_c frozen, ``idx`` = (q, p, c) 0-based: p̄ = p₀ − h(1−θ)∂_qH(q_θ, p̄),
    q₁ = q₀ + h∂_pH(q_θ, p̄), p₁ = p̄ − hθ∂_qH(q_θ, p̄) — nested scalar roots, q₁ outer, p̄ inner."""

    H: sp.Expr  # in DL_QPC
    theta: float
    idx: tuple[int, int, int]
    newton: tuple[float, int, float]


@dataclass(frozen=True)
class DLStage:
    """A DL step (SE+DL, DL+DL with ``fast=True``, :class:`vpforms._methods.se_dl.DLPredictor`) as
    its θ-stages in sequence; the status is the first failure of their solves, then non-finite."""

    stages: tuple[ThetaStage, ...]

    def relabel(self, pi) -> DLStage:
        """X = Ψ(x·π)·π⁻¹: a stage acting on (x·π)_q = x_{π(q)} acts on x_{π(q)}."""
        idx = pi.index
        return DLStage(tuple(replace(s, idx=tuple(idx[i] for i in s.idx)) for s in self.stages))

    def adjoint(self) -> DLStage:
        """Ψ*_h = (Ψ_{−h})⁻¹: the inverse of a θ-stage at −h is the (1−θ)-stage at h, so the
        stages in reverse order with θ → 1 − θ (``DLPredictor._stages_inverse``)."""
        return DLStage(tuple(replace(s, theta=1.0 - s.theta) for s in reversed(self.stages)))


def symbolic_reason(field: Any) -> str | None:
    """None if ``field`` has SymPy expressions without free parameters that C can evaluate, else
    why not."""
    if getattr(field, "exprs", None) is None or getattr(field, "symbols", None) is None:
        return "field was given as a JAX callable; build it with Field.from_sympy"
    free = set().union(*(sp.sympify(e).free_symbols for e in field.exprs))
    if not free <= set(field.symbols):
        return f"field has unsubstituted parameters {sorted(map(str, free - set(field.symbols)))}"
    bad = c_unsupported(*field.exprs)
    if bad:
        return f"field uses {', '.join(bad)}, which C (math.h) has no implementation of"
    return None


def field_reason(field: Any) -> str | None:
    """None if native can evaluate ``field``: SymPy expressions C can print, or a spline vector
    potential or coils (:mod:`.vecpot`); else why not."""
    if getattr(field, "exprs", None) is not None:
        return symbolic_reason(field)
    return vecpot_reason(field)


def field_exprs(field: Any) -> tuple:
    """a(x) in G.x: the field's expressions, or the curl of its vector potential of data."""
    if getattr(field, "exprs", None) is None:
        return vecpot_field_exprs(field)
    return _to_x(field, field.exprs)


def _free(expr: Any) -> set:
    """The free symbols of ``expr`` but the run-time data (:class:`.data.DataRef`)."""
    return {s for s in sp.sympify(expr).free_symbols if not isinstance(s, DataRef)}


def potential_pair(field: Any, splitting: str) -> tuple[sp.Expr, sp.Expr] | str:
    """The ``splitting`` ("se" or "dl") potentials of ``field`` as SymPy expressions in x1, x2, x3,
    as the JAX methods evaluate them, or why there are none:

    * closed-form or user-supplied potentials: their expressions;
    * quadrature potentials of the field's own components (MATH.md §3,
      :func:`vpforms._potentials._quadrature_potentials`): the same formulas with the n-point rule
      as :class:`~vpforms._quadrature.GLSum` (:func:`~vpforms._quadrature.line_integral_expr`),
      whose derivatives are the derivatives ``jax.grad`` takes of the JAX quadrature;
    * anything else (a gauge integral of supplied vector potentials by quadrature): the reason."""
    if getattr(field, "exprs", None) is None and vecpot_reason(field) is None:
        return vecpot_pair(field, splitting)  # the gauge of a spline of A or of coils, as atoms
    _, exprs, how = field._get(splitting)
    if exprs is not None:
        pair = _to_x(field, exprs)
    elif how == f"quadrature(n={field.quadrature_n})" and not field._vector_potentials:
        a = _to_x(field, field.exprs)

        def comp(e):  # a_i as a function of SymPy arguments
            return lambda y1, y2, y3: e.xreplace(dict(zip(G.x, (y1, y2, y3))))

        # the base point as JAX has it (float); 0 exactly, so that s = c + (x − c)t stays x·t
        c = tuple(sp.Integer(0) if v == 0 else sp.Float(v, 17) for v in field.origin)
        P, Q = _quadrature_potentials(tuple(comp(e) for e in a), splitting, c,
                                      field.quadrature_n, integral=line_integral_expr)
        pair = (P(*G.x), Q(*G.x))
    else:
        return f"{splitting.upper()} potentials are {how}; native generates closed forms and " \
               "quadratures of the field's own components only"
    bad = c_unsupported(*pair)
    if bad:
        return (f"the {splitting.upper()} potentials use {', '.join(bad)}, which C (math.h) has no "
                "implementation of")
    return pair


def _to_x(field, exprs):
    """Expressions of ``field.symbols`` → the canonical symbols x1, x2, x3."""
    sub = dict(zip(field.symbols, G.x))
    return tuple(sp.sympify(e).xreplace(sub) for e in exprs)


def _newton(m) -> tuple[float, int, float]:
    n = m.newton
    return float(n["tol"]), int(n["max_iter"]), float(n["twist_tol"])


def class_stage(m: Any) -> MapStage | str:
    """The generating map of the representative method ``m`` (bare), or why it is not generated."""
    name = getattr(m, "name", type(m).__name__)
    if isinstance(m, (DLDL, SEDL)) and not m.fast:
        return (f"{name}: the engine form (fast=False) solves the generating map of discrete "
                "Lagrangians L_d, defined through an inner Newton solve for p̄ (no SymPy "
                "expression); the default stage form (not --engine), the same map as nested θ-stages, "
                "is generated natively")
    field = getattr(m, "field", None)
    why = field_reason(field)
    if why:
        return why
    if isinstance(m, (DLDL, SEDL)):
        return _dl_stage(m)
    a = field_exprs(field)
    if isinstance(m, QuispelCorrection):
        return _correction_stage(m, a)
    if isinstance(m, SESE):
        pair = potential_pair(field, "se")
        if isinstance(pair, str):
            return f"{name}: {pair}"
        F1, F3 = pair
        Y3, Y2, y2, y3, h = G.Y[2], G.Y[1], G.y[1], G.y[2], G.h
        # generic arguments (MATH.md §2): φ(Y₃, y₂, y₃) = φ(X₃, x₂, x₁), Φ(Y₃, Y₂, y₃) = Φ(X₃, X₂, x₁)
        phi = y2 * Y3 + h * F1.xreplace({G.x[0]: y3, G.x[1]: y2, G.x[2]: Y3})
        Phi = y3 * Y2 + h * F3.xreplace({G.x[0]: y3, G.x[1]: Y2, G.x[2]: Y3})
    elif isinstance(m, LinearRecipeMethod):
        gen = m.recipe.generic()
        coeffs = {s: sp.Float(v, 17) if v != 0 else sp.Integer(0)
                  for s, v in zip((G.A[i, j] for i in range(3) for j in range(3)), m._coeffs)}
        phi, Phi = gen.phi.xreplace(coeffs), gen.Phi.xreplace(coeffs)
    else:
        return f"{name} is not generated natively (no symbolic generating map for its class)"
    extra = (_free(phi) | _free(Phi)) - {G.Y[2], G.Y[1], G.y[1], G.y[2], G.h}
    if extra:
        return f"{name}: potentials have unsubstituted parameters {sorted(map(str, extra))}"
    return MapStage(phi, Phi, m.case, m.case.sign, _newton(m), a)


def _correction_stage(m, a) -> CorrectionStage | str:
    """The correction map ``m`` with the f_c its JAX ``correction`` takes: W(u) − W(c) from the
    closed-form antiderivative, else ``line_integral`` as a SymPy expression (the same n-point
    rule on the same integrand, its derivatives those ``jax.grad`` takes of the quadrature)."""
    i, _, k = m.roles
    if m._fc_closed is not None:
        W, (s, h) = correction_antiderivative(m.field, m.roles)  # the one the JAX method lambdified
        W = _to_x(m.field, [W])[0].xreplace({s: CORR_S, h: G.h})
        fc = W - W.xreplace({CORR_S: CORR_C})
    else:
        fc = _correction_quadrature(a, m.roles, m.quadrature_n)
    bad = c_unsupported(fc)
    if bad:
        return f"{m.name}: the correction uses {', '.join(bad)}, which C (math.h) has no implementation of"
    extra = _free(fc) - {G.x[i], G.x[k], CORR_S, CORR_C, G.h}
    if extra:
        return f"{m.name}: correction has unsubstituted parameters {sorted(map(str, extra))}"
    return CorrectionStage(a, fc, tuple(m.roles), _newton(m))


def _correction_quadrature(a, roles, n: int) -> sp.Expr:
    """f_c = ∫_c^u w(s) ds by the n-point rule (``line_integral`` as SymPy) of the integrand
    :func:`~vpforms._methods.correction.correction_integrand`, the one the JAX method integrates."""
    return line_integral_expr(lambda s: correction_integrand(a, G.x, roles, s, G.h), CORR_C, CORR_S, n)


def _dl_stage(m) -> DLStage | str:
    """H¹(q, p; c) = G¹(c, q, p) on (x₂, x₃) with x₁ frozen, then H²(q, p; c) = −G²(q, c, p) on
    (x₁, x₃) with x₂ frozen (θ₂ = θ for DL+DL, 0 for SE+DL), as ``DLPredictor._init_predictor``."""
    pair = potential_pair(m.field, "dl")
    if isinstance(pair, str):
        return f"{m.name}: {pair}"
    G1, G2 = pair
    q, p, c = DL_QPC
    H1 = G1.xreplace({G.x[0]: c, G.x[1]: q, G.x[2]: p})
    H2 = -G2.xreplace({G.x[0]: q, G.x[1]: c, G.x[2]: p})
    extra = (_free(H1) | _free(H2)) - set(DL_QPC)
    if extra:
        return f"{m.name}: potentials have unsubstituted parameters {sorted(map(str, extra))}"
    n, theta2 = _newton(m), (m.theta if isinstance(m, DLDL) else 0.0)
    return DLStage((ThetaStage(H1, m.theta, (1, 2, 0), n), ThetaStage(H2, theta2, (0, 2, 1), n)))

"""The potentials of the paper's recipes — defined ONCE, as SymPy expressions, printed and corrected.

Other parts of vpforms (the numerical methods, issue #5) lambdify *these* expressions; nothing is
retyped elsewhere.  Conventions (MATH.md §4, σ = (3, 2, 1) throughout Section 4 of the paper):

* Symbols (all real, from :mod:`vpforms.symbolic._symbols`, also exported as :data:`SYMBOLS`):
  ``h`` (the paper's Δt), ``a11 … a33`` (a linear field a = A x, tr A = 0, eq:linear),
  ``x1, x2, x3`` (old variables), ``X1, X2, X3`` (new variables).
* Every recipe returns a :class:`Recipe` whose ``phi`` and ``Phi`` are in the *paper's*
  (= Lomelí–Meiss) normalisation and variables, i.e. the LM argument order of the case
  φ(x₋, x∘, X₋), Φ(x₋, X₋, X∘):

  ===========  ==================  =================  ======================
  recipe       case (σ, Σ)         φ depends on       Φ depends on
  ===========  ==================  =================  ======================
  S1           (3,2,1), (3,2,1)    (x1, x2, X1)       (x1, X1, X2)
  S2           (3,2,1), (2,3,1)    (x1, x2, X1)       (x1, X1, X3)
  SE+SE        (3,2,1), (1,2,3)    (x1, x2, X3)       (x1, X3, X2)
  SE+DL        (3,2,1), (1,3,2)    (x1, x2, X2)       (x1, X2, X3)
  DL+DL        (3,2,1), (3,1,2)    (x1, x2, X2)       (x1, X2, X1)
  ===========  ==================  =================  ======================

* :func:`to_generic` converts such a pair for *any* case into the generic argument order of
  :class:`vpforms.GeneratingMap` — φ_g(Y₃, y₂, y₃) = φ_g(X₋, x∘, x₋), Φ_g(Y₃, Y₂, y₃) =
  Φ_g(X₋, X∘, x₋) — with the constant factors c_φ, c_Φ = ±1 of the case (derived from σ, Σ by
  :func:`vpforms.symbolic.case_forms`), so that the sign rule holds with sign = sgn τ.

Printed vs corrected (MATH.md §4): ``printed=True`` returns the formula exactly as printed in the
paper; ``printed=False`` (default) the corrected one.  For S1 the individual fixes can be switched
one by one (``fixes=``), which the errata report uses to show that each fix is necessary.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._case import Case
from .._potentials import potential_exprs  # the one implementation of MATH.md §3
from ._symbols import A as A_SYM
from ._symbols import X, X1, X2, X3, Y, h, x, x1, x2, x3, y
from .forms import case_forms, check_dependencies

__all__ = [
    "SYMBOLS",
    "Recipe",
    "GenericPotentials",
    "REPRESENTATIVES",
    "S1_QUISPEL_FIXES",
    "S1_AZ_FIXES",
    "s1_potentials",
    "s2_potentials",
    "se_se_potentials",
    "se_dl_potentials",
    "dl_dl_potentials",
    "discrete_lagrangian",
    "se_field_potentials",
    "dl_field_potentials",
    "linear_field",
    "as_matrix",
    "to_generic",
    "from_generic",
    "flip_generic",
    "check_dependencies",
]

(a11, a12, a13), (a21, a22, a23), (a31, a32, a33) = (tuple(r) for r in A_SYM.tolist())

#: Every symbol the recipes use, by name: h, a11 … a33, x1, x2, x3, X1, X2, X3.
SYMBOLS: dict[str, sp.Symbol] = {
    "h": h,
    **{str(s): s for s in A_SYM},
    **{str(s): s for s in x},
    **{str(s): s for s in X},
}

#: The class representatives of Section 4 (σ = (3, 2, 1)): class → Case.
REPRESENTATIVES: dict[str, Case] = {
    "S1": Case((3, 2, 1), (3, 2, 1)),
    "S2": Case((3, 2, 1), (2, 3, 1)),
    "SE+SE": Case((3, 2, 1), (1, 2, 3)),
    "SE+DL": Case((3, 2, 1), (1, 3, 2)),
    "DL+DL": Case((3, 2, 1), (3, 1, 2)),
}

#: The two corrections of eq:S1_quispel (MATH.md §4): the parentheses in the last term of Φ, and
#: k₃ = h a₁₃(h a₁₃ + (k₂/k₁) h² a₁₂ a₂₃) (h², not h).
S1_QUISPEL_FIXES: tuple[str, ...] = ("parentheses", "k3")
#: The four corrections of eq:S1_AZ: "Δ a₁₃" in φ is h a₁₃; the denominator h a₃₃ in Φ is h a₁₃;
#: the term a₂₁ x₁ X₁ is a₂₁ x₁ X₂; the last part C̃ is multiplied by −1/(h a₁₃).
S1_AZ_FIXES: tuple[str, ...] = ("phi_h", "Phi_denominator", "a21_x1X2", "Ctilde")


@dataclass(frozen=True)
class Recipe:
    """A pair of LM-normalised potentials for a case, in the paper's variables.

    ``phi``/``Phi`` are SymPy expressions in x1..X3, h and (for linear fields) a11..a33;
    ``phi_args``/``Phi_args`` the LM argument order of ``case``; ``label`` the paper's equation.
    """

    name: str
    case: Case
    phi: sp.Expr
    Phi: sp.Expr
    label: str
    printed: bool
    fixes: tuple[str, ...] = ()
    note: str = ""
    phi_args: tuple[sp.Symbol, ...] = field(default=(), repr=False)
    Phi_args: tuple[sp.Symbol, ...] = field(default=(), repr=False)

    def generic(self) -> "GenericPotentials":
        """The same potentials in the generic argument order of GeneratingMap (:func:`to_generic`)."""
        return to_generic(self.case, self.phi, self.Phi)

    def subs(self, mapping) -> "Recipe":
        """The recipe with parameters substituted (e.g. a concrete matrix, {a11: 1, ...}).

        ValueError if the substitution makes a potential depend on a variable its case does not
        allow (e.g. {a11: x3})."""
        phi, Phi = sp.sympify(self.phi).subs(mapping), sp.sympify(self.Phi).subs(mapping)
        check_dependencies(self.case, phi, Phi)
        return Recipe(
            self.name,
            self.case,
            phi,
            Phi,
            self.label,
            self.printed,
            self.fixes,
            self.note,
            self.phi_args,
            self.Phi_args,
        )


def _recipe(name, case, phi, Phi, label, printed, fixes=(), note="") -> Recipe:
    cf = case_forms(case)
    check_dependencies(case, phi, Phi)
    return Recipe(name, case, phi, Phi, label, printed, tuple(fixes), note, cf.phi_args, cf.Phi_args)


def _resolve_fixes(printed: bool, fixes: Iterable[str] | None, known: tuple[str, ...]) -> set[str]:
    if fixes is None:
        return set() if printed else set(known)
    fixes = set(fixes)
    unknown = fixes - set(known)
    if unknown:
        raise ValueError(f"unknown fix(es) {sorted(unknown)}; known: {list(known)}")
    return fixes


# ------------------------------------------------------------------------------------------------
# S1 (Prop. th:S1): eq:S1_quispel and eq:S1_AZ
# ------------------------------------------------------------------------------------------------
def s1_potentials(
    variant: str = "quispel", printed: bool = False, *, fixes: Iterable[str] | None = None
) -> Recipe:
    """The S1 potentials φ(x1, x2, X1), Φ(x1, X1, X2) for a linear field (Prop. th:S1).

    Parameters
    ----------
    variant:
        ``"quispel"`` (eq:S1_quispel) or ``"az"`` (eq:S1_AZ).
    printed:
        ``True``: exactly as printed; ``False``: corrected (MATH.md §4).
    fixes:
        Optional explicit subset of :data:`S1_QUISPEL_FIXES` / :data:`S1_AZ_FIXES` to apply
        (overrides ``printed``).

    Notes
    -----
    Symbols: h, a11..a33, x1, x2, X1 (φ) and x1, X1, X2 (Φ) — see :data:`SYMBOLS`.  Case
    (σ, Σ) = ((3,2,1), (3,2,1)); LM equations x3 = ∂_{x2}φ, ∂_{X1}φ = ∂_{x1}Φ, X3 = −∂_{X2}Φ (eq:S1).
    Needs a13 ≠ 0.  Printed "Δ a13" in eq:S1_AZ (a bare Δ, no t) is read as a missing factor, i.e.
    a13; the fix "phi_h" makes it h a13.
    """
    if variant == "quispel":
        fx = _resolve_fixes(printed, fixes, S1_QUISPEL_FIXES)
        k1 = 1 + h**2 * a11 * a33 - h * a22
        k2 = 1 + h**2 * a11 * a33 / (1 - h * a22)
        # eq:S1_quispel: k3 = h a13 (h a13 + (k2/k1) h a12 a23) as printed; h² a12 a23 is right.
        k3 = h * a13 * (h * a13 + (k2 / k1) * (h**2 if "k3" in fx else h) * a12 * a23)
        phi = (X1 - x1 - h * a11 * x1 - h**2 * a21 * a12 * x1 * k2 / k1) / (
            h * a13 + h**2 * a23 * a12 * k2 / k1
        ) * x2 - a12 / (k1 * a13 + h * a23 * a12 * k2) * x2**2 / 2
        if "parentheses" in fx:  # −[(2X1x1 − (1+ha11)x1²)·h a23 k2 + h² a13 a21 k2 x1²]/(2k3)
            last = ((2 * X1 * x1 - (1 + h * a11) * x1**2) * h * a23 * k2
                    + h**2 * a13 * a21 * k2 * x1**2) / (2 * k3)
        else:  # as printed: −(2X1x1 − x1²(1+ha11) h a23 k2 + h² a13 a21 k2 x1²)/(2k3)
            last = (2 * X1 * x1 - x1**2 * (1 + h * a11) * h * a23 * k2
                    + h**2 * a13 * a21 * k2 * x1**2) / (2 * k3)
        Phi = (
            -(X1 - x1 - h * a11 * x1) / (h * a13) * (1 + h * a33) * X2
            + X2**2 * (-h * a32 / 2 + a12 / (2 * a13) * (1 + h * a33))
            - h * a31 * X1 * X2
            - last
        )
        label = "eq:S1_quispel"
        known = S1_QUISPEL_FIXES
    elif variant == "az":
        fx = _resolve_fixes(printed, fixes, S1_AZ_FIXES)
        l1 = 1 - h * a12 / a13 * a23
        den_phi = h * a13 if "phi_h" in fx else a13  # printed "Δ a13"
        phi = (X1 - (1 + h * a11) * x1) / den_phi * x2 - sp.Rational(1, 2) * a12 / a13 * x2**2
        den_Phi = h * a13 if "Phi_denominator" in fx else h * a33  # printed "Δt a33"
        xa = X2 if "a21_x1X2" in fx else X1  # printed a21 x1 X1
        C = h * a21 * x1**2 / 2 + h * a23 * (2 * X1 * x1 - x1**2 * (1 + h * a11)) / (2 * h * a13)
        if "Ctilde" in fx:  # C̃ multiplied by −1/(h a13)
            C = -C / (h * a13)
        Phi = -1 / l1 * (
            (1 + h * a33) * ((X1 - (1 + h * a11) * x1) / den_Phi * X2
                             - sp.Rational(1, 2) * a12 / a13 * X2**2)
            + h * a31 * x1 * X2
            + sp.Rational(1, 2) * h * a32 * X2**2
            + h * a12 / a13 * (a21 * x1 * xa + sp.Rational(1, 2) * a22 * X2**2)
        ) + C
        label = "eq:S1_AZ"
        known = S1_AZ_FIXES
    else:
        raise ValueError(f"variant must be 'quispel' or 'az', not {variant!r}")
    is_printed = not fx
    return _recipe(
        f"S1 {variant} ({'printed' if is_printed else 'corrected' if fx == set(known) else 'partially corrected'})",
        REPRESENTATIVES["S1"],
        phi,
        Phi,
        label,
        is_printed,
        tuple(f for f in known if f in fx),
        "needs a13 ≠ 0",
    )


# ------------------------------------------------------------------------------------------------
# S2 (Prop. th:S2): eq:S2_quispel — correct as printed
# ------------------------------------------------------------------------------------------------
def s2_potentials(printed: bool = False) -> Recipe:
    """The S2 potentials φ(x1, x2, X1), Φ(x1, X1, X3) of eq:S2_quispel (Prop. th:S2).

    Correct as printed (MATH.md §4), so ``printed`` only changes the recipe's name.  Case
    ((3,2,1), (2,3,1)); LM equations x3 = ∂_{x2}φ, ∂_{X1}φ = ∂_{x1}Φ, X2 = ∂_{X3}Φ (eq:S2).
    Needs a12 ≠ 0 **and** a13 ≠ 0 (the paper names only a12).  Symbols as in :data:`SYMBOLS`.
    """
    m1 = 1 - h * a33 + h**2 * a11 * a22
    m2 = 1 + h**2 * a11 * a22 / (1 - h * a33)
    phi = (
        (m1 * (X1 - x1 - h * a11 * x1) - h**2 * a31 * a13 * m2 * x1) * x2 / (h * a13)
        - m1 * a12 * x2**2 / (2 * a13)
        - h * a32 * m2 * x2**2 / 2
    )
    Phi = (
        (1 + h * a22) * (X1 - (1 + h * a11) * x1) * X3 / (h * a12)
        - a13 * (1 + h * a22) * X3**2 / (2 * a12)
        + h * a21 * X1 * X3
        + h * a23 / 2 * X3**2
        + m1 * (2 * X1 * x1 - (1 + h * a11) * x1**2) / (2 * h**2 * a12 * a13)
    )
    return _recipe(
        f"S2 quispel ({'printed' if printed else 'corrected'} = as printed)",
        REPRESENTATIVES["S2"],
        phi,
        Phi,
        "eq:S2_quispel",
        printed,
        (),
        "needs a12 ≠ 0 and a13 ≠ 0",
    )


# ------------------------------------------------------------------------------------------------
# Field potentials (eq:vf1–vf3, MATH.md §3), for SymPy fields
# ------------------------------------------------------------------------------------------------
def as_matrix(M) -> sp.Matrix:
    """A 3×3 SymPy matrix from nested lists / numpy / Matrix; ValueError if malformed."""
    try:
        Mx = sp.Matrix(M)
    except Exception as exc:  # noqa: BLE001 - anything sympy cannot read is malformed
        raise ValueError(f"malformed matrix {M!r}: {exc}") from None
    if Mx.shape != (3, 3):
        raise ValueError(f"malformed matrix: expected shape (3, 3), got {Mx.shape}")
    for e in Mx:
        if not isinstance(e, sp.Expr) or e.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            raise ValueError(f"malformed matrix: entry {e!r} is not a finite number/expression")
    return Mx


def linear_field(M) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """The components of a = M x for a traceless 3×3 matrix (ValueError if malformed or tr ≠ 0)."""
    Mx = as_matrix(M)
    tr = sp.expand(Mx.trace())
    if tr != 0:
        raise ValueError(f"matrix is not traceless (tr = {tr}): a = Ax is not divergence free")
    v = Mx * sp.Matrix(x)
    return tuple(sp.expand(e) for e in v)  # type: ignore[return-value]


def _is_matrix_like(a) -> bool:
    """A 3×3 matrix given as a SymPy Matrix, a numpy array or nested sequences."""
    if isinstance(a, sp.MatrixBase) or hasattr(a, "shape"):
        return len(getattr(a, "shape", ())) == 2
    try:
        return any(isinstance(r, (list, tuple)) for r in a)
    except TypeError:
        return False


def _field(a) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    if _is_matrix_like(a):
        return linear_field(a)
    try:
        comps = tuple(sp.sympify(c) for c in a)
    except (TypeError, sp.SympifyError):
        raise ValueError(f"a field is three SymPy expressions in x1, x2, x3, not {a!r}") from None
    if len(comps) != 3 or not all(isinstance(c, sp.Expr) for c in comps):
        raise ValueError(f"a field is three SymPy expressions in x1, x2, x3, not {a!r}")
    if any(c.has(sp.nan, sp.zoo, sp.oo, -sp.oo) for c in comps):
        raise ValueError(f"a field's components must be finite, not {comps}")
    div = sp.simplify(sum(sp.diff(c, xi) for c, xi in zip(comps, x)))
    if div != 0:
        raise ValueError(f"field is not divergence free (div a = {div})")
    return comps  # type: ignore[return-value]


def _field_potentials(a, splitting: str) -> tuple[sp.Expr, sp.Expr]:
    pair = potential_exprs(_field(a), x, splitting)
    if pair is None:
        raise ValueError(f"SymPy cannot integrate the {splitting.upper()} potentials of {a!r} "
                         "in closed form (use vpforms.Field, which falls back to quadrature)")
    return pair


def se_field_potentials(a) -> tuple[sp.Expr, sp.Expr]:
    """(F¹, F³) with a = vf1(F¹) + vf3(F³) (eq:vf1, eq:vf3; MATH.md §3), one-dimensional integrals.

    F³ = ∫₀^{x2} a1(x1,s,x3) ds,   F¹ = −∫₀^{x2} a3(x1,s,x3) ds + ∫₀^{x3} a2(x1,0,t) dt
    (computed by :func:`vpforms.fields.potential_exprs`).
    """
    return _field_potentials(a, "se")


def dl_field_potentials(a) -> tuple[sp.Expr, sp.Expr]:
    """(G¹, G²) with a = vf1(G¹) + vf2(G²) (eq:vf1, eq:vf2; MATH.md §3).

    G¹ = ∫₀^{x3} a2(x1,x2,t) dt,   G² = −∫₀^{x3} a1(x1,x2,t) dt + ∫₀^{x1} a3(s,x2,0) ds
    (computed by :func:`vpforms.fields.potential_exprs`).
    """
    return _field_potentials(a, "dl")


# ------------------------------------------------------------------------------------------------
# SE+SE, SE+DL, DL+DL (eq:case5, eq:case4, eq:case3)
# ------------------------------------------------------------------------------------------------
def se_se_potentials(F1: sp.Expr, F3: sp.Expr) -> Recipe:
    """eq:case5 (correct as printed): φ = x2 X3 + h F¹(x1, x2, X3), Φ = x1 X2 + h F³(x1, X2, X3).

    F¹, F³ are SymPy expressions in x1, x2, x3 (e.g. from :func:`se_field_potentials`).
    """
    phi = x2 * X3 + h * sp.sympify(F1).xreplace({x3: X3})
    Phi = x1 * X2 + h * sp.sympify(F3).xreplace({x2: X2, x3: X3})
    return _recipe("SE+SE", REPRESENTATIVES["SE+SE"], phi, Phi, "eq:case5", True)


def discrete_lagrangian(H: sp.Expr, q: sp.Symbol, p: sp.Symbol, q0, q1, theta=0) -> sp.Expr:
    """The phase-space discrete Lagrangian L_d(q0, q1) = ext_p̄ [p̄ (q1 − q0) − h H(q_θ, p̄)].

    q_θ = q0 + θ (q1 − q0) (MATH.md §4; θ = 0 is the paper's h L(q0, (q1 − q0)/h), θ = ½ the
    implicit-midpoint stage).  The extremum is taken in closed form; this needs H quadratic in p
    with ∂²H/∂p² ≠ 0 (always the case for a linear field with the relevant a_ij ≠ 0), else
    ValueError.
    """
    pbar = sp.Dummy("pbar", real=True)
    L = pbar * (q1 - q0) - h * sp.sympify(H).xreplace({q: q0 + theta * (q1 - q0), p: pbar})
    stat = sp.expand(sp.diff(L, pbar))
    slope = sp.diff(stat, pbar)
    if slope.has(pbar) or sp.simplify(slope) == 0:
        raise ValueError(
            "the extremum over p̄ of the discrete Lagrangian is not explicit: H must be quadratic "
            f"in {p} with ∂²H/∂{p}² ≠ 0 (got ∂²H/∂{p}² = {sp.diff(H, p, 2)})"
        )
    pstar = -stat.subs(pbar, 0) / slope
    return L.subs(pbar, pstar)


def se_dl_potentials(G1: sp.Expr, G2: sp.Expr, printed: bool = False, theta=0) -> Recipe:
    """eq:case4 ("DL+SE", case ((3,2,1), (1,3,2))): φ(x1, x2, X2), Φ(x1, X2, X3).

    Corrected (MATH.md §4): φ = −L_d¹, L_d¹ the discrete Lagrangian of H = G¹ in (q, p) = (x2, x3)
    (x1 a parameter), Φ = −x1 X3 + h G²(x1, X2, X3).  Printed: φ = +L_d¹ (volume preserving but
    inconsistent).  θ as in :func:`discrete_lagrangian`.
    """
    Ld = discrete_lagrangian(G1, x2, x3, x2, X2, theta)
    phi = Ld if printed else -Ld
    Phi = -x1 * X3 + h * sp.sympify(G2).xreplace({x2: X2, x3: X3})
    return _recipe(
        f"SE+DL ({'printed' if printed else 'corrected'})",
        REPRESENTATIVES["SE+DL"],
        phi,
        Phi,
        "eq:case4",
        printed,
        () if printed else ("phi = -L_d",),
    )


def dl_dl_potentials(
    G1: sp.Expr, G2: sp.Expr, printed: bool = False, theta1=0, theta2=0
) -> Recipe:
    """eq:case3 (DL+DL, case ((3,2,1), (3,1,2))): φ(x1, x2, X2), Φ(x1, X2, X1).

    Corrected (MATH.md §4): φ = −L_d¹ as in :func:`se_dl_potentials`, and Φ = +L_d² with the
    discrete Lagrangian of L² = x3 ẋ1 + G²(x1, X2, x3), i.e. H = −G² in (q, p) = (x1, x3), X2 a
    parameter.  Printed: φ = +L_d¹ and Φ = −L_d² with L² = x3 ẋ1 − G²(x1, X2, x3) (H = +G²).
    θ = 0 in both stages gives the same map as SE+DL.
    """
    Ld1 = discrete_lagrangian(G1, x2, x3, x2, X2, theta1)
    G2X = sp.sympify(G2).xreplace({x2: X2})  # G²(x1, X2, x3)
    if printed:
        phi = Ld1
        Phi = -discrete_lagrangian(G2X, x1, x3, x1, X1, theta2)
    else:
        phi = -Ld1
        Phi = discrete_lagrangian(-G2X, x1, x3, x1, X1, theta2)
    return _recipe(
        f"DL+DL ({'printed' if printed else 'corrected'})",
        REPRESENTATIVES["DL+DL"],
        phi,
        Phi,
        "eq:case3",
        printed,
        () if printed else ("phi = -L_d1", "Phi = +L_d2, H = -G2"),
    )


# ------------------------------------------------------------------------------------------------
# Variables check and the conversion to the generic order of GeneratingMap
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GenericPotentials:
    """Potentials in the generic order of :class:`vpforms.GeneratingMap` (eq:volpot).

    ``phi`` is an expression in (Y3, y2, y3) = (X₋, x∘, x₋) and ``Phi`` in (Y3, Y2, y3) =
    (X₋, X∘, x₋) (symbols :data:`vpforms.symbolic._symbols.Y`, ``y``); ``sign`` = sgn τ for
    ``case``; ``params`` the remaining free symbols (h, a_ij, …) sorted by name.
    """

    case: Case
    phi: sp.Expr
    Phi: sp.Expr
    sign: int
    c_phi: int
    c_Phi: int
    params: tuple[sp.Symbol, ...]

    phi_args = (Y[2], y[1], y[2])
    Phi_args = (Y[2], Y[1], y[2])

    def lambdify(self, params: Sequence[sp.Symbol] | None = None, modules="jax"):
        """(phi, Phi) as callables ``phi(Y3, y2, y3, *param_values)``; default params ``self.params``.

        With ``modules="jax"`` the callables are JAX-traceable; bind parameters (e.g. with
        ``functools.partial``) to get the three-argument potentials GeneratingMap expects.
        """
        params = tuple(self.params if params is None else params)
        missing = set(self.params) - set(params)
        if missing:
            raise ValueError(
                f"params must include every free parameter of the potentials; missing "
                f"{', '.join(sorted(map(str, missing)))} (bind values with .phi.subs first, or "
                "pass them as params)"
            )
        return (
            sp.lambdify(self.phi_args + params, self.phi, modules=modules),
            sp.lambdify(self.Phi_args + params, self.Phi, modules=modules),
        )


def to_generic(case: Case | tuple, phi: sp.Expr, Phi: sp.Expr) -> GenericPotentials:
    """LM-normalised potentials of a case (paper variables) → generic order of GeneratingMap.

    φ_g(Y3, y2, y3) = c_φ · φ(x₋ = y3, x∘ = y2, X₋ = Y3),
    Φ_g(Y3, Y2, y3) = c_Φ · Φ(x₋ = y3, X₋ = Y3, X∘ = Y2),
    with c_φ, c_Φ ∈ {±1} the LM normalisation constants of the case (so that φ = c_φ φ_g is the
    paper's/LM φ); the map is then ``GeneratingMap(phi_g, Phi_g, case, sign=case.sign)``.
    ValueError if a potential depends on a variable the case does not allow.
    """
    cf = case_forms(case)
    check_dependencies(cf.case, phi, Phi)
    reserved = set(y) | set(Y)
    for name, e in (("phi", phi), ("Phi", Phi)):
        bad = sp.sympify(e).free_symbols & reserved
        if bad:
            raise ValueError(
                f"{name} contains the generic symbols {', '.join(sorted(map(str, bad)))}: "
                "to_generic takes potentials in the paper's variables x1..x3, X1..X3"
            )
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    phi_g = cf.c_phi * sp.sympify(phi).xreplace({xm: y[2], xc: y[1], Xm: Y[2]})
    Phi_g = cf.c_Phi * sp.sympify(Phi).xreplace({xm: y[2], Xm: Y[2], Xc: Y[1]})
    params = tuple(
        sorted((phi_g.free_symbols | Phi_g.free_symbols) - set(y) - set(Y), key=str)
    )
    return GenericPotentials(cf.case, phi_g, Phi_g, cf.sign, cf.c_phi, cf.c_Phi, params)


def from_generic(case: Case | tuple, phi_g: sp.Expr, Phi_g: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """The inverse of :func:`to_generic`: generic-order expressions φ_g(Y3, y2, y3), Φ_g(Y3, Y2, y3)
    → LM-normalised (φ, Φ) of ``case`` in the paper's variables (φ = c_φ φ_g(X₋, x∘, x₋), …)."""
    cf = case_forms(case)
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    bad = (sp.sympify(phi_g).free_symbols & (set(x) | set(X) | {y[0], Y[0], Y[1]})) | (
        sp.sympify(Phi_g).free_symbols & (set(x) | set(X) | {y[0], y[1], Y[0]})
    )
    if bad:
        raise ValueError(
            f"generic potentials depend on {', '.join(sorted(map(str, bad)))}: phi_g must be a "
            "function of (Y3, y2, y3) and Phi_g of (Y3, Y2, y3)"
        )
    return (
        cf.c_phi * sp.sympify(phi_g).xreplace({Y[2]: Xm, y[1]: xc, y[2]: xm}),
        cf.c_Phi * sp.sympify(Phi_g).xreplace({Y[2]: Xm, Y[1]: Xc, y[2]: xm}),
    )


def flip_generic(phi_g: sp.Expr, Phi_g: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """(Φ_g·p, φ_g·p) in the generic order (prop:volpotinv, prop:switchperm), p = (3, 2, 1).

    The new φ is (Φ_g·p)(Y3, y2, y3) = Φ_g(y3, y2, Y3); the new Φ is (φ_g·p)(Y3, Y2, y3) =
    φ_g(y3, Y2, Y3).
    """
    new_phi = sp.sympify(Phi_g).xreplace({Y[2]: y[2], Y[1]: y[1], y[2]: Y[2]})
    new_Phi = sp.sympify(phi_g).xreplace({Y[2]: y[2], y[1]: Y[1], y[2]: Y[2]})
    return new_phi, new_Phi

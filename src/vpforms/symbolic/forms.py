"""The 36 Lomelí–Meiss generating one-forms, computed from (σ, Σ), and their symbolic proofs.

Everything here is *derived* from the permutation algebra of :mod:`vpforms._perm` — nothing is
typed in per case.  For a case (σ, Σ) the roles are (MATH.md §2; eq:notpzm with σ, not σ⁻¹)

    x₊ = x_{σ(1)}, x∘ = x_{σ(2)}, x₋ = x_{σ(3)},     X₊ = X_{Σ(1)}, X∘ = X_{Σ(2)}, X₋ = X_{Σ(3)},

and the map (σ,Σ)·f^s_{φ,Φ} is defined by eq:volpot read in the roles (eq:-o+general):

    ∂_{x∘} φ_g(X₋, x∘, x₋) = x₊                                   (volpot1)
    ∂_{x₋} Φ_g(X₋, X∘, x₋) + s ∂_{X₋} φ_g(X₋, x∘, x₋) = 0        (volpot2)
    X₊ = ∂_{X∘} Φ_g(X₋, X∘, x₋)                                   (volpot3)

On the graph Γ of this map, d(φ_g dx₋ − s Φ_g dX₋) = x₊ dx∘∧dx₋ − s X₊ dX∘∧dX₋.  The Lomelí–Meiss
primitives are ν = x_c dx_a∧dx_b and ν̃ = X_C dX_A∧dX_B with (a,b,c), (A,B,C) cyclic and c = x₊,
C = X₊, so ν = ε_σ x₊ dx∘∧dx₋ with ε_σ = ±1 read off the order of (a, b) against (x∘, x₋); hence the
LM one-form (eq:oneform, eq:nu_exact / eq:0806031)

    λ = φ dx_l + Φ dX_m,   l = x₋, m = X₋,   φ = c_φ φ_g,  Φ = c_Φ Φ_g,   c_φ = −ε_σ, c_Φ = ε_Σ,

satisfies f*ν̃ − ν = dλ exactly when s = ε_σ ε_Σ = sgn σ sgn Σ = sgn τ (the sign rule).  In this
normalisation the compatibility condition always reads ∂_{X₋}φ = ∂_{x₋}Φ.

:func:`prove_case` checks this on R⁶ for undefined SymPy functions φ_g, Φ_g: the 2-form
Θ = ν̃ − ν − dλ vanishes on Γ = {E₁ = E₂ = E₃ = 0} iff Θ ∧ dE₁ ∧ dE₂ ∧ dE₃ = 0 on Γ (the dE_i span
the conormal space of Γ); reduction modulo the determining equations replaces x₊, X₊ and ∂_{x₋}Φ_g
by what (volpot1–3) say they are.  det Df = −det(∂E/∂x)/det(∂E/∂X) by implicit differentiation.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import sympy as sp

from .._case import Case, cases
from .._perm import Perm
from ._symbols import X, x
from .exterior import Form, d, dvar, wedge, wedge_all

__all__ = [
    "CaseForms",
    "case_forms",
    "generic_equations",
    "lm_equations",
    "CaseProof",
    "prove_case",
    "prove_all",
    "cyclic_primitive",
    "identify_case",
    "check_dependencies",
]

Potential = Callable[..., sp.Expr]


def cyclic_primitive(c: int) -> tuple[int, int, int]:
    """(a, b, c) cyclic with the given c: the primitive x_c dx_a∧dx_b of dx1∧dx2∧dx3."""
    return (c % 3 + 1, (c + 1) % 3 + 1, c)


def _orientation(perm: Perm) -> int:
    """ε = +1 if (x∘, x₋) = (x_a, x_b) for the primitive with c = x₊, −1 if (x_b, x_a)."""
    a, b, _ = cyclic_primitive(perm(1))
    return 1 if (perm(2), perm(3)) == (a, b) else -1


@dataclass(frozen=True)
class CaseForms:
    """The Lomelí–Meiss data of one case (σ, Σ), all computed from σ and Σ.

    Attributes (indices are 1-based coordinates)
    ----------
    case:
        The :class:`vpforms.Case`.
    x_roles, X_roles:
        (x₊, x∘, x₋) and (X₊, X∘, X₋) as SymPy symbols.
    nu, nu_tilde:
        (a, b, c) and (A, B, C): ν = x_c dx_a∧dx_b, ν̃ = X_C dX_A∧dX_B (cyclic triples).
    k, K:
        The cyclic shifts of ν, ν̃ relative to Table tab:123123 (c = 3 ↔ k = 0, c = 1 ↔ 1, c = 2 ↔ 2).
    l, m:
        λ = φ dx_l + Φ dX_m; l = x₋ and m = X₋.
    c_phi, c_Phi:
        The LM normalisation constants: φ_LM = c_phi φ_g, Φ_LM = c_Phi Φ_g (each ±1).
    sign:
        sgn τ, the sign of (volpot2) (the sign rule).
    phi_args, Phi_args:
        The LM argument order φ(x₋, x∘, X₋), Φ(x₋, X₋, X∘).
    cell:
        The Lomelí–Meiss cell: column A if x₋ = x_a, B if x₋ = x_b; row C if X₋ = X_A, D if X₋ = X_B.
    """

    case: Case
    x_roles: tuple[sp.Symbol, sp.Symbol, sp.Symbol]
    X_roles: tuple[sp.Symbol, sp.Symbol, sp.Symbol]
    nu: tuple[int, int, int]
    nu_tilde: tuple[int, int, int]
    k: int
    K: int
    l: int
    m: int
    c_phi: int
    c_Phi: int
    sign: int
    cell: str
    phi_args: tuple[sp.Symbol, sp.Symbol, sp.Symbol] = field(repr=False)
    Phi_args: tuple[sp.Symbol, sp.Symbol, sp.Symbol] = field(repr=False)

    # -- the pieces of the one-form -----------------------------------------------------------
    @property
    def cls(self) -> str:
        return self.case.cls

    @property
    def tau(self) -> Perm:
        return self.case.tau

    def nu_form(self) -> Form:
        """ν = x_c dx_a ∧ dx_b on R⁶."""
        a, b, c = self.nu
        return x[c - 1] * wedge(dvar(x[a - 1]), dvar(x[b - 1]))

    def nu_tilde_form(self) -> Form:
        """ν̃ = X_C dX_A ∧ dX_B on R⁶."""
        A, B, C = self.nu_tilde
        return X[C - 1] * wedge(dvar(X[A - 1]), dvar(X[B - 1]))

    def lam_form(self, phi: sp.Expr, Phi: sp.Expr) -> Form:
        """λ = φ dx_l + Φ dX_m for LM-normalised potentials φ, Φ (eq:oneform)."""
        return phi * dvar(x[self.l - 1]) + Phi * dvar(X[self.m - 1])

    def undefined_potentials(
        self, names: tuple[str, str] = ("phi", "Phi")
    ) -> tuple[sp.Expr, sp.Expr]:
        """Undefined SymPy functions φ(x₋, x∘, X₋), Φ(x₋, X₋, X∘) in the LM argument order."""
        return (
            sp.Function(names[0], real=True)(*self.phi_args),
            sp.Function(names[1], real=True)(*self.Phi_args),
        )

    # -- the generic potentials ↔ LM potentials ---------------------------------------------------
    def lm_from_generic(self, phi_g: Potential, Phi_g: Potential) -> tuple[sp.Expr, sp.Expr]:
        """LM potentials (φ, Φ) in the paper's variables from generic ones φ_g(Y3,y2,y3), Φ_g."""
        xp, xc, xm = self.x_roles
        Xp, Xc, Xm = self.X_roles
        return self.c_phi * phi_g(Xm, xc, xm), self.c_Phi * Phi_g(Xm, Xc, xm)

    def twist_conditions(self) -> tuple[str, str]:
        """The twist conditions of the LM table: ∂X₋/∂x₊ ≠ 0 and ∂x₋/∂X₊ ≠ 0 (as text)."""
        xp, _, xm = self.x_roles
        Xp, _, Xm = self.X_roles
        return (f"∂{Xm}/∂{xp} ≠ 0", f"∂{xm}/∂{Xp} ≠ 0")

    def twist_potentials(self, phi: sp.Expr, Phi: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
        """The second derivatives that must not vanish: ∂²φ/∂x∘∂X₋ and ∂²Φ/∂x₋∂X∘.

        (∂X₋/∂x₊ = c_φ / ∂²φ/∂x∘∂X₋ and ∂x₋/∂X₊ = c_Φ / ∂²Φ/∂x₋∂X∘; see :func:`prove_case`.)
        """
        _, xc, xm = self.x_roles
        _, Xc, Xm = self.X_roles
        return sp.diff(phi, xc, Xm), sp.diff(Phi, xm, Xc)


@functools.lru_cache(maxsize=64)
def _case_forms(sigma: tuple[int, int, int], Sigma: tuple[int, int, int]) -> CaseForms:
    case = Case(sigma, Sigma)
    s, S = case.sigma, case.Sigma
    x_roles = tuple(x[s(i) - 1] for i in (1, 2, 3))
    X_roles = tuple(X[S(i) - 1] for i in (1, 2, 3))
    nu = cyclic_primitive(s(1))
    nu_tilde = cyclic_primitive(S(1))
    eps_s, eps_S = _orientation(s), _orientation(S)
    # The sign rule: on the graph d(φ_g dx₋ − sΦ_g dX₋) = x₊dx∘∧dx₋ − sX₊dX∘∧dX₋, while
    # ν̃ − ν = ε_Σ X₊dX∘∧dX₋ − ε_σ x₊dx∘∧dx₋; so λ = −ε_σ(φ_g dx₋ − sΦ_g dX₋) has dλ = ν̃ − ν iff
    # s = ε_σ ε_Σ, which coincides with sgn τ (checked here, not assumed).
    sign = eps_s * eps_S
    if sign != case.sign:  # pragma: no cover - a contradiction in the permutation algebra
        raise AssertionError(f"ε_σ ε_Σ = {sign} ≠ sgn τ = {case.sign} for {case}")
    a, b, _ = nu
    A, B, _ = nu_tilde
    cell = ("A" if s(3) == a else "B") + ("C" if S(3) == A else "D")
    xp, xc, xm = x_roles
    Xp, Xc, Xm = X_roles
    return CaseForms(
        case=case,
        x_roles=x_roles,  # type: ignore[arg-type]
        X_roles=X_roles,  # type: ignore[arg-type]
        nu=nu,
        nu_tilde=nu_tilde,
        k=nu[2] % 3,
        K=nu_tilde[2] % 3,
        l=s(3),
        m=S(3),
        c_phi=-eps_s,
        c_Phi=eps_S,
        sign=sign,
        cell=cell,
        phi_args=(xm, xc, Xm),
        Phi_args=(xm, Xm, Xc),
    )


def case_forms(case: Case | tuple) -> CaseForms:
    """The :class:`CaseForms` of a case (a :class:`vpforms.Case` or a pair (σ, Σ))."""
    if not isinstance(case, Case):
        case = Case(*case)
    return _case_forms(tuple(case.sigma), tuple(case.Sigma))


def resolve_sign(cf: CaseForms, sign: int | None) -> int:
    """The sign of volpot2: sgn τ of the case if ``sign`` is None, else ``sign`` (±1 only)."""
    if sign is None:
        return cf.sign
    if isinstance(sign, bool) or sign not in (1, -1):
        raise ValueError(f"sign must be +1 or -1 (or None for sgn τ), got {sign!r}")
    return int(sign)


def _slot_diff(P: Potential, args: tuple, i: int) -> sp.Expr:
    """∂_i P at the point ``args`` (distinct symbols), i = 1, 2, 3."""
    return sp.diff(P(*args), args[i - 1])


def _undefined(name: str) -> Potential:
    f = sp.Function(name, real=True)
    return lambda *u: f(*u)


def generic_equations(
    case: Case | tuple,
    phi_g: Potential | None = None,
    Phi_g: Potential | None = None,
    sign: int | None = None,
) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """(E₁, E₂, E₃) with E_i = 0 ⇔ eq:volpot for the case, on R⁶ = {(x, X)} (eq:-o+general).

    ``phi_g`` and ``Phi_g`` are callables of three arguments in the *generic* order
    (φ_g(Y₃, y₂, y₃), Φ_g(Y₃, Y₂, y₃)); default: undefined functions ``phi_g``, ``Phi_g``.
    ``sign`` defaults to sgn τ.

        E₁ = ∂₂φ_g(X₋, x∘, x₋) − x₊,   E₂ = ∂₃Φ_g(X₋, X∘, x₋) + s ∂₁φ_g(X₋, x∘, x₋),
        E₃ = ∂₂Φ_g(X₋, X∘, x₋) − X₊.
    """
    cf = case_forms(case)
    s = resolve_sign(cf, sign)
    phi_g = phi_g or _undefined("phi_g")
    Phi_g = Phi_g or _undefined("Phi_g")
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    E1 = _slot_diff(phi_g, (Xm, xc, xm), 2) - xp  # volpot1
    E2 = _slot_diff(Phi_g, (Xm, Xc, xm), 3) + s * _slot_diff(phi_g, (Xm, xc, xm), 1)  # volpot2
    E3 = _slot_diff(Phi_g, (Xm, Xc, xm), 2) - Xp  # volpot3
    return E1, E2, E3


def lm_equations(
    case: Case | tuple, phi: sp.Expr | None = None, Phi: sp.Expr | None = None
) -> tuple[sp.Eq, sp.Eq, sp.Eq]:
    """The three LM determining/compatibility equations (Table tab:123123 and its relabellings).

    x₊ = c_φ ∂_{x∘}φ,   ∂_{X₋}φ = ∂_{x₋}Φ,   X₊ = c_Φ ∂_{X∘}Φ   for φ(x₋, x∘, X₋), Φ(x₋, X₋, X∘).
    Returned unevaluated (``evaluate=False``) so that they display as printed.
    """
    cf = case_forms(case)
    check_dependencies(cf.case, 0 if phi is None else phi, 0 if Phi is None else Phi)
    if phi is None or Phi is None:
        phi0, Phi0 = cf.undefined_potentials()
        phi = phi0 if phi is None else phi
        Phi = Phi0 if Phi is None else Phi
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    return (
        sp.Eq(xp, cf.c_phi * sp.diff(phi, xc), evaluate=False),
        sp.Eq(sp.diff(phi, Xm), sp.diff(Phi, xm), evaluate=False),
        sp.Eq(Xp, cf.c_Phi * sp.diff(Phi, Xc), evaluate=False),
    )


def check_dependencies(case: Case | tuple, phi: sp.Expr, Phi: sp.Expr) -> None:
    """ValueError if φ or Φ depends on a variable its case does not allow.

    φ may depend on (x₋, x∘, X₋) and Φ on (x₋, X₋, X∘) of the case (plus any parameter that is not
    one of x1..x3, X1..X3).
    """
    cf = case_forms(case)
    coords = set(x) | set(X)
    for name, expr, allowed in (("phi", phi, cf.phi_args), ("Phi", Phi, cf.Phi_args)):
        try:
            expr = sp.sympify(expr)
        except (TypeError, sp.SympifyError):
            raise ValueError(f"{name} must be a SymPy expression, got {expr!r}") from None
        bad = (expr.free_symbols & coords) - set(allowed)
        if bad:
            raise ValueError(
                f"{name} depends on {', '.join(sorted(map(str, bad)))}, which case {cf.case} does "
                f"not allow: {name} must be a function of "
                f"({', '.join(map(str, allowed))}) only"
            )


# ------------------------------------------------------------------------------------------------
# Proofs
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CaseProof:
    """What :func:`prove_case` established for one case and sign (all decided by exact expansion).

    one_form_holds:
        f*ν̃ − ν − dλ = 0 on the graph, for undefined potentials (reduced 5-form ``residual`` = 0).
    det, det_expected:
        det Df computed by implicit differentiation (an expression that simplified to a constant,
        or the unsimplified ratio), and sign·sgn σ·sgn Σ.
    det_holds:
        det Df − sign·sgn σ·sgn Σ expanded to exactly 0.
    twist_holds:
        ∂X₋/∂x₊ · ∂²φ_g/∂Y₃∂y₂ = 1 and ∂x₋/∂X₊ · ∂²Φ_g/∂Y₂∂y₃ = 1, i.e. the two LM twist conditions
        are exactly the solvability conditions ∂₁₂φ_g ≠ 0, ∂₂₃Φ_g ≠ 0 of eq:volpot.
    lm_equivalent:
        The LM equations (:func:`lm_equations`) for φ = c_φφ_g, Φ = c_Φ Φ_g are ±(E₁, E₂, E₃).
    """

    case: Case
    sign: int
    one_form_holds: bool
    residual: dict
    det: sp.Expr
    det_expected: int
    det_holds: bool
    twist_holds: bool
    lm_equivalent: bool

    @property
    def holds(self) -> bool:
        return self.one_form_holds and self.det_holds and self.twist_holds and self.lm_equivalent


def prove_case(case: Case | tuple, sign: int | None = None) -> CaseProof:
    """Prove the generating-form identity, det Df and the twist conditions for one case.

    With ``sign=None`` the sign rule s = sgn τ is used; pass the opposite sign to see the identity
    fail and det Df = −1.
    """
    cf = case_forms(case)
    s = resolve_sign(cf, sign)
    phi_g, Phi_g = _undefined("phi_g"), _undefined("Phi_g")
    E = generic_equations(cf.case, phi_g, Phi_g, s)
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    phi_e, Phi_e = phi_g(Xm, xc, xm), Phi_g(Xm, Xc, xm)

    # --- f*ν̃ − ν = dλ on Γ (eq:0806031): Θ ∧ dE₁ ∧ dE₂ ∧ dE₃ ≡ 0 modulo E.
    lam = cf.lam_form(cf.c_phi * phi_e, cf.c_Phi * Phi_e)
    theta = cf.nu_tilde_form() - cf.nu_form() - d(lam)
    five = wedge(theta, wedge_all([d(e) for e in E]))
    reduce = {  # the determining equations, solved for x₊, X₊ and ∂_{x₋}Φ_g
        xp: sp.diff(phi_e, xc),
        Xp: sp.diff(Phi_e, Xc),
        sp.diff(Phi_e, xm): -s * sp.diff(phi_e, Xm),
    }
    residual = five.map_coefficients(lambda c: sp.expand(c.xreplace(reduce))).nonzero_components()

    # --- det Df by implicit differentiation: E(x, X(x)) = 0 ⇒ DX = −(∂E/∂X)⁻¹ ∂E/∂x.
    Jx = sp.Matrix(3, 3, lambda i, j: sp.diff(E[i], x[j]))
    JX = sp.Matrix(3, 3, lambda i, j: sp.diff(E[i], X[j]))
    det_x = sp.expand(Jx.det(method="berkowitz"))
    det_X = sp.expand(JX.det(method="berkowitz"))
    expected = s * cf.case.sigma.sign * cf.case.Sigma.sign
    det_holds = sp.expand(-det_x - expected * det_X) == 0
    det = sp.cancel(-det_x / det_X) if det_X != 0 else sp.nan

    # --- the twist conditions: ∂X₋/∂x₊ = 1/∂₁₂φ_g and ∂x₋/∂X₊ = 1/∂₂₃Φ_g.
    d12phi = sp.diff(phi_e, Xm, xc)
    d23Phi = sp.diff(Phi_e, Xc, xm)
    DX = -JX.adjugate() * Jx / det_X  # DX/Dx
    Dx = -Jx.adjugate() * JX / det_x  # Dx/DX (the inverse map)
    t1 = sp.cancel(DX[X.index(Xm), x.index(xp)] * d12phi - 1)
    t2 = sp.cancel(Dx[x.index(xm), X.index(Xp)] * d23Phi - 1)
    twist_holds = t1 == 0 and t2 == 0

    # --- the displayed LM equations are (−E₁, −c_Φ E₂, −E₃): the same map, normalised.
    L = lm_equations(cf.case, cf.c_phi * phi_e, cf.c_Phi * Phi_e)
    lm_equivalent = all(
        sp.expand((eq.lhs - eq.rhs) + k * e) == 0 for eq, e, k in zip(L, E, (1, cf.c_Phi, 1))
    )
    return CaseProof(
        case=cf.case,
        sign=s,
        one_form_holds=not residual,
        residual=residual,
        det=det,
        det_expected=expected,
        det_holds=det_holds,
        twist_holds=twist_holds,
        lm_equivalent=lm_equivalent,
    )


def prove_all(sign_rule: bool = True) -> dict[Case, CaseProof]:
    """:func:`prove_case` for all 36 cases (with the sign rule, or with the opposite sign)."""
    return {c: prove_case(c, None if sign_rule else -c.sign) for c in cases()}


def identify_case(phi: sp.Expr, Phi: sp.Expr, l: int, m: int) -> Case:
    """The case (σ, Σ) of a Lomelí–Meiss one-form λ = φ dx_l + Φ dX_m (eq:oneform).

    In every case l = x₋ and m = X₋, φ depends on (x₋, x∘, X₋) and Φ on (x₋, X₋, X∘); so x∘ is the
    one old variable other than x_l that φ depends on, X∘ the one new variable other than X_m that Φ
    depends on, and then σ = (x₊, x∘, x₋), Σ = (X₊, X∘, X₋).  ValueError if λ fits no case.
    """
    if l not in (1, 2, 3) or m not in (1, 2, 3):
        raise ValueError(f"l and m are coordinate indices 1, 2, 3; got l={l!r}, m={m!r}")
    fphi, fPhi = sp.sympify(phi).free_symbols, sp.sympify(Phi).free_symbols
    xc = [i for i in (1, 2, 3) if i != l and x[i - 1] in fphi]
    Xc = [i for i in (1, 2, 3) if i != m and X[i - 1] in fPhi]
    if len(xc) != 1 or len(Xc) != 1:
        raise ValueError(
            f"λ = φ dx{l} + Φ dX{m} fits no case: φ must depend on exactly one of the old variables "
            f"other than x{l} (it depends on {sorted(map(str, fphi & set(x)))}) and Φ on exactly "
            f"one new variable other than X{m} (it depends on {sorted(map(str, fPhi & set(X)))})"
        )
    xp = ({1, 2, 3} - {l, xc[0]}).pop()
    Xp = ({1, 2, 3} - {m, Xc[0]}).pop()
    case = Case((xp, xc[0], l), (Xp, Xc[0], m))
    cf = case_forms(case)
    bad = (fphi & (set(x) | set(X))) - set(cf.phi_args) or (fPhi & (set(x) | set(X))) - set(
        cf.Phi_args
    )
    if bad:
        raise ValueError(
            f"λ = φ dx{l} + Φ dX{m} fits no case: {', '.join(sorted(map(str, bad)))} not allowed "
            f"(the nearest case {case} has φ{cf.phi_args}, Φ{cf.Phi_args})"
        )
    return case

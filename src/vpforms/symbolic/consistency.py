"""Symbolic consistency of a pair of potentials (def:conssol): M(0) = I?, M'(0) = A?, order, det.

For a case (σ, Σ), LM-normalised potentials φ(h), Φ(h) (paper variables, see
:mod:`vpforms.symbolic.recipes`) and a divergence-free field a, the map x ↦ X is solved from the
determining equations of the case *symbolically*:

* **linear fields** (a = A x, quadratic potentials): every equation is linear in its unknown, the
  map is X = M(h) x exactly, and M(h) is expanded in h by exact power-series division of its
  rational entries; det M(h) is computed exactly;
* **polynomial fields** (or non-quadratic potentials): X(h) is computed as a truncated power series
  in h, order by order, and compared with the Lie series of the exact flow
  x + h a + h²/2 (a·∇)a + …; det DX is then known to O(h^{n+1}).

Symbols ``a11 … a33`` in the potentials are read as the entries of the field's matrix (so a recipe
from :mod:`vpforms.symbolic.recipes` can be passed as is with a concrete matrix).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .._case import Case
from ._symbols import A as A_SYM
from ._symbols import X, h, x
from .forms import case_forms
from .recipes import _field, as_matrix, check_dependencies, linear_field

__all__ = ["ConsistencyResult", "consistency", "solve_linear_map", "generic_traceless_matrix"]


def generic_traceless_matrix() -> sp.Matrix:
    """The generic traceless matrix: symbols a11 … a32 and a33 = −a11 − a22."""
    return A_SYM.subs(A_SYM[2, 2], -A_SYM[0, 0] - A_SYM[1, 1])


@dataclass(frozen=True)
class ConsistencyResult:
    """The outcome of :func:`consistency` (all entries decided by exact arithmetic).

    identity_at_0:
        M(0) = I (for series: X(h=0) = x).
    consistent:
        M(0) = I and M'(0) = A (def:conssol): X = x + h a(x) + O(h²).
    order:
        The largest p ≤ ``n_terms`` such that the Taylor coefficients of the map agree with the
        exact flow up to h^p (−1 if already M(0) ≠ I or M(0) is not finite, 0 if M'(0) ≠ A).
        ``order == n_terms`` means "at least n_terms".
    det:
        det M(h) (exact, linear case) or the series of det DX to O(h^{n_terms+1}).
    det_is_one:
        det ≡ 1 (exactly for linear fields; to O(h^{n_terms+1}) for series).
    M, M0, M1:
        Linear case: ``M.matrix`` is the exact M(h) = −P⁻¹Q (computed on first use; ``M.P``,
        ``M.Q`` the polynomial system P X + Q x = 0), M0, M1 its Taylor coefficients.
    X:
        Series case: the solved map as truncated series in h (None in the linear case).
    """

    case: Case
    linear: bool
    identity_at_0: bool
    consistent: bool
    order: int
    n_terms: int
    det: sp.Expr
    det_is_one: bool
    M: "_LazyM | None"
    M0: sp.Matrix | None
    M1: sp.Matrix | None
    X: tuple[sp.Expr, sp.Expr, sp.Expr] | None

    @property
    def defects(self) -> tuple[str, ...]:
        """The failed properties, in the words of the errata report."""
        out = []
        if not self.consistent:
            out.append("inconsistent" + ("" if self.identity_at_0 else " (M(0) ≠ I)"))
        elif self.order != 1 and self.order < self.n_terms:
            out.append(f"order {self.order}")
        if not self.det_is_one:
            out.append("det ≠ 1")
        return tuple(out)


def _lm_residuals(case: Case, phi, Phi, sign: int | None):
    """(E₁, E₂, E₃) for LM potentials; E₂ = c_Φ ∂_{x₋}Φ + s c_φ ∂_{X₋}φ is volpot2 for any sign."""
    cf = case_forms(case)
    s = cf.sign if sign is None else int(sign)
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    E1 = cf.c_phi * sp.diff(phi, xc) - xp  # volpot1: x₊ = ∂_{x∘}φ_g
    E2 = cf.c_Phi * sp.diff(Phi, xm) + s * cf.c_phi * sp.diff(phi, Xm)  # volpot2
    E3 = cf.c_Phi * sp.diff(Phi, Xc) - Xp  # volpot3: X₊ = ∂_{X∘}Φ_g
    return cf, (E1, E2, E3)


def _solve_linear_in(E: sp.Expr, v: sp.Symbol) -> sp.Expr | None:
    """The solution of E(v) = 0 if E is affine in v with a non-zero slope, else None."""
    slope = sp.cancel(sp.diff(E, v))
    if slope == 0 or slope.has(v):
        return None
    return sp.cancel(-E.xreplace({v: 0}) / slope)


def solve_linear_map(case: Case, phi, Phi, sign: int | None = None):
    """Solve the three equations in sequence (X₋ from volpot1, X∘ from volpot2, X₊ from volpot3)
    when each is linear in its unknown; returns X = (X1, X2, X3) as expressions, or None."""
    cf, (E1, E2, E3) = _lm_residuals(case, phi, Phi, sign)
    Xp, Xc, Xm = cf.X_roles
    Xm_sol = _solve_linear_in(E1, Xm)
    if Xm_sol is None:
        return None
    Xc_sol = _solve_linear_in(sp.cancel(E2.xreplace({Xm: Xm_sol})), Xc)
    if Xc_sol is None:
        return None
    Xp_sol = sp.cancel((E3 + Xp).xreplace({Xm: Xm_sol, Xc: Xc_sol}))
    sol = {Xp: Xp_sol, Xc: Xc_sol, Xm: Xm_sol}
    return tuple(sol[v] for v in X)


def _taylor_rational(expr: sp.Expr, n: int) -> list[sp.Expr] | None:
    """Taylor coefficients c_0..c_n in h of a rational function (None if it has a pole at h=0)."""
    num, den = sp.fraction(sp.cancel(sp.together(expr)))
    P = sp.Poly(sp.expand(num), h)
    Q = sp.Poly(sp.expand(den), h)
    p = [P.coeff_monomial(h**k) for k in range(n + 1)]
    q = [Q.coeff_monomial(h**k) for k in range(n + 1)]
    if sp.expand(q[0]) == 0:
        return None
    c: list[sp.Expr] = []
    for k in range(n + 1):
        ck = (p[k] - sum(q[j] * c[k - j] for j in range(1, k + 1))) / q[0]
        c.append(sp.cancel(ck))
    return c


def _mat_zero(M: sp.Matrix) -> bool:
    return all(sp.cancel(e) == 0 for e in M)


def consistency(
    case: Case | tuple,
    phi,
    Phi,
    field,
    *,
    sign: int | None = None,
    n_terms: int = 2,
) -> ConsistencyResult:
    """Is h ↦ (σ,Σ)·f_{φ(h),Φ(h)} consistent with the field (def:conssol)? Order? det?

    Parameters
    ----------
    case:
        The case (a :class:`vpforms.Case` or (σ, Σ)).
    phi, Phi:
        SymPy expressions in the LM variables of the case (φ(x₋, x∘, X₋), Φ(x₋, X₋, X∘)), h and
        parameters; ``a11 … a33`` are replaced by the entries of a matrix ``field``.
    field:
        A traceless 3×3 matrix (linear field a = A x; nested lists, numpy or SymPy Matrix) or three
        SymPy expressions in x1, x2, x3 (a divergence-free field).  ValueError if malformed, not
        traceless, or not divergence free.
    sign:
        The sign of volpot2 (default: sgn τ).  The opposite sign gives det = −1.
    n_terms:
        The highest power of h compared with the exact flow (order is reported up to it).
    """
    if not isinstance(case, Case):
        case = Case(*case)
    matrix = None
    if isinstance(field, sp.MatrixBase) or hasattr(field, "shape") or (
        hasattr(field, "__len__") and any(hasattr(r, "__len__") for r in field)
    ):
        matrix = as_matrix(field)
        comps = linear_field(matrix)
        sub = {A_SYM[i, j]: matrix[i, j] for i in range(3) for j in range(3)}
        phi = sp.sympify(phi).xreplace(sub)
        Phi = sp.sympify(Phi).xreplace(sub)
    else:
        comps = _field(field)
    check_dependencies(case, phi, Phi)
    cf = case_forms(case)

    if matrix is not None:
        lin = _linear_system(case, phi, Phi, sign)
        if lin is not None:
            return _linear_result(case, lin, matrix, n_terms)
    return _series_result(case, phi, Phi, comps, sign, n_terms)


def _linear_system(case, phi, Phi, sign):
    """E = P X + Q x with polynomial P, Q (rows cleared of denominators and of common powers of
    h), or None if some equation is not linear homogeneous in (x, X)."""
    cf, E = _lm_residuals(case, phi, Phi, sign)
    P = sp.zeros(3, 3)
    Q = sp.zeros(3, 3)
    for i, e in enumerate(E):
        num, den = sp.fraction(sp.together(e))
        if den.has(*x, *X):
            return None
        num = sp.expand(num)
        try:
            poly = sp.Poly(num, *x, *X)
        except sp.PolynomialError:
            return None
        if poly.total_degree() > 1 or poly.coeff_monomial(1) != 0:
            return None
        row = [poly.coeff_monomial(v) for v in x + X]
        # divide the row by the largest power of h dividing all its entries (regular at h = 0)
        vals = [min(m[0] for m in sp.Poly(c, h).monoms()) if c != 0 else 10**9 for c in row]
        v = min(vals)
        if v == 10**9:
            return None
        row = [sp.expand(sp.cancel(c / h**v)) for c in row]
        for j in range(3):
            Q[i, j] = row[j]
            P[i, j] = row[3 + j]
    return P, Q


def _poly_coeffs(M: sp.Matrix, n: int) -> list[sp.Matrix]:
    return [M.applyfunc(lambda e: sp.expand(e).coeff(h, k)) for k in range(n + 1)]


def _linear_result(case, PQ, Am, n) -> ConsistencyResult:
    P, Q = PQ  # P X + Q x = 0  ⇒  X = M(h) x, M = −P⁻¹Q
    detP = sp.expand(P.det(method="berkowitz"))
    detQ = sp.expand(Q.det(method="berkowitz"))
    if detP == 0:  # the determining equations do not determine X (twist fails identically)
        nan = (sp.nan,) * 3
        return ConsistencyResult(case, True, False, False, -1, n, sp.nan, False, None, None, None,
                                 nan)
    det = sp.cancel(-detQ / detP)  # det M = det(−Q)/det P
    det_is_one = sp.expand(detQ + detP) == 0
    # M = N / det P with N = −adj(P) Q: Taylor coefficients by power-series division, all
    # polynomial arithmetic in h (and the symbols of A).
    N = (-(P.adjugate() * Q)).applyfunc(sp.expand)
    Dp = sp.Poly(detP, h)
    v = min(m[0] for m in Dp.monoms())
    Npolys = [sp.Poly(e, h) for e in N]
    order, M0, M1 = -1, None, None
    finite = all(e.is_zero or min(m[0] for m in e.monoms()) >= v for e in Npolys)
    if finite:
        q = [Dp.coeff_monomial(h ** (v + k)) for k in range(n + 1)]
        Mk = [sp.zeros(3, 3) for _ in range(n + 1)]
        for idx, e in enumerate(Npolys):
            p_ = [e.coeff_monomial(h ** (v + k)) for k in range(n + 1)]
            c: list[sp.Expr] = []
            for k in range(n + 1):
                c.append(sp.cancel((p_[k] - sum(q[j] * c[k - j] for j in range(1, k + 1))) / q[0]))
                Mk[k][idx] = c[k]
        M0, M1 = Mk[0], (Mk[1] if n >= 1 else None)
        Ak = sp.eye(3)
        for k in range(n + 1):  # exp(hA) = Σ A^k h^k / k!
            if not _mat_zero(Mk[k] - Ak / sp.factorial(k)):
                break
            order = k
            Ak = Ak * Am
    return ConsistencyResult(
        case=case,
        linear=True,
        identity_at_0=order >= 0,
        consistent=order >= 1,
        order=order,
        n_terms=n,
        det=det,
        det_is_one=det_is_one,
        M=_LazyM(P, Q),
        M0=M0,
        M1=M1,
        X=None,
    )


class _LazyM:
    """M(h) = −P⁻¹Q, computed on first use (it can be large for a symbolic matrix)."""

    def __init__(self, P, Q):
        self.P, self.Q = P, Q
        self._M = None

    @property
    def matrix(self) -> sp.Matrix:
        if self._M is None:
            self._M = (-(self.P.adjugate() * self.Q) / self.P.det()).applyfunc(sp.cancel)
        return self._M

    def __repr__(self) -> str:
        return f"M(h) = -P^-1 Q with P = {self.P}, Q = {self.Q}"


def _truncate(e: sp.Expr, n: int) -> sp.Expr:
    e = sp.expand(e)
    return sum((e.coeff(h, k) * h**k for k in range(n + 1)), sp.S.Zero)


def _series_root(E: sp.Expr, v: sp.Symbol, guess: sp.Expr, n: int) -> sp.Expr | None:
    """v(h) = c0 + c1 h + … + cn h^n solving E(v, h) = 0 order by order (None if impossible)."""
    num = sp.expand(sp.numer(sp.together(E)))
    cs = sp.symbols(f"c0:{n + 1}")
    sub = sp.expand(num.xreplace({v: sum(c * h**k for k, c in enumerate(cs))}))
    poly = sp.Poly(sub, h)
    coeffs = [sp.expand(poly.coeff_monomial(h**k)) for k in range(poly.degree() + 1)]
    m0 = next((k for k, c in enumerate(coeffs) if c != 0), None)
    if m0 is None:
        return None
    roots = sp.solve(coeffs[m0], cs[0])
    if not roots:
        return None
    c0 = next((r for r in roots if sp.expand(r - guess) == 0), roots[0])
    vals = {cs[0]: c0}
    for k in range(1, n + 1):
        eq = sp.expand(coeffs[m0 + k].xreplace(vals)) if m0 + k < len(coeffs) else sp.S.Zero
        slope = sp.diff(eq, cs[k])
        if slope == 0:
            return None
        vals[cs[k]] = sp.expand(-eq.xreplace({cs[k]: 0}) / slope)
    return sum((vals[c] * h**k for k, c in enumerate(cs)), sp.S.Zero)


def _series_result(case, phi, Phi, comps, sign, n) -> ConsistencyResult:
    cf, (E1, E2, E3) = _lm_residuals(case, phi, Phi, sign)
    # Later stages may divide by powers of h (e.g. (X₋ − x₋)/h in a discrete Lagrangian), so the
    # earlier unknowns are solved to a few more orders than reported.
    n_out, n = n, n + 3
    Xp, Xc, Xm = cf.X_roles
    ident = dict(zip(X, x))
    Xm_s = _series_root(E1, Xm, ident[Xm], n)
    Xc_s = None
    if Xm_s is not None:
        Xc_s = _series_root(sp.together(E2).xreplace({Xm: Xm_s}), Xc, ident[Xc], n)
    if Xc_s is None:
        nan = (sp.nan,) * 3
        return ConsistencyResult(case, False, False, False, -1, n_out, sp.nan, False, None, None,
                                 None, nan)
    Xp_s = sp.series(sp.together(E3 + Xp).xreplace({Xm: Xm_s, Xc: Xc_s}), h, 0, n_out + 1).removeO()
    n = n_out
    sol = {Xp: _truncate(Xp_s, n), Xc: _truncate(Xc_s, n), Xm: _truncate(Xm_s, n)}
    Xs = tuple(sol[v] for v in X)
    # The exact flow's Lie series: T_0 = x, T_k = (a·∇ T_{k−1}) / k.
    T = [list(x)]
    for k in range(1, n + 1):
        T.append([sp.expand(sum(ai * sp.diff(t, xi) for ai, xi in zip(comps, x)) / k)
                  for t in T[-1]])
    order = -1
    for k in range(n + 1):
        if any(sp.expand(Xs[i].coeff(h, k) - T[k][i]) != 0 for i in range(3)):
            break
        order = k
    J = sp.Matrix(3, 3, lambda i, j: sp.diff(Xs[i], x[j]))
    det = _truncate(J.det(method="berkowitz"), n)
    return ConsistencyResult(
        case=case,
        linear=False,
        identity_at_0=order >= 0,
        consistent=order >= 1,
        order=order,
        n_terms=n,
        det=det,
        det_is_one=sp.expand(det - 1) == 0,
        M=None,
        M0=None,
        M1=None,
        X=Xs,
    )

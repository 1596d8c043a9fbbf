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
from .forms import case_forms, resolve_sign
from .recipes import _field, _is_matrix_like, as_matrix, check_dependencies, linear_field

__all__ = ["ConsistencyResult", "consistency", "generic_traceless_matrix"]


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
    pole_at_0:
        Linear case: M(h) has a pole at h = 0 (so M(0) does not exist).
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
    pole_at_0: bool = False

    @property
    def defects(self) -> tuple[str, ...]:
        """The failed properties, in the words of the errata report."""
        out = []
        if not self.consistent:
            if self.linear:
                why = (" (M(h) has a pole at h = 0)" if self.pole_at_0
                       else " (M'(0) ≠ A)" if self.identity_at_0 else " (M(0) ≠ I)")
            else:
                why = " ((X − x)/h ↛ a)" if self.identity_at_0 else " (X(h = 0) ≠ x)"
            out.append("inconsistent" + why)
        elif self.order != 1 and self.order < self.n_terms:
            out.append(f"order {self.order}")
        if not self.det_is_one:
            out.append("det ≠ 1")
        return tuple(out)


def _lm_residuals(case: Case, phi, Phi, sign: int | None):
    """(E₁, E₂, E₃) for LM potentials; E₂ = c_Φ ∂_{x₋}Φ + s c_φ ∂_{X₋}φ is volpot2 for any sign."""
    cf = case_forms(case)
    s = resolve_sign(cf, sign)
    xp, xc, xm = cf.x_roles
    Xp, Xc, Xm = cf.X_roles
    E1 = cf.c_phi * sp.diff(phi, xc) - xp  # volpot1: x₊ = ∂_{x∘}φ_g
    E2 = cf.c_Phi * sp.diff(Phi, xm) + s * cf.c_phi * sp.diff(phi, Xm)  # volpot2
    E3 = cf.c_Phi * sp.diff(Phi, Xc) - Xp  # volpot3: X₊ = ∂_{X∘}Φ_g
    return cf, (E1, E2, E3)


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

    Raises ValueError (never a NaN result) if the potentials are not finite for the field (a
    recipe dividing by a vanishing a_ij) or do not determine a map (a twist condition fails
    identically).
    """
    if not isinstance(case, Case):
        case = Case(*case)
    matrix = None
    if _is_matrix_like(field):
        matrix = as_matrix(field)
        comps = linear_field(matrix)
        sub = {A_SYM[i, j]: matrix[i, j] for i in range(3) for j in range(3)}
        phi = sp.sympify(phi).xreplace(sub)
        Phi = sp.sympify(Phi).xreplace(sub)
    else:
        comps = _field(field)
    check_dependencies(case, phi, Phi)
    cf = case_forms(case)
    for name, e in (("phi", phi), ("Phi", Phi)):
        if sp.sympify(e).has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            raise ValueError(
                f"{name} is not finite for this field (it divides by zero once the matrix entries "
                "are substituted; e.g. the S1 recipes need a13 ≠ 0, S2 needs a12, a13 ≠ 0)"
            )

    if matrix is not None:
        lin = _linear_system(case, sp.sympify(phi), sp.sympify(Phi), sign)
        if lin is not None:
            return _linear_result(case, lin, matrix, n_terms)
    return _series_result(case, phi, Phi, comps, sign, n_terms)


def _linear_system(case, phi, Phi, sign):
    """E = P X + Q x with P, Q polynomial matrices (elements of a SymPy polynomial ring over
    Q in x, X, h and the parameters), each row cleared of its denominator and of the largest power
    of h dividing it; or None if some equation is not linear and homogeneous in (x, X)."""
    cf, E = _lm_residuals(case, phi, Phi, sign)
    params = sorted(
        set().union(*(e.free_symbols for e in E)) - set(x) - set(X) - {h}, key=str
    )
    try:
        K = sp.field((*x, *X, h, *params), sp.QQ)[0]
        fracs = [K.from_expr(e) for e in E]
    except (sp.PolynomialError, ValueError, TypeError, sp.CoercionFailed):
        return None  # not rational in the variables: leave it to the series path
    R = K.ring
    zero6 = (0,) * 6
    P = [[R.zero] * 3 for _ in range(3)]
    Q = [[R.zero] * 3 for _ in range(3)]
    for i, f in enumerate(fracs):
        num, den = f.numer, f.denom
        if any(m[:6] != zero6 for m in den.monoms()):
            return None
        if not num or any(sum(m[:6]) != 1 for m in num.monoms()):
            return None  # not linear homogeneous in (x, X)
        v = min(m[6] for m in num.monoms())  # divide the row by h^v: regular at h = 0
        for j in range(6):
            cj = R.from_dict(
                {m[:j] + (0,) + m[j + 1:6] + (m[6] - v,) + m[7:]: c
                 for m, c in num.items() if m[j] == 1}
            )
            (Q if j < 3 else P)[i][j % 3] = cj
    return K, P, Q


def _twist_error(case) -> ValueError:
    cf = case_forms(case)
    _, xc, xm = cf.x_roles
    _, Xc, Xm = cf.X_roles
    return ValueError(
        f"the potentials do not determine a map for {case}: a twist condition fails identically "
        f"(∂²φ/∂{xc}∂{Xm} ≠ 0 and ∂²Φ/∂{xm}∂{Xc} ≠ 0 are needed, eq:volpot)"
    )


def _det3(M):
    return (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1])
            - M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0])
            + M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]))


def _adj3(M):
    def cof(i, j):
        r = [k for k in range(3) if k != i]
        c = [k for k in range(3) if k != j]
        minor = M[r[0]][c[0]] * M[r[1]][c[1]] - M[r[0]][c[1]] * M[r[1]][c[0]]
        return minor if (i + j) % 2 == 0 else -minor

    return [[cof(j, i) for j in range(3)] for i in range(3)]  # adj = cofactor matrixᵀ


def _h_coeffs(p, zero):
    """{k: coefficient of h^k} of a ring element (h is generator 6), h exponent set to 0."""
    out: dict[int, dict] = {}
    for m, c in p.items():
        out.setdefault(m[6], {})[m[:6] + (0,) + m[7:]] = c
    return {k: zero.ring.from_dict(d) for k, d in out.items()}


def _linear_result(case, system, Am, n) -> ConsistencyResult:
    K, P, Q = system  # P X + Q x = 0  ⇒  X = M(h) x, M = −P⁻¹Q
    R = K.ring
    detP, detQ = _det3(P), _det3(Q)
    to_mat = lambda M: sp.Matrix(3, 3, lambda i, j: M[i][j].as_expr())  # noqa: E731
    if not detP:  # the determining equations do not determine X (twist fails identically)
        raise _twist_error(case)
    det_is_one = not (detQ + detP)  # det M = det(−Q)/det P
    det = (sp.S.One if det_is_one else sp.S.NegativeOne if not (detQ - detP)
           else (-K.field_new(detQ) / K.field_new(detP)).as_expr())
    # M = N / det P with N = −adj(P) Q: Taylor coefficients in h by power-series division; the
    # coefficients live in the fraction field (exact, automatically cancelled).
    adj = _adj3(P)
    N = [[-sum((adj[i][k] * Q[k][j] for k in range(3)), R.zero) for j in range(3)]
         for i in range(3)]
    Dk = _h_coeffs(detP, R.zero)
    v = min(Dk)
    order, M0, M1 = -1, None, None
    Nk = [[_h_coeffs(N[i][j], R.zero) for j in range(3)] for i in range(3)]
    finite = all(not Nk[i][j] or min(Nk[i][j]) >= v for i in range(3) for j in range(3))
    if finite:
        F = lambda p: K.field_new(p)  # noqa: E731
        q = [F(Dk.get(v + k, R.zero)) for k in range(n + 1)]
        C = [[[None] * (n + 1) for _ in range(3)] for _ in range(3)]
        for i in range(3):
            for j in range(3):
                for k in range(n + 1):
                    pk = F(Nk[i][j].get(v + k, R.zero))
                    C[i][j][k] = (pk - sum((q[l] * C[i][j][k - l] for l in range(1, k + 1)),
                                           K.zero)) / q[0]
        Mk = [sp.Matrix(3, 3, lambda i, j: C[i][j][k].as_expr()) for k in range(n + 1)]
        M0, M1 = Mk[0], (Mk[1] if n >= 1 else None)
        Ak = sp.eye(3)
        for k in range(n + 1):  # exp(hA) = Σ A^k h^k / k!
            target = Ak / sp.factorial(k)
            if any(C[i][j][k] != K.from_expr(target[i, j]) for i in range(3) for j in range(3)):
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
        M=_LazyM(to_mat(P), to_mat(Q)),
        M0=M0,
        M1=M1,
        X=None,
        pole_at_0=not finite,
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
        t1, t2 = cf.twist_potentials(phi, Phi)
        if sp.simplify(t1) == 0 or sp.simplify(t2) == 0:
            raise _twist_error(case)
        raise ValueError(
            f"the determining equations of {case} could not be solved as power series in h "
            "(no root of the h⁰ equation, or a vanishing linearisation)"
        )
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

"""The potentials of a divergence-free field (MATH.md §3): the closed-form and quadrature formulas,
the gauge that turns any vector potential into the SE or DL pair, and the checks that a pair may
step on a domain (issue #23).

SE:  a = vf1(F¹) + vf3(F³)  ⇔  A = (F¹, 0, F³) is a vector potential of a (∇×A = a);
DL:  a = vf1(G¹) + vf2(G²)  ⇔  A = (G¹, G², 0).
So a pair is a vector potential in the gauge A₂ = 0 (SE) or A₃ = 0 (DL), and any vector potential A
gives both by one gauge integral, A − ∇χ with χ = ∫ A_k dx_k (k = 2 for SE, 3 for DL).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import jax.numpy as jnp
import numpy as np
import sympy as sp

from ._budget import (
    MAX_FACTOR_DEGREE,
    MAX_INTEGRATE_OPS,
    MAX_SIMPLIFY_OPS,
    bounded_expand,
    guarded,
    integration_obstacle,
)
from ._errors import BudgetError
from ._fieldops import (
    _SPLITTINGS,
    SYMBOLS,
    PotentialError,
    _float_scale,
    _fmt_pt,
    _lambdify_numpy,
    _symbolic_zero,
    jax_unsupported,
    padded_blocks,
    sample_box,
    vf1_expr,
    vf2_expr,
    vf3_expr,
)
from ._quadrature import line_integral
from ._vecpot import GAUGE_ZERO, CallablePotential


def _potential_key(k: Any) -> str:
    """A key of the ``potentials`` argument: a splitting ("se", "dl") or "A" (a vector potential)."""
    return "A" if str(k).strip() in ("A", "vector") else _check_splitting(k)


def _check_splitting(splitting: str) -> str:
    s = str(splitting).lower().replace("+", "").replace("-", "")
    s = {"sese": "se", "se": "se", "dl": "dl", "dldl": "dl", "sedl": "dl"}.get(s, s)
    if s not in _SPLITTINGS:
        raise ValueError(f"splitting must be 'se' (F1, F3) or 'dl' (G1, G2); got {splitting!r}")
    return s


def _split_formula(key: str) -> str:
    if key == "A":
        return "∇×A"
    return "vf1(F1) + vf3(F3)" if key == "se" else "vf1(G1) + vf2(G2)"


def _check_potentials_arg(potentials: Any) -> dict[str, tuple]:
    if not isinstance(potentials, Mapping):
        raise ValueError('potentials must be a dict {"se": (F1, F3), "dl": (G1, G2), "A": (A1, A2, A3)}')  # noqa: TRY004
    out = {}
    for k, pair in potentials.items():
        key = _potential_key(k)
        n = 3 if key == "A" else 2
        if callable(pair) and key == "A":
            pair = _split_vector_callable(pair)
        if isinstance(pair, (str, sp.Basic)) or len(pair) != n:
            what = "a triple (A1, A2, A3)" if n == 3 else "a pair"
            raise ValueError(f"{k!r} potentials must be {what}; got {pair!r}")
        out[key] = tuple(pair)
    return out


def _split_vector_callable(A):
    """A(x) of shape (3,) → three scalar callables A_i(x1, x2, x3)."""
    def comp(i):
        return lambda x1, x2, x3: A(jnp.stack(jnp.broadcast_arrays(x1, x2, x3)).astype(float))[i]

    return tuple(comp(i) for i in range(3))


def _residual_exprs(exprs, symbols, key, pair):
    if key == "A":  # ∇×A − a
        A, (x1, x2, x3) = pair, symbols
        curl = (sp.diff(A[2], x2) - sp.diff(A[1], x3), sp.diff(A[0], x3) - sp.diff(A[2], x1),
                sp.diff(A[1], x1) - sp.diff(A[0], x2))
        return tuple(c - a for c, a in zip(curl, exprs))
    P, Q = pair
    u = vf1_expr(P, symbols)
    v = vf3_expr(Q, symbols) if key == "se" else vf2_expr(Q, symbols)
    return tuple(ui + vi - ai for ui, vi, ai in zip(u, v, exprs))


def potential_exprs(
    exprs: Sequence[Any],
    symbols: Sequence[sp.Symbol] = SYMBOLS,
    splitting: str = "se",
    origin: Sequence[Any] = (0, 0, 0),
) -> tuple[Any, Any] | None:
    """The potentials of MATH.md §3 of a SymPy field, by ``sympy.integrate`` (the one
    implementation of these formulas; :class:`Field` and :mod:`vpforms.symbolic.recipes` use it).

    ``"se"`` → (F¹, F³), ``"dl"`` → (G¹, G²), integrated from the base point ``origin``; None if
    an integrand is over the budgets of :mod:`vpforms._budget` (:func:`integration_obstacle`), or
    SymPy leaves an unevaluated integral or a Piecewise (:func:`closed_form_attempt` says which).
    Not verified here: the formulas give the field only if it is divergence free.
    """
    return closed_form_attempt(exprs, symbols, splitting, origin)[0]


def closed_form_attempt(exprs, symbols=SYMBOLS, splitting: str = "se", origin=(0, 0, 0)):
    """(pair, None) as :func:`potential_exprs`, or (None, why not): the budget an integrand is over
    or how ``sympy.integrate`` failed — the reason recorded for a quadrature."""
    splitting = _check_splitting(splitting)
    a1, a2, a3 = (sp.sympify(e) for e in exprs)
    x1, x2, x3 = symbols
    c1, c2, c3 = (sp.nsimplify(c) for c in origin)
    s, t = sp.Dummy("s", real=True), sp.Dummy("t", real=True)

    if splitting == "se":  # F3 = ∫a1 dx2,  F1 = −∫a3 dx2 + ∫a2(x1, c2, t) dt
        plan = [(a1, x2, s, c2), (a3, x2, s, c2), (a2.xreplace({x2: c2}), x3, t, c3)]
    else:  # G1 = ∫a2 dx3,  G2 = −∫a1 dx3 + ∫a3(s, x2, c3) ds
        plan = [(a2, x3, t, c3), (a1, x3, t, c3), (a3.xreplace({x3: c3}), x1, s, c1)]
    try:  # every integrand within budget before any is integrated
        integrands = [_within_budget(expr, var, dummy) for expr, var, dummy, _ in plan]
        first, second, third = (_integrate(e, expr, var, dummy, lo)
                                for e, (expr, var, dummy, lo) in zip(integrands, plan))
    except _NoClosedForm as why:
        return None, str(why)
    P, Q = (-second + third, first) if splitting == "se" else (first, -second + third)
    pair = (bounded_expand(P), bounded_expand(Q))
    if any(p is None for p in pair):
        return None, "the closed form's expansion is over MAX_EXPAND_TERMS (vpforms._budget)"
    if any(p.has(sp.Piecewise) for p in pair):
        return None, "sympy.integrate gives a piecewise closed form"
    return pair, None


def _closed_form_potentials(field: Any, splitting: str) -> tuple[tuple | None, str | None]:
    """(SymPy closed forms of MATH.md §3, verified symbolically, None) or (None, why not) — the
    reason recorded for the quadrature that replaces them: a component of more than
    MAX_INTEGRATE_OPS operations, an integrand over the structural budgets of
    :func:`vpforms._budget.integration_obstacle`, integrate failing, a closed form that needs a
    function with no JAX implementation (e.g. hyper, Shi, RootSum) or complex numbers (e.g.
    fresnels(e^{iπ/4}x)·e^{−3iπ/4}, real but not evaluable in float64), or one not proven to give
    the field within budget.  Every decision is deterministic; the integration and verification
    run under the last guard (:func:`vpforms._budget.guarded`: BudgetError, never a fallback)."""
    for i, e in enumerate(field.exprs, start=1):
        n = sp.count_ops(e)
        if n > MAX_INTEGRATE_OPS:
            return None, f"component a{i} has {n} operations > MAX_INTEGRATE_OPS = {MAX_INTEGRATE_OPS} (vpforms._budget)"
    return guarded(f"the closed-form {splitting.upper()} potentials of field {field.name!r}",
                   _verified_closed_form, field, splitting)


def _verified_closed_form(field: Any, splitting: str) -> tuple[tuple | None, str | None]:
    pair, why = closed_form_attempt(field.exprs, field.symbols, splitting, field.origin)
    if pair is None:
        return None, why
    if any(p.has(sp.I) for p in pair):
        return None, "the closed form has complex numbers (not evaluable in float64)"
    missing = sorted({n for p in pair for n in jax_unsupported(p)}
                     | {type(a).__name__ for p in pair for a in p.atoms(sp.RootSum, sp.Lambda)})
    if missing:
        return None, f"the closed form needs {', '.join(missing)}, which has no JAX implementation"
    thr = 1e-12 * _float_scale(field.exprs)
    res = _residual_exprs(field.exprs, field.symbols, splitting, pair)
    if not all(_symbolic_zero(r, field.symbols, thr) for r in res):
        return None, "the closed form is not proven to give the field within the budgets of vpforms._budget"
    return pair, None


class _NoClosedForm(Exception):
    """Why a closed form is not attempted or not found (the message)."""


def _within_budget(expr, var, dummy):
    """The integrand expr(var → dummy), expanded, or _NoClosedForm naming the budget it is over."""
    e = bounded_expand(expr.xreplace({var: dummy}))
    if e is None:
        raise _NoClosedForm(f"∫ {_short(expr, 60)} d{var}: its expansion is over MAX_EXPAND_TERMS (vpforms._budget)")
    why = integration_obstacle(e, dummy)
    if why is not None:
        raise _NoClosedForm(f"∫ {_short(expr, 60)} d{var}: {why.replace(str(dummy), str(var))} "
                            "(budget of vpforms._budget)")
    return e


def _integrate(e, expr, var, dummy, lo):
    """∫_lo^var e d(dummy) by sympy.integrate, or _NoClosedForm saying how it failed."""
    try:
        r = sp.integrate(e, (dummy, lo, var))
    except Exception as err:  # noqa: BLE001 - SymPy may raise on hard integrands
        raise _NoClosedForm(f"∫ {_short(expr, 60)} d{var}: sympy.integrate raised {type(err).__name__}") from None
    if r.has(sp.Integral):
        raise _NoClosedForm(f"∫ {_short(expr, 60)} d{var}: sympy.integrate finds no antiderivative")
    return r


def _quadrature_potentials(comps, splitting: str, origin, n: int, integral=line_integral):
    """Differentiable Gauss–Legendre potentials (MATH.md §3 with base point ``origin``):

        SE:  F³ = ∫_{c₂}^{x₂} a₁(x₁,s,x₃) ds,  F¹ = −∫_{c₂}^{x₂} a₃(x₁,s,x₃) ds + ∫_{c₃}^{x₃} a₂(x₁,c₂,t) dt,
        DL:  G¹ = ∫_{c₃}^{x₃} a₂(x₁,x₂,t) dt,  G² = −∫_{c₃}^{x₃} a₁(x₁,x₂,t) dt + ∫_{c₁}^{x₁} a₃(s,x₂,c₃) ds,

    each integral the n-point rule ``integral(f, lower, upper, n)``: :func:`line_integral` (JAX, the
    default) or :func:`vpforms._quadrature.line_integral_expr` (the same rule as SymPy, for the native
    backend, with ``comps`` mapping SymPy arguments to SymPy expressions)."""
    a1, a2, a3 = comps
    c1, c2, c3 = origin

    if splitting == "se":

        def F3(x1, x2, x3):
            return integral(lambda s: a1(x1, s, x3), c2, x2, n)

        def F1(x1, x2, x3):
            return -integral(lambda s: a3(x1, s, x3), c2, x2, n) + integral(
                lambda t: a2(x1, c2, t), c3, x3, n
            )

        F1.__name__, F3.__name__ = "F1_quadrature", "F3_quadrature"
        return F1, F3

    def G1(x1, x2, x3):
        return integral(lambda t: a2(x1, x2, t), c3, x3, n)

    def G2(x1, x2, x3):
        return -integral(lambda t: a1(x1, x2, t), c3, x3, n) + integral(
            lambda s: a3(s, x2, c3), c1, x1, n
        )

    G1.__name__, G2.__name__ = "G1_quadrature", "G2_quadrature"
    return G1, G2


# ---------------------------------------------------------------------------------------------
# vector potentials and the gauge (issue #23: user potentials reach every case)
# ---------------------------------------------------------------------------------------------
#: the component of A that the gauge of a splitting sets to zero: SE ↔ A₂ = 0, DL ↔ A₃ = 0


def vector_potential(pair: Sequence[Any], splitting: str) -> tuple:
    """The vector potential A of a potential pair: SE (F¹, F³) → (F¹, 0, F³), DL (G¹, G²) →
    (G¹, G², 0) (∇×A = vf1(P) + vf3(Q) resp. vf1(P) + vf2(Q)). Entries are SymPy expressions or
    JAX scalar callables, as given; the zero is ``0`` (an int)."""
    P, Q = pair
    return (P, 0, Q) if _check_splitting(splitting) == "se" else (P, Q, 0)


def relabel_vector_potential(A: Sequence[Any], pi: Any, symbols: Sequence[sp.Symbol]) -> tuple:
    """Ã of the relabelled field ã(x) = a(x·π⁻¹)·π (prop:trivperm): Ã(x) = sgn π · A(x·π⁻¹)·π.

    (x ↦ x·π⁻¹ is the linear map M with ã = M a∘M⁻¹; curl(M A∘M⁻¹) = det M · M (curl A)∘M⁻¹ for a
    permutation matrix, and det M = sgn π.) SymPy entries only."""
    idx, inv = list(pi.index), list(pi.inverse().index)
    sub = {symbols[j]: symbols[inv[j]] for j in range(3)}
    s = int(pi.sign)
    return tuple(s * sp.sympify(A[k]).xreplace(sub) for k in idx)


def gauge_exprs(A: Sequence[Any], symbols: Sequence[sp.Symbol], splitting: str,
                origin: Sequence[Any] = (0, 0, 0)) -> tuple[Any, Any] | None:
    """The SE or DL pair of the vector potential A (SymPy): A − ∇χ with χ = ∫_{c_k}^{x_k} A_k dx_k
    (k = 2 for SE, 3 for DL), which has the same curl and A_k − ∂_kχ = 0. χ = 0 when A_k ≡ 0
    (the pair is read off A). None if SymPy leaves the integral unevaluated or piecewise."""
    splitting = _check_splitting(splitting)
    k = GAUGE_ZERO[splitting]
    A = [sp.sympify(a) for a in A]
    xk = symbols[k]
    if A[k] == 0:
        chi = sp.Integer(0)
    else:
        t = sp.Dummy("t", real=True)
        try:
            chi = guarded(f"the gauge integral ∫ {_short(A[k], 60)} d{xk}", sp.integrate,
                          A[k].xreplace({xk: t}), (t, sp.nsimplify(origin[k]), xk))
        except BudgetError:
            raise
        except Exception:  # noqa: BLE001 - SymPy may raise on hard integrands
            return None
        if chi.has(sp.Integral) or chi.has(sp.Piecewise):
            return None
    B = [A[i] - sp.diff(chi, symbols[i]) for i in range(3)]
    return (B[0], B[2]) if splitting == "se" else (B[0], B[1])


def gauge_callables(A: Sequence[Any], splitting: str, origin: Sequence[float], n: int):
    """:func:`gauge_exprs` for JAX scalar callables A_i(x1, x2, x3) (or 0): χ by the differentiable
    Gauss–Legendre rule, ∂_iχ by autodiff (:meth:`vpforms._vecpot.VectorPotential.gauge`)."""
    splitting = _check_splitting(splitting)
    return CallablePotential(A).gauge(splitting, origin, n)


# ---------------------------------------------------------------------------------------------
# checks: a pair may step on a domain only if it reproduces the field there (issue #23)
# ---------------------------------------------------------------------------------------------
#: relative reconstruction error max|∇×A − a| / max|a| above which a numerically built pair
#: (quadrature, gauge by quadrature) is refused on a domain
POTENTIAL_TOL = 1e-8
#: points of the box a pair is checked on (seeded, uniform), besides the caller's points
CHECK_POINTS = 512
#: the block of the check at given points (initial conditions): a second fixed compiled shape
POINT_BLOCK = 64
_NAMES = {"se": ("F1", "F3"), "dl": ("G1", "G2")}


def _singular_sets(expr: sp.Expr, symbols: Sequence[sp.Symbol]) -> list[tuple[sp.Expr, str]]:
    """(g, kind) with g = 0 where ``expr`` may be singular: denominators, logarithm arguments,
    radicands, and cos/sin under tan/sec, cot/csc; polynomial g split into irreducible factors.

    Remembered per (expression, symbols) (:func:`vpforms.integrate` checks the potentials at every
    run's initial conditions) unless a factorisation failed.  Factored only within the budgets
    MAX_SIMPLIFY_OPS and MAX_FACTOR_DEGREE (deterministic), under the last guard."""
    key = (expr, tuple(symbols))
    hit = _SINGULAR_SETS.get(key)
    if hit is not None:
        return list(hit)
    out, complete = _find_singular_sets(expr, symbols)
    if complete:
        if len(_SINGULAR_SETS) >= 256:
            _SINGULAR_SETS.clear()
        _SINGULAR_SETS[key] = tuple(out)
    return out


#: (expression, symbols) → its singular sets (:func:`_singular_sets`), keyed by SymPy's structural
#: equality (a Float's precision and a symbol's assumptions count)
_SINGULAR_SETS: dict[tuple, tuple] = {}


def _find_singular_sets(expr: sp.Expr, symbols: Sequence[sp.Symbol]) -> tuple[list[tuple[sp.Expr, str]], bool]:
    """:func:`_singular_sets` and whether every factorisation it tried finished."""
    syms = set(symbols)
    complete = True
    raw: list[tuple[sp.Expr, str]] = []
    for p in expr.atoms(sp.Pow):
        b, e = p.as_base_exp()
        if not (b.free_symbols & syms):
            continue
        if e.is_negative:
            raw.append((b, "denominator"))
        elif e.is_integer is not True:
            raw.append((b, "radicand"))
    raw += [(f.args[0], "logarithm argument") for f in expr.atoms(sp.log)]
    raw += [(sp.cos(f.args[0]), "denominator") for f in expr.atoms(sp.tan, sp.sec)]
    raw += [(sp.sin(f.args[0]), "denominator") for f in expr.atoms(sp.cot, sp.csc)]
    out: list[tuple[sp.Expr, str]] = []
    for g, kind in raw:
        facs = [(g, 1)]
        if _factorable(g, symbols):
            try:
                facs = guarded(f"factoring {_short(g, 60)}", sp.factor_list, g, *symbols)[1] or facs
            except BudgetError:
                raise
            except Exception:  # noqa: BLE001 - factoring is only a refinement
                complete = False
        for f, _ in facs:
            if f.free_symbols & syms and (f, kind) not in out:
                out.append((f, kind))
    return out, complete


def _factorable(g: sp.Expr, symbols: Sequence[sp.Symbol]) -> bool:
    """Is g a polynomial within the budgets of factoring (MAX_SIMPLIFY_OPS, MAX_FACTOR_DEGREE)?"""
    if not g.is_polynomial(*symbols) or sp.count_ops(g) > MAX_SIMPLIFY_OPS:
        return False
    return sp.Poly(g, *symbols).total_degree() <= MAX_FACTOR_DEGREE


def _numpy_fn(expr, symbols):
    """``expr`` as a NumPy function of points (N, 3); lambdified once per (expression, symbols)
    (:func:`vpforms.integrate` checks the potentials at every run's initial conditions)."""
    return _numpy_fn_cached(sp.sympify(expr), tuple(symbols))


@lru_cache(maxsize=256)
def _numpy_fn_cached(expr, symbols):
    # keyed by SymPy's structural equality (a Float's precision and a symbol's assumptions count)
    f = _lambdify_numpy(symbols, expr)

    def g(pts):
        with np.errstate(all="ignore"):
            v = f(*np.asarray(pts, float).T)
        return np.broadcast_to(np.asarray(v, dtype=complex if np.iscomplexobj(v) else float),
                               (len(pts),))

    return g


def _zero_between(fn, p, q, iters: int = 80):
    """A point of the segment [p, q] where the continuous fn changes sign (bisection)."""
    fp = fn(p[None])[0]
    for _ in range(iters):
        m = 0.5 * (p + q)
        fm = fn(m[None])[0]
        if np.sign(fm) == np.sign(fp):
            p, fp = m, fm
        else:
            q = m
    return 0.5 * (p + q), (q - p) / max(float(np.linalg.norm(q - p)), 1e-300)


def _blows_up(expr, symbols, z, d) -> bool:
    """Does |∇expr| grow without bound towards z along ±d (a true singularity, not a removable
    0/0 such as sin(x₁x₂)/x₁)?"""
    grads = [_numpy_fn(sp.diff(expr, s), symbols) for s in symbols]

    def size(eps):
        pts = np.stack([z + eps * d, z - eps * d])
        v = np.stack([g(pts) for g in grads], axis=1)
        return np.inf if not np.all(np.isfinite(v)) else float(np.max(np.abs(v)))

    far, near = size(1e-3), size(1e-8)
    return not np.isfinite(near) or near > 1e3 * (far + 1.0)


def singular_point(exprs: Sequence[sp.Expr], symbols: Sequence[sp.Symbol], pts) -> tuple | None:
    """(index, g, kind, x) for the first expression of ``exprs`` that is singular on the domain
    sampled by ``pts`` (N, 3): a non-finite or complex value at a point, or a set g = 0 of
    :func:`_singular_sets` that separates two points (g changes sign between them) and on which the
    expression truly blows up; None if no singularity is found."""
    pts = np.asarray(pts, float)
    for i, e in enumerate(exprs):
        e = sp.sympify(e)
        if not (e.free_symbols & set(symbols)):
            continue
        v = _numpy_fn(e, symbols)(pts)
        bad = ~np.isfinite(v) if not np.iscomplexobj(v) else ~np.isfinite(v) | (np.abs(v.imag) > 0)
        if np.any(bad):
            j = int(np.flatnonzero(bad)[0])
            return i, None, "non-finite or complex value", pts[j]
        for g, kind in _singular_sets(e, symbols):
            gv = _numpy_fn(g, symbols)(pts)
            if np.iscomplexobj(gv) or not np.all(np.isfinite(gv)):
                continue
            neg, pos = np.flatnonzero(gv < 0), np.flatnonzero(gv > 0)
            if kind == "radicand" and neg.size:
                return i, g, kind, pts[neg[0]]
            if not (neg.size and pos.size):
                continue
            # the closest pair of points on either side of g = 0, bisected onto it
            a, b = pts[neg[np.argmin(np.abs(gv[neg]))]], pts[pos[np.argmin(np.abs(gv[pos]))]]
            z, d = _zero_between(_numpy_fn(g, symbols), a, b)
            if kind != "denominator" or _blows_up(e, symbols, z, d):
                return i, g, kind, z
    return None


def check_pair(field: Any, splitting: str, points: Any = None, what: str = "") -> None:
    """Refuse (:class:`~vpforms.fields.PotentialError`) the ``splitting`` pair of ``field`` if it
    does not reproduce the field on the domain: the field's :attr:`~vpforms.Field.domain` where it
    has one (a region that follows the plasma), else its box (:data:`CHECK_POINTS` seeded points),
    and ``points`` (e.g. the initial conditions). Checked: symbolic potentials have no singular set
    inside the domain (:func:`singular_point`); numerically built ones (quadrature, gauge by
    quadrature) reconstruct the field to :data:`POTENTIAL_TOL` relative at every point. The
    message names ``what`` (the case), the potential and a point. The domain's check is cached:
    later calls with ``points`` reconstruct the field at those points only (relative to the larger
    of the domain's and their max |a|), in blocks of :data:`POINT_BLOCK`."""
    splitting = _check_splitting(splitting)
    cache = field.__dict__.setdefault("_checked_pairs", {})
    if splitting not in cache:
        dom_pts = domain_check_points(field, CHECK_POINTS, field.seed + 7)
        try:
            cache[splitting] = _pair_problem(field, splitting, dom_pts, CHECK_POINTS)
        except PotentialError as err:  # the pair cannot even be built
            cache[splitting] = (str(err), 0.0)
    reason, scale = cache[splitting]
    if reason is None and points is not None:
        pts = np.asarray(points, float).reshape(-1, 3)[:4096]
        # the singular-set test sees the domain's points too (a set between them and the points)
        context = domain_check_points(field, CHECK_POINTS, field.seed + 7)
        reason, _ = _pair_problem(field, splitting, pts, POINT_BLOCK, scale, context)
    if reason is not None:
        raise PotentialError(f"{what}: {reason}" if what else reason)


def domain_check_points(field: Any, n: int, seed: int) -> np.ndarray:
    """``n`` seeded points where the field is used, in its own coordinates: samples of its
    :attr:`~vpforms.Field.domain` (toroidal (u = R²/2, φ, Z) or Cartesian) where it has one, else
    uniform points of its box — or its own ``sampler`` (:meth:`vpforms.Field.sample_points`)."""
    if getattr(field, "sampler", None) is not None:
        return field.sample_points(n, seed)
    domain = getattr(field, "domain", None)
    if domain is None:
        return sample_box(field.box, n, seed)
    return domain.sample_points(n, seed, toroidal=str(field.coordinates).startswith("toroidal"))


def _short(e: Any, n: int = 160) -> str:
    s = str(e)
    return s if len(s) <= n else s[: n - 1] + "…"


def _pair_problem(field: Any, splitting: str, pts, block: int, scale: float = 0.0,
                  context: Any = None) -> tuple[str | None, float]:
    """(why the pair fails at ``pts``, or None; max |a| over ``pts`` and ``scale``); symbolic
    potentials are tested for singular sets on ``context`` and ``pts`` together."""
    _, exprs, how = field._get(splitting)
    names = _NAMES[splitting]
    label = f"the {splitting.upper()} potentials of field {field.name!r} ({how})"
    if exprs is not None:
        hit = singular_point(exprs, field.symbols, pts if context is None else np.concatenate([context, pts]))
        if hit is not None:
            i, g, kind, x = hit
            where = f"is not finite/real at x = {_fmt_pt(x)}" if g is None else (
                f"is singular where its {kind} {g} vanishes, inside the domain (e.g. x = {_fmt_pt(x)})")
            return f"{label}: {names[i]} = {_short(exprs[i])} {where}", scale
        if how in ("closed form", "user-supplied"):
            return None, scale  # verified symbolically: reproduces the field wherever it is defined
    # in padded blocks of a fixed size: one compiled shape for the domain's points and one for any
    # number of initial conditions, so that a run with a new number of particles compiles nothing
    a, r = padded_blocks(lambda q: (field(q), field.reconstruct(q, splitting)), pts, block)
    scale = max(float(np.max(np.abs(a[np.isfinite(a)]), initial=0.0)), scale, np.finfo(float).tiny)
    err = np.max(np.abs(r - a), axis=1) / scale
    err = np.where(np.isfinite(err), err, np.inf)
    j = int(np.argmax(err))
    if err[j] > POTENTIAL_TOL:
        return (f"{label} do not reproduce the field: |{_split_formula(splitting)} − a| / max|a| = "
                f"{err[j]:.3g} > {POTENTIAL_TOL:g} at x = {_fmt_pt(pts[j])}"), scale
    return None, scale

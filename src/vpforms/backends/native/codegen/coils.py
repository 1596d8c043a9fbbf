"""Filament coils in the native backend: a SymPy atom for the coils' A, its C, its run-time data.

The vector potential of filamentary coils (:class:`vpforms.coils.CoilPotential`) is the sum over
straight segments s of Hanson & Hirshman's A (:mod:`vpforms.coils._segments`),

    A(x) = Σ_s ê_s f_s(x),   f_s = (μ0 I_s/4π) log1p(2L_s/D_s),   D_s = R_i + R_f − L_s,

with D_s = (R_i − t) + (R_f − u) and each difference in its cancellation-free form (ρ²/(R + t)
where t > 0, R − t where t ≤ 0; t = ê·(x − x_i), u = ê·(x_f − x), ρ² = |ê × (x − x_i)|²). So:

* :class:`CoilA` ``(ref, k, orders, x₁, x₂, x₃)`` is ∂^orders A_k at the Cartesian point
  (x₁, x₂, x₃) of the coils ``ref`` (a :class:`.data.DataRef`); its derivative along an argument is
  the atom of one order more (``fdiff``). A potential in Cartesian coordinates has components
  A_k = CoilA(ref, k, 0, x); one in toroidal coordinates (u = R²/2, φ, Z) (:class:`vpforms.toroidal.
  ToroidalPotential` of the coils) the covariant (A_R/R, R A_φ, A_Z) at (R cos φ, R sin φ, Z),
  R = √(2u), exactly as JAX writes them, which SymPy differentiates by the chain rule.
* χ_k = ∫_c^{x_k} A_k is the n-point Gauss–Legendre rule of :func:`vpforms._vecpot.
  periodic_line_integral` (:func:`vpforms._quadrature.line_integral_expr`, loops over the same
  nodes in C); along a period T as w·∫_c^{c+T} + ∫_c^{c+r}, r = x_k − c − wT, with
  w = :class:`WholePeriods` ((x_k − c)/T) = ⌊·⌋ of derivative 0 (``jax.lax.stop_gradient``).

C (:func:`coil_calls`): the atoms of one statement group at one point are one loop over the
segments, in a helper generated from SymPy for the set of derivative orders α they need: the
symbolic derivatives ∂^α D_s of both branches of each difference (selected by t > 0, u > 0: the
derivatives of the branch JAX evaluates, what ``jax.jacfwd`` gives), ∂^α f_s from them by the chain
rule of f = (μ0 I/4π) log1p(2L/D), one cse; the loop accumulates ê_{s,k} ∂^α f_s for k = 1, 2, 3.

Data (:func:`_pack`): the header is [offset of the segment arrays, S]; then 11 arrays of S
doubles: x_i (3), x_f (3), ê (3), L, μ0 I/4π. The source does not depend on the coils: another
coil set, of any number of segments, reuses the compiled kernel.
"""

from __future__ import annotations

import os
from functools import lru_cache
from itertools import product
from typing import Any

import numpy as np
import sympy as sp
from sympy.codegen.cfunctions import log1p
from sympy.core.function import ArgumentIndexError

from ...._quadrature import GL_T, line_integral_expr
from ....coils import CoilPotential, CoilSet
from ....toroidal import ToroidalPotential
from .cprinter import printer as _printer
from .data import HS, PACKERS, DataRef, code3, e_sub, emission, nested, uncode3

__all__ = ["CoilA", "WholePeriods", "coil_calls", "coil_exprs", "hoist"]

#: μ0/4π (SI), as :mod:`vpforms.coils._segments`
_MU0_4PI = 1e-7


class CoilA(sp.Function):
    """∂^orders A_k(x₁, x₂, x₃) of the coils ``ref``: args (ref, k, orders, x₁, x₂, x₃), orders as
    a :func:`.data.code3`."""

    nargs = 6
    _vp_native = True  # printed by coil_calls, not by the C printer
    _vp_at_point = True  # data evaluated at the point args[3:] (data.data_atoms)

    def fdiff(self, argindex: int = 1):
        if argindex < 4:
            raise ArgumentIndexError(self, argindex)
        ref, k, orders, *x = self.args
        o = uncode3(orders)
        o[argindex - 4] += 1
        return CoilA(ref, k, code3(o), *x)

    @property
    def k(self) -> int:
        return int(self.args[1])

    @property
    def orders(self) -> tuple[int, int, int]:
        return tuple(uncode3(self.args[2]))


class WholePeriods(sp.Function):
    """⌊s⌋ of derivative 0: the number of whole periods of a periodic line integral
    (``jax.lax.stop_gradient(jnp.floor(·))`` in :func:`vpforms._vecpot.periodic_line_integral`)."""

    nargs = 1
    _vp_native = True

    def fdiff(self, argindex: int = 1):
        return sp.Integer(0)

    def _ccode(self, printer):
        return f"floor({printer._print(self.args[0])})"


# ----------------------------------------------------------------------------- SymPy of potentials
def _coils_of(A: Any) -> tuple[CoilPotential, ToroidalPotential | None] | None:
    """(the coils' Cartesian potential, the toroidal wrapper or None) of A, or None."""
    if isinstance(A, CoilPotential):
        return A, None
    if isinstance(A, ToroidalPotential) and isinstance(A.A_cartesian, CoilPotential):
        return A.A_cartesian, A
    return None


def _ref(owner: Any, key: Any, name: str, obj: Any) -> DataRef:
    """The data ref ``key`` of a potential object: one per object, so that every expression of a
    kernel reads the same slot."""
    refs = owner.__dict__.setdefault("_native_refs", {})
    if key not in refs:
        refs[key] = DataRef(name, obj)
    return refs[key]


def coil_exprs(A: Any, x: tuple) -> tuple | None:
    """(components, antiderivative(k, c, n)) of a coil potential as atoms at x (module docstring),
    or None if A is not one."""
    got = _coils_of(A)
    if got is None:
        return None
    cart, tor = got
    ref = _ref(cart, "coils", "coils", cart.coils)
    if tor is None:
        comps = tuple(CoilA(ref, k, code3((0, 0, 0)), *x) for k in range(3))
        owner, periods = cart, (None, None, None)
    else:  # covariant components, as ToroidalPotential._covariant
        u, phi, Z = x
        R = sp.sqrt(2 * u)
        c, s = sp.cos(phi), sp.sin(phi)
        Ax, Ay, Az = (CoilA(ref, k, code3((0, 0, 0)), R * c, R * s, Z) for k in range(3))
        comps = ((Ax * c + Ay * s) / R, R * (-Ax * s + Ay * c), Az)
        owner, periods = tor, tor.periods

    def anti(k, c, n):
        lower = _ref(owner, ("c", k, float(c)), f"c{k}", float(c))

        def f(v):  # A_k with x_k → v
            return comps[k].xreplace({x[k]: v})

        if periods[k] is None:
            return line_integral_expr(f, lower, x[k], n)
        T = _ref(owner, ("T", k), f"T{k}", float(periods[k]))
        w = WholePeriods((x[k] - lower) / T)
        return w * line_integral_expr(f, lower, lower + T, n) + line_integral_expr(f, lower, x[k] - w * T, n)

    return comps, anti


# ----------------------------------------------------------------------------- C
#: the C names of the point and of one segment's data inside the loop (:func:`_segment_helper`)
_P = sp.symbols("vc_p1 vc_p2 vc_p3", real=True)
_SEG = ("xi0", "xi1", "xi2", "xf0", "xf1", "xf2", "e0", "e1", "e2", "L", "w")


def _derivative(e: sp.Expr, alpha: tuple[int, int, int]) -> sp.Expr:
    for j, m in enumerate(alpha):
        if m:
            e = sp.diff(e, _P[j], m)
    return e


def _below(alphas) -> list[tuple[int, int, int]]:
    """Every multi-index ≤ one of ``alphas`` (what the chain rule of f(D) needs of D)."""
    out = {b for a in alphas for b in product(*(range(m + 1) for m in a))}
    return sorted(out, key=lambda b: (sum(b), b))


_NAME = "VP_COILS_HELPER"


def _segment_geometry() -> tuple[dict, tuple, tuple, Any, Any]:
    """One segment's symbols at the point p: (data symbols by name (:data:`_SEG`), ê × (x − x_i),
    the two cancellation-free differences as (ρ²/(R + s), R − s, s) with s = t, u, R_i, R_f)."""
    S = {n: sp.Symbol(f"vc_{n}", real=True) for n in _SEG}
    xi, xf, e = ([S[f"{p}{j}"] for j in range(3)] for p in ("xi", "xf", "e"))
    d = [_P[j] - xi[j] for j in range(3)]  # x − x_i
    g = [_P[j] - xf[j] for j in range(3)]  # x − x_f
    Ri = sp.sqrt(sum(v * v for v in d))
    Rf = sp.sqrt(sum(v * v for v in g))
    t = sum(d[j] * e[j] for j in range(3))  # ê·(x − x_i)
    u = -sum(g[j] * e[j] for j in range(3))  # ê·(x_f − x)
    cr = (e[1] * d[2] - e[2] * d[1], e[2] * d[0] - e[0] * d[2], e[0] * d[1] - e[1] * d[0])
    rho2 = sum(v * v for v in cr)  # |ê × (x − x_i)|²
    tv, uv = sp.Symbol("vc_t", real=True), sp.Symbol("vc_u", real=True)
    # R_i − t, R_f − u without cancellation (ρ²/(R + t) where t > 0), differentiated branch by branch
    branches = ((rho2 / (Ri + t), Ri - t, tv), (rho2 / (Rf + u), Rf - u, uv))
    return S, cr, branches, (Ri, Rf), (t, u)


def _loop(comment: str, name: str, accumulators: list[str], body: list[str], store: str,
          fields: tuple[str, ...] = _SEG) -> str:
    """A C helper ``name``(fd, h, p₁, p₂, p₃, out) looping ``body`` over the S columns of the
    arrays ``fields`` (read as ``vc_<field>``; h = [offset of the arrays, S])."""
    loop = "\n        ".join([f"double vc_{nm} = q[{j} * S + s];" for j, nm in enumerate(fields)] + body)
    return f"""/* {comment} */
static void {name}(const double *fd, const double *h, double vc_p1, double vc_p2, double vc_p3,
                   double *restrict out) {{
    const double *q = fd + (int64_t)h[0];
    int64_t S = (int64_t)h[1];
    double {", ".join(f"{a} = 0.0" for a in accumulators)};
    for (int64_t s = 0; s < S; s++) {{
        {loop}
    }}
    {store}
}}
"""


@lru_cache(maxsize=64)
def _segment_helper(alphas: tuple[tuple[int, int, int], ...]) -> str:
    """The C helper (named ``_NAME``)(fd, h, p₁, p₂, p₃, out): out[k·|α| + j] = Σ_s ê_{s,k} ∂^{α_j} f_s
    at p (module docstring), generated from SymPy."""
    S, _, branches, _, (t, u) = _segment_geometry()
    need = _below(alphas)
    Dsym = {b: sp.Symbol(f"vc_D{b[0]}{b[1]}{b[2]}", real=True) for b in need}
    D_defs = [sum((sp.Piecewise((_derivative(p, b), s > 0), (_derivative(q, b), True))
                   for p, q, s in branches), sp.Integer(0)) for b in need]
    # f = (μ0 I/4π) log1p(2L/D) as a function of D(x): ∂^α f by the chain rule, in the ∂^β D
    Dfun = sp.Function("vc_Dfun")(*_P)
    f = S["w"] * log1p(2 * S["L"] / Dfun)
    fa = []
    for a in alphas:
        fx = _derivative(f, a)
        rep = {dv: Dsym[tuple(dv.variables.count(p) for p in _P)] for dv in fx.atoms(sp.Derivative)}
        fa.append(fx.xreplace(rep).xreplace({Dfun: Dsym[(0, 0, 0)]}))
    reps, red = sp.cse(D_defs, symbols=sp.numbered_symbols("vc_a"))
    reps2, red2 = sp.cse(fa, symbols=sp.numbered_symbols("vc_b"))
    n = len(alphas)
    body = [f"double vc_t = {_printer.doprint(t)}, vc_u = {_printer.doprint(u)};"]
    body += [f"double {v} = {_printer.doprint(ex)};" for v, ex in reps]
    body += [f"double {Dsym[b]} = {_printer.doprint(ex)};" for b, ex in zip(need, red)]
    body += [f"double {v} = {_printer.doprint(ex)};" for v, ex in reps2]
    body += [f"double vc_f{j} = {_printer.doprint(ex)};" for j, ex in enumerate(red2)]
    body += [f"o{k}_{j} += vc_e{k} * vc_f{j};" for k in range(3) for j in range(n)]
    store = " ".join(f"out[{k * n + j}] = o{k}_{j};" for k in range(3) for j in range(n))
    orders = ", ".join("".join(map(str, a)) for a in alphas)
    return _loop(f"Σ_s ê_s,k ∂^α f_s at p for α in ({orders}), k = 1, 2, 3: Hanson–Hirshman segments", _NAME,
                 [f"o{k}_{j}" for k in range(3) for j in range(n)], body, store)


@lru_cache(maxsize=1)
def _segment_B_helper() -> str:
    """The C helper (named ``_NAME``)(fd, h, p₁, p₂, p₃, out): out = B(p) = Σ_s g_s ê_s × (x − x_i),
    g_s = (μ0 I/4π) 2L(R_i+R_f)/(R_i R_f (R_i+R_f+L) D_s) — Hanson & Hirshman's closed form (as
    :func:`vpforms.coils._segments._kernel`), with the same cancellation-free D_s as the A loop; the
    curl of that loop's A to rounding (tested), at a fraction of the cost of its derivatives."""
    S, cr, branches, (Ri, Rf), (t, u) = _segment_geometry()
    D = sum((sp.Piecewise((p, s > 0), (q, True)) for p, q, s in branches), sp.Integer(0))
    g = S["w"] * 2 * S["L"] * (Ri + Rf) / (Ri * Rf * (Ri + Rf + S["L"]) * D)
    reps, red = sp.cse([g, *cr], symbols=sp.numbered_symbols("vc_a"))
    body = [f"double vc_t = {_printer.doprint(t)}, vc_u = {_printer.doprint(u)};"]
    body += [f"double {v} = {_printer.doprint(ex)};" for v, ex in reps]
    body += [f"o{k} += ({_printer.doprint(red[0])}) * ({_printer.doprint(red[1 + k])});" for k in range(3)]
    return _loop("B = Σ_s g_s ê_s × (x − x_i) at p: Hanson–Hirshman segments, closed form", _NAME,
                 ["o0", "o1", "o2"], body, "out[0] = o0; out[1] = o1; out[2] = o2;")


#: the arrays of a current element k (:class:`vpforms.coils.QuadratureCoils`): γ_k, w_k
_ELEMENT = ("g0", "g1", "g2", "w0", "w1", "w2")


@lru_cache(maxsize=2)
def _element_helper(what: str) -> str:
    """The C helper (named ``_NAME``)(fd, h, p₁, p₂, p₃, out): A = Σ_k w_k/r_k (``what="A"``) or
    B = Σ_k w_k × (x − γ_k)/r_k³ (``"B"``), r_k = |x − γ_k|, of current elements (γ_k, w_k) with the
    weights w_k already holding μ0/4π; generated from SymPy."""
    S = {n: sp.Symbol(f"vc_{n}", real=True) for n in _ELEMENT}
    d = [_P[j] - S[f"g{j}"] for j in range(3)]  # x − γ_k
    w = [S[f"w{j}"] for j in range(3)]
    # 1/r as a variable of its own (a square root and a division, which vectorise; SymPy would
    # print r⁻³ as pow(·, −3/2), a scalar call 13× slower)
    inv = sp.Symbol("vc_inv", positive=True)
    if what == "A":
        terms = [w[k] * inv for k in range(3)]
    else:
        cross = (w[1] * d[2] - w[2] * d[1], w[2] * d[0] - w[0] * d[2], w[0] * d[1] - w[1] * d[0])
        inv3 = sp.Symbol("vc_inv3", positive=True)
        terms = [c * inv3 for c in cross]
    reps, red = sp.cse(terms, symbols=sp.numbered_symbols("vc_a"))
    body = [f"double vc_inv = 1.0 / sqrt({_printer.doprint(sum(v * v for v in d))});"]
    body += [] if what == "A" else ["double vc_inv3 = vc_inv * vc_inv * vc_inv;"]
    body += [f"double {v} = {_printer.doprint(ex)};" for v, ex in reps]
    body += [f"o{k} += {_printer.doprint(red[k])};" for k in range(3)]
    return _loop(f"{what} of current elements at p", _NAME, ["o0", "o1", "o2"], body,
                 "out[0] = o0; out[1] = o1; out[2] = o2;", fields=_ELEMENT)


def _libmvec_log1p() -> bool:
    """Whether the C library is glibc ≥ 2.35, whose libmvec has vector log1p."""
    try:
        name, version = os.confstr("CS_GNU_LIBC_VERSION").split()
        major, minor = (int(v) for v in version.split(".")[:2])
    except (AttributeError, OSError, ValueError, TypeError):
        return False
    return name == "glibc" and (major, minor) >= (2, 35)


#: declared as libmvec's vector log1p (glibc ≥ 2.35) the segment loop of a value vectorises
#: (as emit's sin/cos/exp/log); elsewhere the scalar log1p
_LOG1P_DECL = ('__attribute__((__simd__("notinbranch"))) double log1p(double);\n'
               if _libmvec_log1p() else "")


def _helper(em: Any, alphas: tuple) -> str:
    """The name of the kernel's segment loop for the orders ``alphas`` (made on first use)."""
    key = ("coils", alphas)
    if _LOG1P_DECL and ("coils", "log1p") not in em.helpers:
        em.helpers[("coils", "log1p")] = ("", _LOG1P_DECL)
    if key not in em.helpers:
        name = f"vp_coils{sum(k[0] == 'coils' for k in em.helpers)}"
        em.helpers[key] = (name, _segment_helper(alphas).replace(_NAME, name))
    return em.helpers[key][0]


def coil_calls(exprs: list[Any], tag: str, printer: Any) -> tuple[list[str], list[Any]]:
    """The :class:`CoilA` atoms of ``exprs`` as C: per point one call of the segment loop for
    every derivative order the atoms there need (an atom already evaluated in a visible scope is
    read); each value is remembered in the current scope. Returns the statements and ``exprs``
    with the atoms replaced by their variables (data scalars are left to the caller)."""
    exprs = [sp.sympify(e) for e in exprs]
    atoms = sorted({a for e in exprs for a in e.atoms(CoilA)}, key=sp.default_sort_key)
    if not atoms:
        return [], exprs
    em = emission()
    rep: dict = {}
    groups: dict = {}
    for a in atoms:
        known = em.find(("atom", a))
        if known is not None:
            rep[a] = known
        else:
            groups.setdefault((a.args[0], a.args[3:]), []).append(a)
    lines = []
    for (ref, args), members in groups.items():
        alphas = tuple(sorted({m.orders for m in members}, key=lambda b: (sum(b), b)))
        em.count += 1
        v = f"{tag}_c{em.count}"
        pts = ", ".join(printer.doprint(e_sub(x)) for x in args)
        lines.append(f"double {v}[{3 * len(alphas)}]; {_helper(em, alphas)}(fd, fd + {HS * em.slot(ref)}, "
                     f"{pts}, {v});")
        for m in members:
            rep[m] = em.scopes[-1][("atom", m)] = sp.Symbol(f"{v}[{m.k * len(alphas) + alphas.index(m.orders)}]")
    return lines, [e.xreplace(rep) for e in exprs]


def hoist(exprs: list[Any], z: Any, printer: Any) -> list[str]:
    """Before a Newton loop in z, in the current scope: the coil atoms of ``exprs`` free of z (not
    those inside a quadrature's integrand), which the loop's body then reads."""
    if emission(required=False) is None:
        return []
    atoms = {a for e in exprs for a in sp.sympify(e).atoms(CoilA)}
    whole = sorted((a for a in atoms if z not in a.free_symbols and GL_T not in a.free_symbols
                    and not nested(a)), key=sp.default_sort_key)
    return coil_calls(whole, "hc", printer)[0] if whole else []


def _pack(coils: CoilSet, head: np.ndarray, put) -> None:
    """The header [offset, S] and the 11 segment arrays (module docstring): ê and L as
    :func:`vpforms.coils._segments._evaluate` computes them."""
    xi, xf, cur = (np.asarray(a, dtype=np.float64) for a in coils.segments())
    seg = (xf - xi).T
    L = np.sqrt(seg[0] * seg[0] + seg[1] * seg[1] + seg[2] * seg[2])
    e = seg / L
    head[0] = put(np.concatenate([xi.T.ravel(), xf.T.ravel(), e.ravel(), L, _MU0_4PI * cur]))
    head[1] = xi.shape[0]


PACKERS[CoilSet] = _pack

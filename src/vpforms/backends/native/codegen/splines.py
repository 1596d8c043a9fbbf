"""Spline fields in the native backend: SymPy atoms for spline evaluations, their C, their data.

A field given by a spline vector potential (:class:`vpforms.grids.SplinePotential`, relabelled
or summed, :mod:`vpforms._vecpot`) has potentials that are spline evaluations, not formulas. They
enter the generated code as SymPy atoms (:mod:`.vecpot`), so the stage plan, the symbolic
differentiation of the generating map and the Newton emission are those of every other field:

* :class:`SplineAt` ``(ref, orders, degrees, x₁, x₂, x₃)`` is ∂^orders s(x₁, x₂, x₃) of the
  tensor spline ``ref`` (a :class:`.data.DataRef`); its derivative along an argument is the atom
  of one order more (``fdiff``), 0 past the degree — the exact derivative of the cell polynomial
  that ``jax.grad`` takes of :func:`vpforms.grids._bspline.evaluate`;
* a :class:`.data.DataRef` scalar (the base point c of an antiderivative, a grid bound) is a
  number the kernel reads at run time.

So the C source depends only on the spline's structure (degrees, periodic axes, which derivatives
and antiderivatives); the knots, cell polynomials, coefficients and scalars travel in the
``const double *fd`` array of :mod:`.data`, and a new grid of the same structure reuses the
compiled kernel. A spline's header (:func:`_pack`): offsets of its three knot vectors, three
cell-polynomial tables and coefficients; m₁, m₂, m₃; the three periods, 0 for none; per axis
(m − k)/(t_m − t_k), the interval guess.

Evaluation in C (:data:`C_HELPERS`) is that of :mod:`vpforms.grids._bspline`: on a periodic axis
x is wrapped into [t_k, t_k + T) (``jnp.mod``: fmod, + T where negative); on a non-periodic axis
x outside [t_k, t_m] is NaN (value and every derivative), the knot interval is
clip(#{t ≤ x} − 1, k, m − 1) (a binary search), the basis is the cell's power-basis polynomials
differentiated exactly (Horner), and the coefficient block is contracted axis 0, then 1, then 2.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from typing import Any

import numpy as np
import sympy as sp
from sympy.core.function import ArgumentIndexError

from ....grids._bspline import PeriodicAntiderivative, TensorSpline
from ....grids._spline_potential import (
    SplinePotential,
    affine_antiderivative,
    affine_value,
)
from ...._quadrature import GL_T
from .data import HS, PACKERS, DataRef, code3, e_sub, emission, nested, uncode3

__all__ = ["C_HELPERS", "SplineAt", "domain_reason", "domain_test", "hoist", "spline_calls",
           "spline_exprs"]

#: lines one ``vp_lines`` call contracts at most (``VP_LINES`` in :data:`C_HELPERS`)
_VP_LINES = 8


class SplineAt(sp.Function):
    """∂^orders s(x₁, x₂, x₃) of the tensor spline ``ref``: args (ref, orders, degrees, x₁, x₂,
    x₃), orders and degrees as :func:`.data.code3` s."""

    nargs = 6
    _vp_native = True  # printed by spline_calls, not by the C printer
    _vp_at_point = True  # data evaluated at the point args[3:] (data.data_atoms)

    def fdiff(self, argindex: int = 1):
        if argindex < 4:
            raise ArgumentIndexError(self, argindex)
        a = argindex - 4
        ref, orders, degrees, *x = self.args
        o = uncode3(orders)
        o[a] += 1
        if o[a] > uncode3(degrees)[a]:  # the cell polynomials have degree k along axis a
            return sp.Integer(0)
        return SplineAt(ref, code3(o), degrees, *x)

    @property
    def orders(self) -> list[int]:
        return uncode3(self.args[1])

    @property
    def degrees(self) -> list[int]:
        return uncode3(self.args[2])


_SPLINE_REFS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _spline_atom(s: TensorSpline, name: str, x: Sequence[Any]) -> sp.Expr:
    ref = _SPLINE_REFS.get(s)
    if ref is None:
        ref = _SPLINE_REFS[s] = DataRef(name, s)
    if max(s.degrees) > 9:
        raise ValueError(f"native splines have degrees ≤ 9; got {s.degrees}")
    return SplineAt(ref, code3((0, 0, 0)), code3(s.degrees), *x)



def spline_exprs(A: SplinePotential, x: Sequence[Any]) -> tuple:
    """(components, antiderivative(k, c, n)) of a spline potential as atoms at x: the
    antiderivative is exact (a spline; far round a periodic axis μ·(x_k − c) + Q), n unused."""
    comps = tuple(_spline_atom(s, f"A{i}", x) if a is None else sp.sympify(affine_value(_exact(a), x))
                  for i, (s, a) in enumerate(zip(A.splines, A.affine)))
    scal: dict = {}

    def anti(k, c, n):
        if A.affine[k] is not None:  # the affine component's own antiderivative, c read at run time
            key = (k, float(c))
            if key not in scal:
                scal[key] = DataRef(f"c{k}", float(c))
            return sp.sympify(affine_antiderivative(_exact(A.affine[k]), k, x, scal[key]))
        obj = A.antiderivative(k, c)
        if isinstance(obj, TensorSpline):
            return _spline_atom(obj, f"X{k}", x)
        if isinstance(obj, PeriodicAntiderivative):  # μ·(x_k − c) + Q (exact far round)
            key = (k, float(obj.c))
            if key not in scal:
                scal[key] = DataRef(f"c{k}", float(obj.c))
            return ((x[obj.axis] - scal[key]) * _spline_atom(obj.M, f"M{k}", x)
                    + _spline_atom(obj.Q, f"Q{k}", x))
        return None

    return comps, anti


def _exact(a: Sequence[float]) -> tuple:
    """Affine coefficients as SymPy numbers, integers exact (so that a zero component is 0)."""
    return tuple(sp.Integer(int(t)) if float(t).is_integer() else sp.Float(float(t)) for t in a)


def domain_reason(field: Any) -> str | None:
    """None unless ``field`` has a domain test (``field.inside``: a step that fails off it is
    ``left_domain``) that is not a spline grid's box, which native cannot emit."""
    inside = getattr(field, "inside", None)
    if inside is not None and not isinstance(getattr(inside, "__self__", None), SplinePotential):
        return "the field's domain test (field.inside) is not a spline grid's; native emits those only"
    return None


def domain_test(field: Any) -> list[tuple[int, DataRef, DataRef]]:
    """[(axis, lo, hi)] of the grid box of ``field.inside`` (non-periodic axes), as data refs."""
    inside = getattr(field, "inside", None)
    pot = getattr(inside, "__self__", None)
    if not isinstance(pot, SplinePotential):
        return []
    cache = pot.__dict__.setdefault("_native_box", {})
    out = []
    for a, (lo, hi) in enumerate(pot.grid_box):
        if pot.periods[a] is None:
            if a not in cache:
                cache[a] = (DataRef(f"lo{a}", float(lo)), DataRef(f"hi{a}", float(hi)))
            out.append((a, *cache[a]))
    return out


# ----------------------------------------------------------------------------- emission and data
def _knot_class(em: Any, ref: DataRef, a: int) -> int:
    """The knot class of axis a of ``ref``: axes of splines with equal knots, degree and period
    share one interval search and basis."""
    s = ref.obj
    t, k, T = np.asarray(s.knots[a]), s.degrees[a], s.periods[a]
    for j, (a2, t2, k2, T2) in enumerate(em.classes):
        if (a2, k2, T2) == (a, k, T) and t2.shape == t.shape and np.array_equal(t2, t):
            return j
    em.classes.append((a, t, k, T))
    return len(em.classes) - 1


def _axis(em: Any, ref: DataRef, a: int, k: int, arg: Any, n: int, printer: Any,
          lines: list[str]) -> tuple[str, str]:
    """(the knot-interval variable, the basis array of order n) of axis a of ``ref`` at ``arg``,
    emitted into ``lines`` unless a visible scope has them."""
    cls = _knot_class(em, ref, a)
    c = printer.doprint(e_sub(arg))
    cell = em.find((cls, c))
    if cell is None:
        em.count += 1
        q = f"vs{em.count}"
        lines.append(f"double {q}_y; int64_t {q}_i = vp_cell(fd, fd + {HS * em.slot(ref)}, {a}, "
                     f"{k}, {c}, &{q}_y);")
        cell = em.scopes[-1][(cls, c)] = (q, HS * em.slot(ref))
    q, h = cell
    N = em.find((cls, c, n))
    if N is None:
        N = f"{q}_N{n}"
        lines.append(f"double {N}[{k + 1}]; vp_basis(fd, fd + {h}, {a}, {k}, {q}_i, {n}, {q}_y, {N});")
        em.scopes[-1][(cls, c, n)] = N
    return f"{q}_i", N


def hoist(exprs: list[Any], z: Any, printer: Any, later: tuple | None = None) -> list[str]:
    """Before a Newton loop in z, in the current scope (the loop's body then reuses them): the
    spline atoms of ``exprs`` free of z, whole; for an atom whose argument moves with z on one
    axis only, the interval and basis of its two other axes and a cache of the block contracted
    over them (the coefficients along the moving axis in its current cell: an iteration that
    stays in the cell costs one interval search, one basis and k + 1 products).

    ``later`` = (expressions evaluated after the loop, the solve's result u, symbols not known
    yet): their atoms moving with u on one axis, the others known, get caches too, in the group
    of the loop's atoms of the same spline, axis and other arguments: every member of a group is
    contracted when its cell is entered, so that the atoms at the root (the next solve's
    constants, the explicit component) are a Horner each in the cell the loop last entered."""
    em = emission(required=False)
    if em is None:
        return []
    lines: list[str] = []
    # not the atoms of a quadrature's integrand (bound to its node) nor those at a point that holds
    # atoms (evaluated in the loop's body, inner ones first)

    def plain(es):
        return sorted({a for e in es for a in sp.sympify(e).atoms(SplineAt)
                       if GL_T not in a.free_symbols and not nested(a)}, key=sp.default_sort_key)

    atoms = plain(exprs)
    whole = [a for a in atoms if z not in a.free_symbols]
    if whole:
        more, vals = spline_calls(whole, "hz", printer)
        lines += more
        for a, v in zip(whole, vals):
            em.scopes[-1][("atom", a)] = v
    members = [(at, _moving(at, {z})) for at in atoms if z in at.free_symbols]
    if later is not None:
        exprs_later, u, unknown = later
        members += [(at, _moving(at, {u}, {z, *unknown})) for at in plain(exprs_later) if u in at.free_symbols]
    # a group: the moving axis's knot class (one cell test serves the splines of equal knots there)
    # and argument, the other axes' arguments → its members' atoms
    groups: dict = {}
    for at, f in members:
        if f is not None:
            rest = tuple(printer.doprint(e_sub(at.args[3 + ax])) for ax in range(3) if ax != f)
            groups.setdefault((_knot_class(em, at.args[0], f), f, rest), []).append(at)
    for (_, f, _), ats in groups.items():
        own: dict = {}  # line key → the first atom with it (the member's orders on the fixed axes)
        for at in ats:
            key = _line_key(at, f, printer)
            if key not in own and em.find(key) is None:
                own[key] = at
                for ax in range(3):
                    if ax != f:
                        _axis(em, at.args[0], ax, at.degrees[ax], at.args[3 + ax], at.orders[ax], printer, lines)
        if not own:
            continue
        em.count += 1
        q, kf, group = f"ln{em.count}", ats[0].degrees[f] + 1, list(own.values())
        lines.append(" ".join(f"double {q}_P{j}[{kf}];" for j in range(len(group))) + f" vp_seg_t {q}_s = VP_SEG0;")
        for j, key in enumerate(own):
            em.scopes[-1][key] = (q, j, group)
    return lines


def _moving(at: SplineAt, zs: set, unknown: set = frozenset()) -> int | None:
    """The one axis whose argument holds a symbol of ``zs``, the others free of ``zs`` and of
    ``unknown``; None if there is no such axis."""
    free = [at.args[3 + ax].free_symbols for ax in range(3)]
    moving = [ax for ax in range(3) if free[ax] & zs]
    if len(moving) != 1 or any(free[ax] & (zs | unknown) for ax in range(3) if ax != moving[0]):
        return None
    return moving[0]


def _line_key(at: SplineAt, f: int, printer: Any) -> tuple:
    """The cache of ``at``'s block contracted over every axis but f: the spline, f, the other
    axes' arguments and orders."""
    rest = tuple((ax, printer.doprint(e_sub(at.args[3 + ax])), at.orders[ax]) for ax in range(3) if ax != f)
    return ("line", at.args[0], f, rest)


def spline_calls(exprs: list[Any], tag: str, printer: Any) -> tuple[list[str], list[Any]]:
    """The :class:`SplineAt` atoms of ``exprs`` as C, and scalar :class:`DataRef` s as reads of
    ``fd``. Per axis one interval search and one basis per derivative order serve every spline
    of the same knots at the same argument (and are reused from an enclosing scope); the
    coefficient block of a spline is contracted over axis 0 once per order along it, then over
    axis 1 once per pair of orders (the sums :func:`vpforms.grids._bspline._contract` shares);
    an atom :func:`hoist` prepared is read, or contracted from its cached line.
    Data scalars are left to the caller (:func:`.data.read_scalars`). Returns the statements and ``exprs`` with the atoms replaced by their variables."""
    exprs = [sp.sympify(e) for e in exprs]
    atoms = sorted({a for e in exprs for a in e.atoms(SplineAt)}, key=sp.default_sort_key)
    if not atoms:
        return [], exprs
    em = emission()
    groups: dict = {}
    lines: list[str] = []
    rep: dict = {}
    segs: dict = {}  # line group → (the moving axis's argument, y there): its last vp_seg here
    for a in atoms:
        if any(arg.atoms(SplineAt) for arg in a.args[3:]):
            raise ValueError("a spline evaluated at a spline is not generated natively")
        known = em.find(("atom", a))
        if known is not None:
            rep[a] = known
            continue
        lined = [f for f in range(3) if em.find(_line_key(a, f, printer)) is not None]
        if lined:  # contracted over the fixed axes once per cell of the moving one
            f = lined[0]
            q, j, group = em.find(_line_key(a, f, printer))
            k, o = a.degrees, a.orders
            arg = printer.doprint(e_sub(a.args[3 + f]))
            y = segs.get(q)
            if y is None or y[0] != arg:  # the cell of this argument: one test per group and point
                em.count += 1
                y = segs[q] = (arg, f"{tag}_y{em.count}")
                # on entering a cell: every member's line there, one pass over each spline's block
                # (at most VP_LINES lines a call), with its polynomial in y
                fill, per = [], {}
                for jj, m in enumerate(group):
                    ax = {b: _axis(em, m.args[0], b, m.degrees[b], m.args[3 + b], m.orders[b], printer, lines)
                          for b in range(3) if b != f}
                    cells = ", ".join(f"{q}_s.i" if b == f else ax[b][0] for b in range(3))
                    per.setdefault((m.args[0], cells), []).append(
                        f"{', '.join(ax[b][1] for b in sorted(ax))}, {q}_P{jj}")
                for (ref, cells), args in per.items():
                    hr = f"fd + {HS * em.slot(ref)}"
                    for j0 in range(0, len(args), _VP_LINES):
                        chunk = args[j0:j0 + _VP_LINES]
                        line = _specialised(em, "vp_lines", (*ref.obj.degrees, f, len(chunk)))
                        fill.append(f"{line}(fd, {hr}, {cells}, {', '.join(chunk)});")
                h = f"fd + {HS * em.slot(group[0].args[0])}"
                lines.append(f"double {y[1]}; if (vp_seg(fd, {h}, {f}, {k[f]}, {arg}, &{q}_s, "
                             f"&{y[1]})) {{ {' '.join(fill)} }}")
            em.count += 1
            v = sp.Symbol(f"{tag}_l{em.count}")
            lines.append(f"double {v} = vp_pn({k[f]}, {o[f]}, {q}_P{j}, {y[1]});")
            rep[a] = v
            continue
        groups.setdefault((a.args[0], a.args[3:]), []).append(a)
    for (ref, args), members in groups.items():
        k = members[0].degrees
        em.count += 1
        p = f"{tag}_s{em.count}"
        h = f"fd + {HS * em.slot(ref)}"
        ax = [{n: _axis(em, ref, a, k[a], args[a], n, printer, lines)
               for n in sorted({m.orders[a] for m in members})} for a in range(3)]
        idx = ", ".join(ax[a][next(iter(ax[a]))][0] for a in range(3))
        # first over the axis with the fewest orders among the members (one pass over the block
        # where they all share one), then over the other two in axis order
        a0 = min(range(3), key=lambda a: len(ax[a]))
        a1, a2 = (a for a in range(3) if a != a0)
        c0 = _specialised(em, "vp_c0", (*k, a0))
        for o0 in sorted({m.orders[a0] for m in members}):
            lines.append(f"double {p}_b{o0}[{(k[a1] + 1) * (k[a2] + 1)}]; {c0}(fd, {h}, {idx}, "
                         f"{ax[a0][o0][1]}, {p}_b{o0});")
        for o0, o1 in sorted({(m.orders[a0], m.orders[a1]) for m in members}):
            lines.append(f"double {p}_b{o0}{o1}[{k[a2] + 1}]; vp_c1({k[a1]}, {k[a2]}, {ax[a1][o1][1]}, "
                         f"{p}_b{o0}, {p}_b{o0}{o1});")
        for j, m in enumerate(members):
            o = m.orders
            v = sp.Symbol(f"{p}_v{j}")
            lines.append(f"double {v} = vp_c2({k[a2]}, {ax[a2][o[a2]][1]}, {p}_b{o[a0]}{o[a1]});")
            rep[m] = v
    return lines, [e.xreplace(rep) for e in exprs]



#: the contractions over a cell's coefficient block, specialised to constant degrees (and axis)
_SPECIALISED = {
    "vp_c0": ("static _VP_STAGE void {name}(const double *fd, const double *h, int64_t i0, int64_t i1, "
              "int64_t i2, const double *N, double *P) {{\n"
              "    vp_c0(fd, h, {0}, {1}, {2}, i0, i1, i2, {3}, N, P);\n}}\n"),
}


def _lines_c(name: str, k0: int, k1: int, k2: int, f: int, n: int) -> str:
    """C of ``vp_lines`` for constant degrees, moving axis f and n lines: (Na, Nb, L) per line."""
    args = ", ".join(f"const double *Na{j}, const double *Nb{j}, double *P{j}" for j in range(n))
    arr = lambda v: ", ".join(f"{v}{j}" for j in range(n))  # noqa: E731
    return (f"static _VP_STAGE void {name}(const double *fd, const double *h, int64_t i0, int64_t i1, "
            f"int64_t i2, {args}) {{\n"
            f"    const double *Na[{n}] = {{{arr('Na')}}}, *Nb[{n}] = {{{arr('Nb')}}}; "
            f"double *P[{n}] = {{{arr('P')}}};\n"
            f"    vp_lines(fd, h, {k0}, {k1}, {k2}, i0, i1, i2, {f}, {n}, Na, Nb, P);\n}}\n")


def _specialised(em: Any, fn: str, consts: tuple) -> str:
    """The name of ``vp_lines`` (consts: degrees, moving axis, number of lines) / ``vp_c0``
    (degrees, contracted axis) for constant ``consts``: one function per kernel with its loops unrolled
    (``_VP_STAGE``: compiled once and called, as the stages of a kernel without a vectorised pass —
    every spline kernel). Inlined at each of a stage's ~50 evaluations, these unrolled blocks were
    half of gcc's time; called, the step costs a few per cent more (issue #41,
    benchmarks/native/bench_compile.py)."""
    key = ("splines", fn, tuple(int(c) for c in consts))
    if key not in em.helpers:
        name = f"{fn}_{''.join(str(c) for c in key[2][:4])}" + (f"_{key[2][4]}" if fn == "vp_lines" else "")
        code = _lines_c(name, *key[2]) if fn == "vp_lines" else _SPECIALISED[fn].format(*key[2], name=name)
        em.helpers[key] = (name, code)
    return em.helpers[key][0]


def _pack(o: TensorSpline, head: np.ndarray, put) -> None:
    """A spline's header (module docstring); its arrays after the headers."""
    c = np.asarray(o.coefficients)
    if c.ndim != 3:
        raise ValueError("native splines are scalar (coefficients of shape (m1, m2, m3))")
    head[0:3] = [put(t) for t in o.knots]
    head[3:6] = [put(P) for P in o.cells]
    head[6] = put(c)
    head[7:10] = c.shape
    head[10:13] = [0.0 if T is None else float(T) for T in o.periods]
    for ax, (t, k) in enumerate(zip(o.knots, o.degrees)):  # the interval guess of vp_cell
        t = np.asarray(t)
        m = t.size - k - 1
        head[13 + ax] = (m - k) / (t[m] - t[k])


PACKERS[TensorSpline] = _pack


C_HELPERS = r"""
/* x wrapped into [t_k, t_k + T) on a periodic axis (T > 0; jnp.mod: fmod, + T where negative) */
static inline _VP_INLINE double vp_wrap(const double *t, double T, int k, double x) {
    if (!(T > 0.0)) return x;
    /* fmod's remainder without its call where the quotient q = trunc(d / T) is right: d - q T is
       then fmod's (exact, so representable) and one fma gives it exactly; else fmod */
    double d = x - t[k], q = trunc(d / T), r = fma(-q, T, d);
    if (!(fabs(r) < T) || (r != 0.0 && (r < 0.0) != (d < 0.0))) r = fmod(d, T);
    return t[k] + ((r != 0.0 && r < 0.0) ? r + T : r);
}

/* axis a of the spline with header h at x: the knot interval i = clip(#{t <= x} - 1, k, m - 1)
   and y = x - t_i; on a periodic axis x wraps into [t_k, t_k + T) (jnp.mod), off a
   non-periodic axis's range [t_k, t_m] y is NaN (the value and every derivative) */
static inline _VP_INLINE int64_t vp_cell(const double *fd, const double *h, int a, int k, double x,
                                         double *y) {
    const double *t = fd + (int64_t)h[a];
    int64_t m = (int64_t)h[7 + a];
    double T = h[10 + a], lo = t[k];
    x = vp_wrap(t, T, k, x);
    double xs = x;
    if (!(T > 0.0) && !(x >= lo && x <= t[m])) x = NAN;
    /* the largest i in [k, m - 1] with t_i <= xs (k if none, or NaN): from the interval a uniform
       spacing of the base interval would give (h[13 + a] = (m - k) / (t_m - t_k)), walked to
       the exact one (a step or two on a grid's near-uniform knots) */
    int64_t i;
    if (!(xs >= lo)) i = k;
    else if (xs >= t[m - 1]) i = m - 1;
    else {
        double g = (xs - lo) * h[13 + a];
        i = g < (double)(m - 1 - k) ? k + (int64_t)g : m - 1;
        while (i < m - 1 && t[i + 1] <= xs) i++;
        while (i > k && t[i] > xs) i--;
    }
    *y = x - t[i];
    return i;
}

/* the n-th derivative of sum_p c[p] y^p, Horner term by term (vp_basis: of each B-spline of a
   cell; vp_seg's callers: of a line's polynomial, vp_lpoly) */
static inline _VP_INLINE double vp_pn(int k, int n, const double *c, double y) {
    double f = 1.0;
    for (int j = 0; j < n; j++) f *= (double)(k - j);
    double v = f * c[k];
    for (int p = k - 1; p >= n; p--) {
        double g = 1.0;
        for (int j = 0; j < n; j++) g *= (double)(p - j);
        v = v * y + g * c[p];
    }
    return (n == k) ? v + 0.0 * y : v;  /* NaN off the grid, also for a constant */
}

/* the n-th derivatives of the k+1 non-zero B-splines of cell i at y: Horner on the cell's
   power-basis polynomials P[i - k, r, p] (coefficient of y^p), d^n/dy^n term by term */
static inline _VP_INLINE void vp_basis(const double *fd, const double *h, int a, int k, int64_t i,
                                       int n, double y, double *N) {
    const double *P = fd + (int64_t)h[3 + a] + (i - k) * (k + 1) * (k + 1);
    for (int r = 0; r <= k; r++) N[r] = vp_pn(k, n, P + r * (k + 1), y);
}

/* the coefficient block c[i0-k0+u, i1-k1+v, i2-k2+w] contracted over axis a with N: P over the
   other two axes in axis order (a = 0: P[v, w]; 1: P[u, w]; 2: P[u, v]) */
static inline _VP_INLINE void vp_c0(const double *fd, const double *h, int k0, int k1, int k2,
                                    int64_t i0, int64_t i1, int64_t i2, int a, const double *N,
                                    double *P) {
    const double *c = fd + (int64_t)h[6];
    int64_t m1 = (int64_t)h[8], m2 = (int64_t)h[9];
    const double *b = c + ((i0 - k0) * m1 + (i1 - k1)) * m2 + (i2 - k2);
    if (a == 0) {
        for (int j = 0; j < (k1 + 1) * (k2 + 1); j++) P[j] = 0.0;
        for (int x = 0; x <= k0; x++)  /* innermost along the contiguous axis 2 */
            for (int y = 0; y <= k1; y++)
                for (int z = 0; z <= k2; z++) P[y * (k2 + 1) + z] += N[x] * b[(x * m1 + y) * m2 + z];
    } else if (a == 1) {
        for (int j = 0; j < (k0 + 1) * (k2 + 1); j++) P[j] = 0.0;
        for (int x = 0; x <= k0; x++)
            for (int y = 0; y <= k1; y++)
                for (int z = 0; z <= k2; z++) P[x * (k2 + 1) + z] += N[y] * b[(x * m1 + y) * m2 + z];
    } else {
        for (int x = 0; x <= k0; x++)
            for (int y = 0; y <= k1; y++) {
                double s = 0.0;
                for (int z = 0; z <= k2; z++) s += N[z] * b[(x * m1 + y) * m2 + z];
                P[x * (k1 + 1) + y] = s;
            }
    }
}

/* a line's polynomial in y in cell i of axis a: c[p] = sum_r L[r] P[i - k, r, p] (the cell's
   B-spline polynomials weighted by the line's coefficients) */
static inline _VP_INLINE void vp_lpoly(const double *fd, const double *h, int a, int k, int64_t i,
                                       const double *L, double *c) {
    const double *P = fd + (int64_t)h[3 + a] + (i - k) * (k + 1) * (k + 1);
    for (int p = 0; p <= k; p++) {
        double s = 0.0;
        for (int r = 0; r <= k; r++) s += L[r] * P[r * (k + 1) + p];
        c[p] = s;
    }
}

/* a row of k + 1 = 4 or 6 doubles (degree 3 or 5) as a 4-vector and a 2-vector (0 for k = 3), in
   gcc's vector extensions: the shared-y contraction of vp_lines runs on whole rows (unaligned
   loads; may_alias: the rows are read from double arrays). gcc left to itself vectorised it
   across pairs of y rows with a horizontal sum per entry, 1.27x slower on W7-X's K */
typedef double vp_v4 __attribute__((vector_size(32), aligned(8), may_alias));
typedef double vp_v2 __attribute__((vector_size(16), aligned(8), may_alias));
typedef struct { vp_v4 a; vp_v2 b; } vp_row;
#define VP_ROWK(k) ((k) == 3 || (k) == 5)
static inline _VP_INLINE vp_row vp_ld(int k, const double *r) {
    vp_row v = {*(const vp_v4 *)r, {0.0, 0.0}};
    if (k == 5) v.b = *(const vp_v2 *)(r + 4);
    return v;
}
static inline _VP_INLINE void vp_fma(int k, vp_row *s, double w, vp_row v) {
    s->a += w * v.a;
    if (k == 5) s->b += w * v.b;
}
static inline _VP_INLINE double vp_dot(int k, vp_row u, vp_row v) {
    vp_v4 a = u.a * v.a;
    double s = (a[0] + a[1]) + (a[2] + a[3]);
    if (k == 5) { vp_v2 b = u.b * v.b; s += b[0] + b[1]; }
    return s;
}
static inline _VP_INLINE double vp_at(vp_row v, int p) { return p < 4 ? v.a[p] : v.b[p - 4]; }

/* the block contracted over every axis but f, for n lines of it at once (line j: Na[j], Nb[j],
   the bases of the other two axes in axis order), in one pass over the block: the k_f + 1
   coefficients of line j in the cell along axis f, then its polynomial in y there, P[j] (as
   vp_lpoly); the innermost loop runs along the contiguous axis 2 (n <= VP_LINES, degrees <= 9) */
#define VP_LINES 8
static inline _VP_INLINE void vp_lines(const double *fd, const double *h, int k0, int k1, int k2,
                                       int64_t i0, int64_t i1, int64_t i2, int f, int n,
                                       const double *const *Na, const double *const *Nb,
                                       double *const *P) {
    const double *c = fd + (int64_t)h[6];
    int64_t m1 = (int64_t)h[8], m2 = (int64_t)h[9];
    const double *b = c + ((i0 - k0) * m1 + (i1 - k1)) * m2 + (i2 - k2);
    int kf = f == 0 ? k0 : f == 1 ? k1 : k2;
    double acc[VP_LINES][10];  /* the sums, local: no store to L can alias the block */
    for (int j = 0; j < n; j++)
        for (int p = 0; p <= kf; p++) acc[j][p] = 0.0;
    /* lines along x or z that share the basis of y (a stage's lines are at one point of the
       other two axes, differentiated along one of them): y contracted once, T[x][z], then each
       line's other axis — (k+1)^3 + n (k+1)^2 products instead of n ((k+1)^3 + (k+1)^2) */
    int sa = n > 1, sb = n > 1;
    for (int j = 1; j < n; j++) { sa &= Na[j] == Na[0]; sb &= Nb[j] == Nb[0]; }
    if ((f == 0 && sa) || (f == 2 && sb)) {  /* lines along x or z, one y basis */
        const double *Ny = f == 0 ? Na[0] : Nb[0];
        if (VP_ROWK(k2) && VP_ROWK(kf)) {  /* the same sums on whole rows (vp_row) */
            vp_row R[10];  /* R[x] = sum_y N[y] c[x][y][.] */
            for (int x = 0; x <= k0; x++) {
                vp_row s = {{0.0, 0.0, 0.0, 0.0}, {0.0, 0.0}};
                for (int y = 0; y <= k1; y++) vp_fma(k2, &s, Ny[y], vp_ld(k2, b + (x * m1 + y) * m2));
                R[x] = s;
            }
            /* line j's coefficients L along f, then its polynomial sum_r L[r] P[i - k, r, .] (vp_lpoly) */
            const double *Pc = fd + (int64_t)h[3 + f] + ((f == 0 ? i0 : i2) - kf) * (kf + 1) * (kf + 1);
            for (int j = 0; j < n; j++) {
                double L[10];
                if (f == 0) {
                    vp_row nz = vp_ld(k2, Nb[j]);
                    for (int x = 0; x <= k0; x++) L[x] = vp_dot(k2, nz, R[x]);
                } else {
                    vp_row s = {{0.0, 0.0, 0.0, 0.0}, {0.0, 0.0}};
                    for (int x = 0; x <= k0; x++) vp_fma(k2, &s, Na[j][x], R[x]);
                    for (int z = 0; z <= k2; z++) L[z] = vp_at(s, z);
                }
                vp_row q = {{0.0, 0.0, 0.0, 0.0}, {0.0, 0.0}};
                for (int r = 0; r <= kf; r++) vp_fma(kf, &q, L[r], vp_ld(kf, Pc + r * (kf + 1)));
                for (int p = 0; p <= kf; p++) P[j][p] = vp_at(q, p);
            }
            return;
        }
        double T[10][10];  /* T[x][z] = sum_y N[y] c[x][y][z] */
        for (int x = 0; x <= k0; x++) {
            for (int z = 0; z <= k2; z++) T[x][z] = 0.0;
            for (int y = 0; y <= k1; y++) {
                const double *r = b + (x * m1 + y) * m2;
                double w = Ny[y];
                for (int z = 0; z <= k2; z++) T[x][z] += w * r[z];
            }
        }
        for (int j = 0; j < n; j++) {
            if (f == 0) {  /* each line's z basis */
                for (int x = 0; x <= k0; x++) {
                    double t = 0.0;
                    for (int z = 0; z <= k2; z++) t += Nb[j][z] * T[x][z];
                    acc[j][x] = t;
                }
            } else {  /* each line's x basis */
                for (int z = 0; z <= k2; z++) acc[j][z] = 0.0;
                for (int x = 0; x <= k0; x++) {
                    double w = Na[j][x];
                    for (int z = 0; z <= k2; z++) acc[j][z] += w * T[x][z];
                }
            }
        }
        for (int j = 0; j < n; j++) vp_lpoly(fd, h, f, kf, f == 0 ? i0 : i2, acc[j], P[j]);
        return;
    }
    for (int x = 0; x <= k0; x++)
        for (int y = 0; y <= k1; y++) {
            const double *r = b + (x * m1 + y) * m2;
            for (int j = 0; j < n; j++) {
                if (f == 2) {
                    double w = Na[j][x] * Nb[j][y];
                    for (int z = 0; z <= k2; z++) acc[j][z] += w * r[z];
                } else {
                    double s = 0.0;
                    for (int z = 0; z <= k2; z++) s += Nb[j][z] * r[z];
                    acc[j][f == 0 ? x : y] += (f == 0 ? Na[j][y] : Na[j][x]) * s;
                }
            }
        }
    int64_t i = f == 0 ? i0 : f == 1 ? i1 : i2;
    for (int j = 0; j < n; j++) vp_lpoly(fd, h, f, kf, i, acc[j], P[j]);
}

/* the cell of z on axis a, kept by a hoisted line (hoist) while z (wrapped, vp_wrap) stays in
   it: [lo, hi) = [t_i, t_i+1), y = z - t_i as vp_cell gives it; 1 when z entered another cell
   (vp_cell then), or is off the grid (y NaN, the cell never kept) */
typedef struct { double lo, hi; int64_t i; } vp_seg_t;
#define VP_SEG0 {1.0, 0.0, -1}
static inline _VP_INLINE int vp_seg(const double *fd, const double *h, int a, int k, double z,
                                    vp_seg_t *s, double *y) {
    const double *t = fd + (int64_t)h[a];
    double w = vp_wrap(t, h[10 + a], k, z);
    if (w >= s->lo && w < s->hi) { *y = w - s->lo; return 0; }
    s->i = vp_cell(fd, h, a, k, z, y);
    s->lo = t[s->i]; s->hi = t[s->i + 1];
    return 1;
}

/* then over axis 1 with N1: V[c] */
static inline _VP_INLINE void vp_c1(int k1, int k2, const double *N1, const double *P, double *V) {
    for (int z = 0; z <= k2; z++) {
        double s = 0.0;
        for (int y = 0; y <= k1; y++) s += N1[y] * P[y * (k2 + 1) + z];
        V[z] = s;
    }
}

/* then over axis 2 with N2: the value */
static inline _VP_INLINE double vp_c2(int k2, const double *N2, const double *V) {
    double s = 0.0;
    for (int z = 0; z <= k2; z++) s += N2[z] * V[z];
    return s;
}
"""

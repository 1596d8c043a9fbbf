"""C statements from SymPy expressions, shared by the emitters of :mod:`.emit`.

:func:`_assign` prints ``double t = e;`` with common-subexpression elimination, after turning the
Gauss–Legendre sums of quadrature potentials into loops over the nodes (:func:`_gl_loops`), the
spline atoms of spline potentials and the coil atoms of coil potentials into their evaluations
(:func:`.splines.spline_calls`, :func:`.coils.coil_calls`) and data scalars into reads of ``fd``.
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from ...._quadrature import GL_T, GLSum, _nodes_weights
from . import coils, data, splines
from .cprinter import printer as _printer

__all__ = ["_C", "_assign", "_gl_loops", "_gl_table"]

# C variable names as SymPy symbols (no assumptions: printed by name)
_C = {n: sp.Symbol(n) for n in ("x1", "x2", "x3", "y1", "y2", "y3", "Y2", "Y3", "z", "h")}


def _assign(targets: list[str], exprs: list[Any], subs: dict, tag: str) -> list[str]:
    """C statements ``double t = e;`` with common-subexpression elimination (sympy.cse); the
    Gauss–Legendre sums in them first, by :func:`_gl_loops`."""
    exprs = [sp.sympify(e).xreplace(subs) for e in exprs]
    lines, exprs = _gl_loops(exprs, tag)
    more, exprs = _nested_calls(exprs, tag)  # atoms inside atoms' arguments: those first
    lines += more
    more, exprs = splines.spline_calls(exprs, tag, _printer)  # spline atoms: data read at run time
    lines += more
    more, exprs = coils.coil_calls(exprs, tag, _printer)  # coil atoms: one loop over the segments
    lines += more
    exprs = data.read_scalars(exprs)
    syms = sp.numbered_symbols(f"{tag}_")
    reps, red = sp.cse(exprs, symbols=syms)
    lines += [f"double {s} = {_printer.doprint(e)};" for s, e in reps]
    lines += [f"double {t} = {_printer.doprint(e)};" for t, e in zip(targets, red)]
    return lines


def _nested_calls(exprs: list[Any], tag: str) -> tuple[list[str], list[Any]]:
    """The atoms evaluated at a point that itself holds atoms (a field at the Euler point
    x + h a(x), as the correction integrand's Q(s)): the inner ones first, innermost first, as
    variables, so that every atom the calls below print has a plain point."""
    lines: list[str] = []
    while True:
        inner = {b for e in exprs for a in data.data_atoms(e) for x in a.args[3:] for b in data.data_atoms(x)}
        inner = sorted((b for b in inner if not data.nested(b)), key=sp.default_sort_key)
        if not inner:
            return lines, exprs
        more, vals = splines.spline_calls(inner, tag, _printer)
        lines += more
        more, vals = coils.coil_calls(vals, tag, _printer)
        lines += more
        if any(data.data_atoms(v) for v in vals):
            raise ValueError(f"native codegen: no evaluation emitted for {inner}")
        rep = dict(zip(inner, vals))
        exprs = [sp.sympify(e).xreplace(rep) for e in exprs]


def _gl_table(n: int) -> str:
    """The n-point Gauss–Legendre rule on [0, 1] as two static C arrays, the nodes and weights of
    :func:`vpforms._quadrature._nodes_weights` printed exactly (``%.17g`` round-trips a double)."""
    t, w = (", ".join(format(float(v), ".17g") for v in a) for a in _nodes_weights(n))
    return (f"static const double VP_GL_T{n}[{n}] = {{{t}}};\n"
            f"static const double VP_GL_W{n}[{n}] = {{{w}}};\n")


def _gl_loops(exprs: list[Any], tag: str) -> tuple[list[str], list[Any]]:
    """The :class:`~vpforms._quadrature.GLSum` s in ``exprs`` as C loops over the nodes.

    Each distinct sum Σᵢ wᵢ fᵢ becomes an accumulator ``{tag}_gsK``; the sums of one rule share a
    loop in which their integrands at t = tᵢ are evaluated together (one cse). Returns the loop
    statements and ``exprs`` with the sums replaced by their accumulators."""
    sums = sorted({q for e in exprs for q in sp.sympify(e).atoms(GLSum)}, key=sp.default_sort_key)
    if not sums:
        return [], exprs
    acc = {q: sp.Symbol(f"{tag}_gs{k}") for k, q in enumerate(sums)}
    lines = []
    for n in sorted({q.n for q in sums}):
        group = [q for q in sums if q.n == n]
        t = sp.Symbol(f"{tag}_t{n}")
        with data.scope():  # the loop's body is a C block
            body = _assign([f"{tag}_gf{n}_{k}" for k in range(len(group))],
                           [q.integrand.xreplace({GL_T: t}) for q in group], {}, f"{tag}_g{n}")
        # Σᵢ wᵢ f(tᵢ) in node order, as jnp.dot(w, f(t)) in vpforms._quadrature.line_integral
        lines += [f"double {', '.join(f'{acc[q]} = 0.0' for q in group)};",
                  f"for (int {tag}_k = 0; {tag}_k < {n}; {tag}_k++) {{",
                  f"    double {t} = VP_GL_T{n}[{tag}_k], {tag}_w = VP_GL_W{n}[{tag}_k];",
                  *(f"    {ln}" for ln in body),
                  *(f"    {acc[q]} += {tag}_w * {tag}_gf{n}_{k};" for k, q in enumerate(group)),
                  "}"]
    return lines, [sp.sympify(e).xreplace(acc) for e in exprs]

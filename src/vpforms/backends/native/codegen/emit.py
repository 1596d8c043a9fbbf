"""C from the stages of :mod:`.plan`: the generic map per lane, RK4, and the kernel ``vp_run``.

A :class:`~.potentials.MapStage` becomes a function that does what :mod:`vpforms._map` does for one
point: y = x·σ, the Euler guess, the scalar solve of volpot1 for Y₃ then of volpot2 for Y₂ (the
rules of :func:`vpforms._newton.newton_scalar`: step, stopping test, twist, divergence bound, final
Newton step; status ``not_converged``/``twist_failure``), Y₁ from volpot3, X = Y·Σ⁻¹, and the
non-finite status. A solve whose equation is affine in its unknown (g' free of it: e.g. the SE+SE
shears of ABC) is emitted in closed form z = −g(0)/g' with the same twist test — the root Newton
converges to; ``engine="newton"`` forces the iteration everywhere (tests, benchmark).

The kernel: particles in blocks of ``BLOCK`` lanes held as structure-of-arrays in L1 for all steps
of a segment; OpenMP over blocks; ``#pragma omp simd`` over lanes so gcc calls libmvec's sin/cos.
A lane whose step fails is frozen with its status and its step index kept.
"""

from __future__ import annotations

from typing import Any

import sympy as sp
from sympy.printing.c import C99CodePrinter

from ...._errors import RESULTS
from ....symbolic import _symbols as G
from .plan import plan
from .potentials import MapStage, RK4Stage

__all__ = ["BLOCK", "CDEF", "kernel_source"]

BLOCK = 64
CDEF = "void vp_run(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h);"

_printer = C99CodePrinter()

#: glibc declares libmvec's vector variants only under __FAST_MATH__, which -fno-finite-math-only
#: turns off; re-declare them (glibc ≥ 2.22 has these five) so gcc still vectorises the calls.
_SIMD_DECLS = "".join(
    f'__attribute__((__simd__("notinbranch"))) double {f}(double{", double" if f == "pow" else ""});\n'
    for f in ("sin", "cos", "exp", "log", "pow")
)

# C variable names as SymPy symbols (no assumptions: printed by name)
_C = {n: sp.Symbol(n) for n in ("x1", "x2", "x3", "y1", "y2", "y3", "Y2", "Y3", "z", "h")}


def _assign(targets: list[str], exprs: list[Any], subs: dict, tag: str) -> list[str]:
    """C statements ``double t = e;`` with common-subexpression elimination (sympy.cse)."""
    exprs = [sp.sympify(e).xreplace(subs) for e in exprs]
    syms = sp.numbered_symbols(f"{tag}_")
    reps, red = sp.cse(exprs, symbols=syms)
    lines = [f"double {s} = {_printer.doprint(e)};" for s, e in reps]
    lines += [f"double {t} = {_printer.doprint(e)};" for t, e in zip(targets, red)]
    return lines


def _newton_c(var: str, z0: str, g_dg: list[str], opts: tuple, tag: str) -> list[str]:
    """newton_scalar (vpforms._newton) in C: same step, stopping rule, twist and divergence tests,
    and the final Newton step; ``g_dg`` are statements defining ``{tag}_g``/``{tag}_dg`` of z.
    Defines ``double var`` and ``int {tag}_st``."""
    tol, mi, tw = opts
    body = "\n        ".join(g_dg)
    return [
        f"double {tag}_z = {z0}, {tag}_z0 = {tag}_z; int {tag}_st = -1;",
        f"double {tag}_far = 1e8 * (1.0 + fabs({tag}_z0));",
        f"for (int it = 0; it < {mi} && {tag}_st == -1; it++) {{",
        f"    double z = {tag}_z;",
        f"    {{\n        {body}",
        f"    int tw = !(fabs({tag}_dg) > {tw!r});",
        f"    double step = {tag}_g / (tw ? 1.0 : {tag}_dg);",
        "    double zn = z - step;",
        f"    int dv = !(fabs(zn) <= DBL_MAX) || fabs(zn - {tag}_z0) > {tag}_far;",
        f"    int cv = fabs(step) <= {tol!r} * (1.0 + fabs(zn));",
        f"    {tag}_st = tw ? {RESULTS.twist_failure} : dv ? {RESULTS.not_converged} : cv ? 0 : -1;",
        f"    {tag}_z = (tw || dv) ? z : zn;",
        "    }",
        "}",
        f"if ({tag}_st == -1) {tag}_st = {RESULTS.not_converged};",
        f"if ({tag}_st == 0) {{ double z = {tag}_z; {{\n        {body}",
        f"    {tag}_z = z - {tag}_g / {tag}_dg; }} }}",
        f"double {var} = {tag}_z;",
    ]


def _solve_c(var: str, g: sp.Expr, subs: dict, guess: str, opts: tuple, tag: str,
             newton: bool) -> list[str]:
    """Solve g(z) = 0 for ``var`` (z = the symbol _C["z"] after ``subs``); defines ``{tag}_st``."""
    g = sp.sympify(g).xreplace(subs)
    z = _C["z"]
    dg = sp.diff(g, z)
    if newton or z in dg.free_symbols:
        return _newton_c(var, guess, _assign([f"{tag}_g", f"{tag}_dg"], [g, dg], {}, f"{tag}c"),
                         opts, tag)
    # affine in z: the root Newton converges to, in closed form; the same twist test on g' = const
    lines = _assign([f"{tag}_g0", f"{tag}_dg"], [g.xreplace({z: 0}), dg], {}, f"{tag}c")
    lines.append(f"double {var} = -{tag}_g0 / {tag}_dg;")
    if dg.is_Number and abs(float(dg)) > opts[2]:
        lines.append(f"int {tag}_st = 0;")
    else:
        lines.append(f"int {tag}_st = !(fabs({tag}_dg) > {opts[2]!r}) ? {RESULTS.twist_failure} : 0;")
    return lines


def _map_body(st: MapStage, newton: bool) -> list[str]:
    """((σ,Σ)·f^s_{φ,Φ})(x) on one lane, as vpforms._map._solve_point (see the module docstring)."""
    Y3, Y2, y1, y2, y3, h = G.Y[2], G.Y[1], G.y[0], G.y[1], G.y[2], G.h
    c = _C
    sig, Sig, Sinv = st.case.sigma.index, st.case.Sigma.index, st.case.Sigma.inverse().index
    lines = [f"double y{k + 1} = x{sig[k] + 1};" for k in range(3)]  # y = x·σ
    base = {y1: c["y1"], y2: c["y2"], y3: c["y3"], h: c["h"]}
    d2phi, d1phi = sp.diff(st.phi, y2), sp.diff(st.phi, Y3)
    d3Phi, d2Phi = sp.diff(st.Phi, y3), sp.diff(st.Phi, Y2)
    g1 = d2phi - y1  # volpot1: ∂₂φ(Y₃, y₂, y₃) = y₁, for Y₃
    g2 = d3Phi + st.sign * d1phi  # volpot2: ∂₃Φ(Y₃, Y₂, y₃) ± ∂₁φ(Y₃, y₂, y₃) = 0, for Y₂
    # Euler guess X ≈ x + h a(x), Y = X·Σ: only the components a Newton iteration starts from
    need = {}
    for k, g, sub in ((2, g1, {Y3: c["z"]}), (1, g2, {Y3: c["Y3"], Y2: c["z"]})):
        gz = sp.sympify(g).xreplace({**base, **sub})
        if newton or c["z"] in sp.diff(gz, c["z"]).free_symbols:
            need[k] = Sig[k]
    xs = {G.x[i]: c[f"x{i + 1}"] for i in range(3)}
    if need:
        comps = sorted(set(need.values()))
        lines += _assign([f"ga{i + 1}" for i in comps], [st.field_exprs[i] for i in comps], xs, "ge")
    guess = {k: f"x{i + 1} + h*ga{i + 1}" if k in need else "0.0" for k, i in ((2, Sig[2]), (1, Sig[1]))}
    lines += _solve_c("Y3", g1, {**base, Y3: c["z"]}, guess[2], st.newton, "n1", newton)
    lines += _solve_c("Y2", g2, {**base, Y3: c["Y3"], Y2: c["z"]}, guess[1], st.newton, "n2", newton)
    lines += _assign(["Y1"], [d2Phi], {**base, Y3: c["Y3"], Y2: c["Y2"]}, "v3")  # volpot3
    lines += [f"X{i + 1} = Y{Sinv[i] + 1};" for i in range(3)]  # X = Y·Σ⁻¹
    lines += [
        "int inok = (fabs(x1) <= DBL_MAX) & (fabs(x2) <= DBL_MAX) & (fabs(x3) <= DBL_MAX);",
        "int fin = (fabs(X1) <= DBL_MAX) & (fabs(X2) <= DBL_MAX) & (fabs(X3) <= DBL_MAX);",
        "code = n1_st ? n1_st : n2_st;",
        f"code = !inok ? {RESULTS.nonfinite} : (code == 0 && !fin) ? {RESULTS.nonfinite} : code;",
    ]
    return lines


def _rk4_body(field) -> list[str]:
    s = field.symbols
    a = [sp.sympify(e) for e in field.exprs]
    lines = []
    prev = None
    for c, name in [(0, "k1"), (0.5, "k2"), (0.5, "k3"), (1.0, "k4")]:
        args = [f"x{i + 1}" if prev is None else f"(x{i + 1} + {c!r}*h*{prev}_{i + 1})" for i in range(3)]
        lines += [f"double {name}_in{i + 1} = {args[i]};" for i in range(3)]
        lines += _assign([f"{name}_{i + 1}" for i in range(3)], a,
                         {s[i]: sp.Symbol(f"{name}_in{i + 1}") for i in range(3)}, f"{name}c")
        prev = name
    for i in range(3):
        j = i + 1
        lines.append(f"X{j} = x{j} + (h/6.0)*(k1_{j} + 2.0*k2_{j} + 2.0*k3_{j} + k4_{j});")
    return lines


def _stage_fn(name: str, body: list[str]) -> str:
    step = "\n    ".join(body)
    return f"""static inline int {name}(double x1, double x2, double x3, double h,
                           double *restrict o1, double *restrict o2, double *restrict o3) {{
    double X1, X2, X3; int code = 0;
    {step}
    *o1 = X1; *o2 = X2; *o3 = X3;
    return code;
}}
"""


def _stage_body(stage: Any, newton: bool) -> list[str]:
    if isinstance(stage, RK4Stage):
        return _rk4_body(stage.field)
    return _map_body(stage, newton)


def kernel_source(method: Any, engine: str = "auto") -> str:
    """The complete C source of ``vp_run`` for ``method`` (see :data:`CDEF`).

    ``engine="newton"`` iterates Newton on every solve, also where the equation is affine in its
    unknown (the same map; used to measure the engine against the closed form)."""
    from ...._integrate import describe

    if engine not in ("auto", "newton"):
        raise ValueError(f"engine must be 'auto' or 'newton', got {engine!r}")
    stages = plan(method)
    if isinstance(stages, str):
        raise ValueError(stages)
    names: dict[str, str] = {}  # body → function name (stages with the same map share one)
    calls = []
    for stage, coef in stages:
        body = "\n".join(_stage_body(stage, engine == "newton"))
        fn = names.setdefault(body, f"vp_s{len(names)}")
        calls.append(f"c = {fn}(y1, y2, y3, {coef!r} * h, &y1, &y2, &y3); code = code ? code : c;")
    fns = "".join(_stage_fn(fn, body.split("\n")) for body, fn in names.items())
    calls_c = "\n    ".join(calls)
    return f"""
#include <math.h>
#include <stdint.h>
#include <float.h>
#define B {BLOCK}
{_SIMD_DECLS}
{fns}
/* one step of {describe(method)}: {len(stages)} stage(s), generated from SymPy */
static inline int vp_step(double x1, double x2, double x3, double h,
                          double *restrict o1, double *restrict o2, double *restrict o3) {{
    double y1 = x1, y2 = x2, y3 = x3; int code = 0, c;
    {calls_c}
    *o1 = y1; *o2 = y2; *o3 = y3;
    return code;
}}

void vp_run(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h) {{
    int64_t nb = (N + B - 1) / B;
    #pragma omp parallel for schedule(dynamic, 1)
    for (int64_t b = 0; b < nb; b++) {{
        int64_t lo = b * B;
        int m = (int)(N - lo < B ? N - lo : B);
        double a1[B], a2[B], a3[B];
        int32_t st[B];
        int64_t nn[B];
        int64_t nmin = n_target;
        for (int i = 0; i < B; i++) {{
            if (i < m) {{
                a1[i] = x[3 * (lo + i)]; a2[i] = x[3 * (lo + i) + 1]; a3[i] = x[3 * (lo + i) + 2];
                st[i] = status[lo + i]; nn[i] = n[lo + i];
                if (st[i] == 0 && nn[i] < nmin) nmin = nn[i];
            }} else {{
                a1[i] = a2[i] = a3[i] = 0.0; st[i] = 1; nn[i] = n_target;  /* padding lane: inactive */
            }}
        }}
        for (int64_t k = nmin; k < n_target; k++) {{
            #pragma omp simd
            for (int i = 0; i < B; i++) {{
                double X1, X2, X3;
                int code = vp_step(a1[i], a2[i], a3[i], h, &X1, &X2, &X3);
                int act = (st[i] == 0) & (nn[i] < n_target);
                /* non-finite test that survives -ffast-math: NaN fails every comparison */
                int fin = (fabs(X1) <= DBL_MAX) & (fabs(X2) <= DBL_MAX) & (fabs(X3) <= DBL_MAX);
                int inok = (fabs(a1[i]) <= DBL_MAX) & (fabs(a2[i]) <= DBL_MAX) & (fabs(a3[i]) <= DBL_MAX);
                code = !inok ? {RESULTS.nonfinite} : code ? code : fin ? 0 : {RESULTS.nonfinite};
                int ok = act & (code == 0);
                a1[i] = ok ? X1 : a1[i]; a2[i] = ok ? X2 : a2[i]; a3[i] = ok ? X3 : a3[i];
                st[i] = (act & (code != 0)) ? code : st[i];
                nn[i] += ok;
            }}
        }}
        for (int i = 0; i < m; i++) {{
            x[3 * (lo + i)] = a1[i]; x[3 * (lo + i) + 1] = a2[i]; x[3 * (lo + i) + 2] = a3[i];
            status[lo + i] = st[i]; n[lo + i] = nn[i];
        }}
    }}
}}
"""

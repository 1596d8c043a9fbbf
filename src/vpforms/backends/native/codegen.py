"""Generate the C kernel of a method from the SymPy expressions vpforms already has.

Supported now: :class:`vpforms.RK4` on a symbolic field (the baseline) and SE+SE (eq:case5) on its
representative case when both shears are explicit (closed-form potentials, ∂₂F¹ free of x₃ and
∂₁F³ free of x₂; decided by :func:`vpforms._methods.se_se._explicit_flags`), e.g. ABC.  Everything
else returns a reason from :func:`unsupported_reason` (and runs on JAX under ``backend="auto"``).

The kernel: particles in blocks of ``BLOCK`` lanes held as structure-of-arrays in L1 for all steps
of a segment; OpenMP over blocks; ``#pragma omp simd`` over lanes so gcc calls libmvec's sin/cos.
A lane whose step is non-finite is frozen with status ``nonfinite`` and its step index kept.
"""

from __future__ import annotations

from typing import Any

import sympy as sp
from sympy.printing.c import C99CodePrinter

from ..._errors import RESULTS

__all__ = ["BLOCK", "CDEF", "kernel_source", "unsupported_reason"]

BLOCK = 64
CDEF = "void vp_run(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h);"

_printer = C99CodePrinter()

#: glibc declares libmvec's vector variants only under __FAST_MATH__, which -fno-finite-math-only
#: turns off; re-declare them (glibc ≥ 2.22 has these five) so gcc still vectorises the calls.
_SIMD_DECLS = "".join(
    f'__attribute__((__simd__("notinbranch"))) double {f}(double{", double" if f == "pow" else ""});\n'
    for f in ("sin", "cos", "exp", "log", "pow")
)


def _bare(method: Any) -> Any:
    return getattr(method, "without_recovery", lambda: method)()


def _symbolic(field: Any) -> str | None:
    if getattr(field, "exprs", None) is None or getattr(field, "symbols", None) is None:
        return "field was given as a JAX callable; build it with Field.from_sympy"
    free = set().union(*(sp.sympify(e).free_symbols for e in field.exprs))
    if not free <= set(field.symbols):
        return f"field has unsubstituted parameters {sorted(map(str, free - set(field.symbols)))}"
    return None


def _plan(method: Any) -> tuple[Any, list[tuple[str, float]]] | str:
    """(base method, stages [(\"fwd\" | \"adj\", coefficient of h)]) or the reason it is unsupported.

    Compositions (HLW II.4): SymmetricPair = Ψ*_{h/2}∘Ψ_{h/2}; Composition = S_{γ_s h}∘…∘S_{γ_1 h};
    Adjoint = Ψ*_h.  All stages run in one kernel call per step.
    """
    from ..._integrate import RK4
    from ..._methods._base import Adjoint
    from ..._methods.compose import Composition, SymmetricPair
    from ..._methods.se_se import SESE

    m = _bare(method)
    if isinstance(m, Composition):
        inner = _plan(m.base)
        if isinstance(inner, str):
            return inner
        base, st = inner
        return base, [(k, c * g) for g in m.gammas for (k, c) in st]
    if isinstance(m, SymmetricPair):
        inner = _plan(m.base)
        if isinstance(inner, str):
            return inner
        base, st = inner
        if st != [("fwd", 1.0)]:
            return "native compositions need an order-1 SE+SE base"
        return base, [("fwd", 0.5), ("adj", 0.5)]
    if isinstance(m, Adjoint):
        inner = _plan(m.base)
        if isinstance(inner, str):
            return inner
        base, st = inner
        if st != [("fwd", 1.0)]:
            return "native adjoints need an order-1 SE+SE base"
        return base, [("adj", 1.0)]
    if isinstance(m, (RK4, SESE)):
        return m, [("fwd", 1.0)]
    return (f"{getattr(m, 'name', type(m).__name__)} is not generated natively yet "
            "(native supports RK4 and closed-form SE+SE with its compositions)")


def unsupported_reason(method: Any) -> str | None:
    """None if :func:`kernel_source` can generate ``method``, else the reason it cannot."""
    from ..._integrate import RK4
    from ..._methods._representatives import REPRESENTATIVES
    from ..._methods.se_se import _explicit_flags

    plan = _plan(method)
    if isinstance(plan, str):
        return plan
    m, stages = plan
    why = _symbolic(m.field)
    if why or isinstance(m, RK4):
        return why
    if m.field.se_potential_exprs is None:
        return "SE potentials have no closed form (quadrature); native needs symbolic potentials"
    if m.case != REPRESENTATIVES["SE+SE"]:
        return f"SE+SE on case {m.case} is not generated natively yet (representative case only)"
    if any(k == "adj" for k, _ in stages) and not (all(_explicit_flags(m.field))
                                                     and all(_adjoint_flags(m.field))):
        return ("the SE+SE adjoint is implicit for this field; the native inverse Newton engine "
                "is not built yet (compositions need it)")
    return None


def _adjoint_flags(field) -> tuple[bool, bool]:
    """(∂₂F³ free of x₁, ∂₃F¹ free of x₂): the adjoint's shears are then explicit too."""
    x1, x2, x3 = field.symbols
    F1, F3 = (sp.sympify(e) for e in field.se_potential_exprs)
    return x1 not in sp.diff(F3, x2).free_symbols, x2 not in sp.diff(F1, x3).free_symbols


def _assign(targets: list[str], exprs: list[Any], subs: dict, tag: str) -> list[str]:
    """C statements ``double t = e;`` with common-subexpression elimination (sympy.cse)."""
    exprs = [sp.sympify(e).xreplace(subs) for e in exprs]
    syms = sp.numbered_symbols(f"{tag}_")
    reps, red = sp.cse(exprs, symbols=syms)
    lines = [f"double {s} = {_printer.doprint(e)};" for s, e in reps]
    lines += [f"double {t} = {_printer.doprint(e)};" for t, e in zip(targets, red)]
    return lines


def _rk4_body(field) -> list[str]:
    s = field.symbols
    y = sp.symbols("y1 y2 y3", real=True)
    a = [sp.sympify(e) for e in field.exprs]
    lines = []
    prev = None
    for k, (c, name) in enumerate([(0, "k1"), (0.5, "k2"), (0.5, "k3"), (1.0, "k4")]):
        args = [f"x{i + 1}" if prev is None else f"(x{i + 1} + {c!r}*h*{prev}_{i + 1})" for i in range(3)]
        lines += [f"double {name}_in{i + 1} = {args[i]};" for i in range(3)]
        lines += _assign([f"{name}_{i + 1}" for i in range(3)], a,
                         {s[i]: sp.Symbol(f"{name}_in{i + 1}") for i in range(3)}, f"{name}c")
        prev = name
    for i in range(3):
        j = i + 1
        lines.append(f"X{j} = x{j} + (h/6.0)*(k1_{j} + 2.0*k2_{j} + 2.0*k3_{j} + k4_{j});")
    del y
    return lines


def _sese_body(field) -> list[str]:
    x1, x2, x3 = field.symbols
    F1, F3 = (sp.sympify(e) for e in field.se_potential_exprs)
    h = sp.Symbol("h")
    S = sp.Symbol
    lines = []
    # X₃ = x₃ − h∂₂F¹(x₁, x₂, ·)   (volpot1; explicit: ∂₂F¹ free of x₃)
    lines += _assign(["t3"], [x3 - h * sp.diff(F1, x2)], {x1: S("x1"), x2: S("x2"), x3: S("x3")}, "a")
    # X₂ = x₂ + h∂₃F¹(x₁, x₂, X₃) − h∂₁F³(x₁, ·, X₃)   (volpot2; explicit: ∂₁F³ free of x₂)
    lines += _assign(["t2"], [x2 + h * sp.diff(F1, x3) - h * sp.diff(F3, x1)],
                     {x1: S("x1"), x2: S("x2"), x3: S("t3")}, "b")
    # X₁ = x₁ + h∂₂F³(x₁, X₂, X₃)   (volpot3)
    lines += _assign(["t1"], [x1 + h * sp.diff(F3, x2)], {x1: S("x1"), x2: S("t2"), x3: S("t3")}, "c")
    lines += ["X1 = t1;", "X2 = t2;", "X3 = t3;"]
    return lines


def _newton_c(var: str, z0: str, g: list[str], dg: list[str], opts: dict, tag: str) -> list[str]:
    """newton_scalar (vpforms._newton) in C: same step, stopping rule, twist and divergence tests,
    and the final Newton step; ``g``/``dg`` are statements defining ``{tag}_g``/``{tag}_dg`` of z."""
    tol, mi, tw = float(opts["tol"]), int(opts["max_iter"]), float(opts["twist_tol"])
    body = "\n        ".join(g + dg)
    return [
        f"double {var}, {tag}_z = {z0}, {tag}_z0 = {z0}; int {tag}_st = -1;",
        f"double {tag}_far = 1e8 * (1.0 + fabs({tag}_z0));",
        f"for (int it = 0; it < {mi} && {tag}_st == -1; it++) {{",
        f"    double z = {tag}_z;",
        f"    {{\n        {body}",
        f"    int tw = !(fabs({tag}_dg) > {tw!r});",
        f"    double step = {tag}_g / (tw ? 1.0 : {tag}_dg);",
        f"    double zn = z - step;",
        f"    int dv = !(fabs(zn) <= DBL_MAX) || fabs(zn - {tag}_z0) > {tag}_far;",
        f"    int cv = fabs(step) <= {tol!r} * (1.0 + fabs(zn));",
        f"    {tag}_st = tw ? {RESULTS.twist_failure} : dv ? {RESULTS.not_converged} : cv ? 0 : -1;",
        f"    {tag}_z = (tw || dv) ? z : zn;",
        "    }",
        "}",
        f"if ({tag}_st == -1) {tag}_st = {RESULTS.not_converged};",
        f"if ({tag}_st == 0) {{ double z = {tag}_z; {{\n        {body}",
        f"    {tag}_z = z - {tag}_g / {tag}_dg; }} }}",
        f"{var} = {tag}_z;",
    ]


def _sese_newton_body(m) -> list[str]:
    """SE+SE through the generating map (eq:volpot, representative case, sign −1), Euler guess:
    volpot1 X₃ + h∂₂F¹(x₁,x₂,X₃) − x₃ = 0; volpot2 X₂ + h∂₁F³(x₁,X₂,X₃) − x₂ − h∂₃F¹(x₁,x₂,X₃) = 0;
    volpot3 X₁ = x₁ + h∂₂F³(x₁,X₂,X₃)."""
    field = m.field
    x1, x2, x3 = field.symbols
    F1, F3 = (sp.sympify(e) for e in field.se_potential_exprs)
    h, z = sp.Symbol("h"), sp.Symbol("z")
    S = sp.Symbol
    X = {x1: S("x1"), x2: S("x2"), x3: S("x3")}
    lines = _assign(["g1", "g2", "g3"], list(field.exprs), X, "e")  # Euler guess x + h a(x)
    g1 = z + h * sp.diff(F1, x2) - x3
    lines += _newton_c("t3", "x3 + h*g3",
                       _assign(["n1_g"], [g1], {x1: S("x1"), x2: S("x2"), x3: z}, "p"),
                       _assign(["n1_dg"], [sp.diff(g1, z)], {x1: S("x1"), x2: S("x2"), x3: z}, "q"),
                       m.newton, "n1")
    g2 = z + h * sp.diff(F3, x1).xreplace({x2: z}) - x2 - h * sp.diff(F1, x3)
    sub2 = {x1: S("x1"), x2: S("x2"), x3: S("t3")}
    lines += _newton_c("t2", "x2 + h*g2", _assign(["n2_g"], [g2], sub2, "r"),
                       _assign(["n2_dg"], [sp.diff(g2, z)], sub2, "u"), m.newton, "n2")
    lines += _assign(["t1"], [x1 + h * sp.diff(F3, x2)], {x1: S("x1"), x2: S("t2"), x3: S("t3")}, "c")
    lines += ["X1 = t1;", "X2 = t2;", "X3 = t3;", "code = n1_st ? n1_st : n2_st;"]
    return lines


def _sese_adjoint_body(field) -> list[str]:
    """Ψ*_h = (Ψ_{−h})⁻¹: the three shears of Ψ_{−h} undone in reverse order (explicit here)."""
    x1, x2, x3 = field.symbols
    F1, F3 = (sp.sympify(e) for e in field.se_potential_exprs)
    h = sp.Symbol("h")
    S = sp.Symbol
    lines = []
    lines += _assign(["t1"], [x1 + h * sp.diff(F3, x2)], {x1: S("x1"), x2: S("x2"), x3: S("x3")}, "a")
    lines += _assign(["t2"], [x2 + h * sp.diff(F1, x3) - h * sp.diff(F3, x1)],
                     {x1: S("t1"), x2: S("x2"), x3: S("x3")}, "b")
    lines += _assign(["t3"], [x3 - h * sp.diff(F1, x2)], {x1: S("t1"), x2: S("t2"), x3: S("x3")}, "c")
    lines += ["X1 = t1;", "X2 = t2;", "X3 = t3;"]
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


def kernel_source(method: Any, engine: str = "auto") -> str:
    """The complete C source of ``vp_run`` for ``method`` (see :data:`CDEF`).

    ``engine="newton"`` forces the generic engine for an order-1 SE+SE step even where its shears
    are explicit (the same map; used to measure the engine against the closed form)."""
    from ..._integrate import RK4, describe

    why = unsupported_reason(method)
    if why:
        raise ValueError(why)
    m, stages = _plan(method)
    from ..._methods.se_se import _explicit_flags

    if isinstance(m, RK4):
        fwd = _rk4_body(m.field)
    elif all(_explicit_flags(m.field)) and not (engine == "newton" and stages == [("fwd", 1.0)]):
        fwd = _sese_body(m.field)
    else:
        fwd = _sese_newton_body(m)
    fns = _stage_fn("vp_fwd", fwd)
    if any(k == "adj" for k, _ in stages):
        fns += _stage_fn("vp_adj", _sese_adjoint_body(m.field))
    calls = "\n    ".join(
        f"c = vp_{k}(y1, y2, y3, {c!r} * h, &y1, &y2, &y3); code = code ? code : c;"
        for k, c in stages
    )
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
    {calls}
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

"""C from the stages of :mod:`.plan`: the generic map per lane, RK4, and the kernel ``vp_run``.

A :class:`~.potentials.MapStage` becomes a function that does what :mod:`vpforms._map` does for one
point: y = x·σ, the Euler guess, the scalar solve of volpot1 for Y₃ then of volpot2 for Y₂ (the
rules of :func:`vpforms._newton.newton_scalar`: step, stopping test, twist, divergence bound, the
same root; status ``not_converged``/``twist_failure``), Y₁ from volpot3, X = Y·Σ⁻¹, and the
non-finite status. A solve whose equation is affine in its unknown (g' free of it: e.g. the SE+SE
shears of ABC) is emitted in closed form z = −g(0)/g' with the same twist test — the root Newton
converges to; ``engine="newton"`` forces the iteration everywhere (tests, benchmark). A
:class:`~.potentials.CorrectionStage` (Quispel's correction map) is its three scalar equations in
sequence, solved by the same emitter.

Every stage is emitted twice: an exact version (early-exit Newton, the status) and a vectorised
one (``FIXED_ITERS`` masked iterations, a success flag). The kernel runs the vectorised step on all
lanes and redoes with the exact one only the lanes it did not decide as successes, so statuses
and results are those of the exact code while gcc vectorises the common path (an early-exit loop
inside ``#pragma omp simd`` would not be).

Quadrature potentials (:class:`vpforms._quadrature.GLSum`, Gauss–Legendre sums of an integrand
over the nodes tᵢ) become C loops over a static table of the nodes and weights of
:func:`vpforms._quadrature._nodes_weights` (:func:`_gl_loops`): the sums one statement group needs
(g and g' of a Newton iteration: the potential's derivatives, each the rule applied to the
differentiated integrand) share one loop and one cse. gcc vectorises these node loops rather than
the lane loop, so such a kernel has no vectorised pass: every lane takes the exact step.

The kernel: particles in blocks of ``BLOCK`` lanes held as structure-of-arrays in L1 for all steps
of a segment; OpenMP over blocks; ``#pragma omp simd`` over lanes so gcc calls libmvec's sin/cos.
A lane whose step fails is frozen with its status and its step index kept.
"""

from __future__ import annotations

import re
from typing import Any

import sympy as sp

from ...._errors import RESULTS
from ...._guard import FLOOR as GUARD_FLOOR
from ...._methods._base import Method
from ...._solution import describe
from ....symbolic import _symbols as G
from . import coils, data, entries, ring, splines
from .assign import _C, _assign, _gl_table
from .cprinter import printer as _printer
from .lanes import lane_code
from .plan import plan
from .potentials import (
    CORR_C,
    CORR_S,
    DL_QPC,
    CorrectionStage,
    DLStage,
    MapStage,
    RK4Stage,
    ThetaStage,
    field_exprs,
    field_reason,
)
from .entries import RUN_CDEF, run_entry
from .sections import sections_entry
from .walls import speed_fn, wall_entry

__all__ = ["BLOCK", "CDEF", "kernel_parts", "kernel_source"]

BLOCK = 64
#: Newton iterations of the vectorised pass (see :func:`_newton_fixed_c`); only speed depends on it
FIXED_ITERS = 5
CDEF = RUN_CDEF


#: glibc declares libmvec's vector variants only under __FAST_MATH__, which -fno-finite-math-only
#: turns off; re-declare them (glibc ≥ 2.22 has these five) so gcc still vectorises the calls.
_SIMD_DECLS = "".join(
    f'__attribute__((__simd__("notinbranch"))) double {f}(double{", double" if f == "pow" else ""});\n'
    for f in ("sin", "cos", "exp", "log", "pow")
)

def _newton_c(var: str, z0: str, g_dg: list[str], opts: tuple, tag: str) -> list[str]:
    """newton_scalar (vpforms._newton) in C: same step, stopping rule, twist and divergence tests,
    and the same root (newton_scalar's final step carries the derivative only, which a kernel does
    not need); ``g_dg`` are statements defining ``{tag}_g``/``{tag}_dg`` of z.
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
        f"double {var} = {tag}_z;",
    ]


def _newton_fixed_c(var: str, z0: str, g_dg: list[str], opts: tuple, tag: str) -> list[str]:
    """The vectorised pass of :func:`_newton_c`: its first ``FIXED_ITERS`` iterations unrolled and
    masked, the state kept in doubles (so that gcc if-converts every select), and ``{tag}_ok`` =
    1.0 only if the solve converged in them. Anything else (a failure, or a lane still iterating)
    sends the lane's whole step to the exact early-exit code (``vp_step_exact``): statuses and
    iterations are always those of :func:`_newton_c`; only speed depends on ``FIXED_ITERS``."""
    tol, mi, tw = opts
    body = "\n    ".join(g_dg)
    it = [
        f"{{ double z = {tag}_z;",
        f"    {body}",
        f"    double tw = !(fabs({tag}_dg) > {tw!r}) ? 1.0 : 0.0;",
        f"    double step = {tag}_g / (tw > 0.5 ? 1.0 : {tag}_dg);",
        "    double zn = z - step;",
        f"    double dv = (!(fabs(zn) <= DBL_MAX) | (fabs(zn - {tag}_z0) > {tag}_far)) ? 1.0 : 0.0;",
        f"    double cv = fabs(step) <= {tol!r} * (1.0 + fabs(zn)) ? 1.0 : 0.0;",
        "    double fail = tw > dv ? tw : dv;",  # fmax does not vectorise (NaN semantics)
        f"    {tag}_z = {tag}_run * (1.0 - fail) > 0.5 ? zn : {tag}_z;",
        f"    {tag}_bad = {tag}_bad + {tag}_run * fail;",  # fails at most once
        f"    {tag}_run = {tag}_run * (1.0 - fail) * (1.0 - cv); }}",
    ]
    lines = [
        f"double {tag}_z = {z0}, {tag}_z0 = {tag}_z, {tag}_run = 1.0, {tag}_bad = 0.0;",
        f"double {tag}_far = 1e8 * (1.0 + fabs({tag}_z0));",
    ]
    for _ in range(min(FIXED_ITERS, mi)):
        lines += it
    lines += [
        f"double {tag}_ok = (1.0 - {tag}_bad) * (1.0 - {tag}_run);",
        f"double {var} = {tag}_z;",
    ]
    return lines


def _solve_c(var: str, g: sp.Expr, subs: dict, guess: str, opts: tuple, tag: str,
             newton: bool, fixed: bool, later: tuple | None = None) -> list[str]:
    """Solve g(z) = 0 for ``var`` (z = the symbol _C["z"] after ``subs``); defines the status
    ``int {tag}_st``, or with ``fixed`` (the vectorised pass, :func:`_newton_fixed_c`) the
    success flag ``double {tag}_ok``. ``later``: what is evaluated at the root after the solve
    (:func:`.splines.hoist`)."""
    g = sp.sympify(g).xreplace(subs)
    z = _C["z"]
    dg = sp.diff(g, z)
    if newton or z in dg.free_symbols:
        emit = _newton_fixed_c if fixed else _newton_c
        # spline axes whose argument does not move with z: evaluated once, before the iterations
        pre = splines.hoist([g, dg], z, _printer, later) + coils.hoist([g, dg], z, _printer)
        with data.scope():  # the iteration's body is a C block
            body = _assign([f"{tag}_g", f"{tag}_dg"], [g, dg], {}, f"{tag}c")
        return pre + emit(var, guess, body, opts, tag)
    # affine in z: the root Newton converges to, in closed form; the same twist test on g' = const
    lines = _assign([f"{tag}_g0", f"{tag}_dg"], [g.xreplace({z: 0}), dg], {}, f"{tag}c")
    lines.append(f"double {var} = -{tag}_g0 / {tag}_dg;")
    if dg.is_Number and abs(float(dg)) > opts[2]:
        lines.append(f"double {tag}_ok = 1.0;" if fixed else f"int {tag}_st = 0;")
    elif fixed:
        lines.append(f"double {tag}_ok = fabs({tag}_dg) > {opts[2]!r} ? 1.0 : 0.0;")
    else:
        lines.append(f"int {tag}_st = !(fabs({tag}_dg) > {opts[2]!r}) ? {RESULTS.twist_failure} : 0;")
    return lines


def _map_body(st: MapStage, newton: bool, fixed: bool) -> list[str]:
    """((σ,Σ)·f^s_{φ,Φ})(x) on one lane, as vpforms._map._solve_point (see the module docstring)."""
    Y3, Y2, y1, y2, y3, h = G.Y[2], G.Y[1], G.y[0], G.y[1], G.y[2], G.h
    c = _C
    sig, Sig, Sinv = st.case.sigma.index, st.case.Sigma.index, st.case.Sigma.inverse().index
    # y = x·σ, printed as the x it is: an atom at (y₃, y₂, ·) shares the cells and bases of a(x)
    lines = []
    base = {y1: c[f"x{sig[0] + 1}"], y2: c[f"x{sig[1] + 1}"], y3: c[f"x{sig[2] + 1}"], h: c["h"]}
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
    # a(x): the components the guesses need; in the exact pass all three, written to ga where the
    # caller asks (the guard's predictor, for the first stage: one evaluation of a(x) per step)
    comps = sorted(set(need.values()))
    # on a spline field a(x) is a whole 3-D contraction per stage (216 products at degree 5), which
    # the Euler guess costs: the exact pass evaluates a(x) once per step, in the first stage (gnew),
    # and every stage starts from x + h a(x₀) with the step's x₀ (a guess off by O(h·h_step), in
    # the root's cell more often than x: on W7-X's φ-time K the block contractions per stage went
    # 1.29 → 1.02, Newton iterations per solve 3.0–3.1 → 2.9–3.0), or from x where the kernel passes
    # no a (ga NULL)
    start = not fixed and any(sp.sympify(e).has(splines.SplineAt) for e in st.field_exprs)
    if start:
        comps = []
    if not fixed and comps:
        lines += _assign([f"ga{i + 1}" for i in range(3)], list(st.field_exprs), xs, "ge")
        lines.append("if (ga && gnew) { ga[0] = ga1; ga[1] = ga2; ga[2] = ga3; }")
    elif not fixed:
        with data.scope():  # a C block
            own = _assign([f"ga{i + 1}" for i in range(3)], list(st.field_exprs), xs, "ge")
        lines += ["if (ga && gnew) {", *(f"    {ln}" for ln in own), "    ga[0] = ga1; ga[1] = ga2; ga[2] = ga3;", "}"]
    elif comps:
        lines += _assign([f"ga{i + 1}" for i in comps], [st.field_exprs[i] for i in comps], xs, "ge")
    guess = {k: (f"(ga ? x{i + 1} + h*ga[{i}] : x{i + 1})" if start else f"x{i + 1} + h*ga{i + 1}")
             if k in need else "0.0"
             for k, i in ((2, Sig[2]), (1, Sig[1]))}
    # evaluated at the roots: g₂'s terms at Y₃ (the second solve's constants), volpot3 at (Y₃, Y₂)
    at_roots = {**base, Y3: c["Y3"], Y2: c["Y2"]}
    v3 = d2Phi.xreplace(at_roots)
    lines += _solve_c("Y3", g1, {**base, Y3: c["z"]}, guess[2], st.newton, "n1", newton, fixed,
                      ([g2.xreplace(at_roots), v3], c["Y3"], {c["Y2"]}))
    lines += _solve_c("Y2", g2, {**base, Y3: c["Y3"], Y2: c["z"]}, guess[1], st.newton, "n2",
                      newton, fixed, ([v3], c["Y2"], set()))
    lines += _assign(["Y1"], [d2Phi], {**base, Y3: c["Y3"], Y2: c["Y2"]}, "v3")  # volpot3
    lines += [f"X{i + 1} = Y{Sinv[i] + 1};" for i in range(3)]  # X = Y·Σ⁻¹
    if fixed:  # success flag only: finite input and output, both solves converged
        fin = "_VP_FINITE(x1, x2, x3) && _VP_FINITE(X1, X2, X3)"
        return lines + [f"ok = n1_ok * n2_ok * ({fin} ? 1.0 : 0.0);"]
    return lines + [
        "int inok = _VP_FINITE(x1, x2, x3), fin = _VP_FINITE(X1, X2, X3);",
        "code = n1_st ? n1_st : n2_st;",
        f"code = !inok ? {RESULTS.nonfinite} : (code == 0 && !fin) ? {RESULTS.nonfinite} : code;",
    ]


def _correction_body(st: CorrectionStage, newton: bool, fixed: bool) -> list[str]:
    """Quispel's correction map on one lane, as QuispelCorrection._forward/_backward: with roles
    (i, j, k), forward: c = h a_j(x_i, c, x_k) (guess 0), then X_j from
    X_j − x_j − h a_j(x_i, X_j, x_k) + f_c(x_i, X_j, x_k) = 0 (guess x_j + h a_j(x)), then X_i, X_k
    explicit; inverse: x_k, x_i by Newton, c, then x_j explicit. h is ``hsign``·h; the lane is
    conjugated by π (y = x·π, X = Y·π⁻¹)."""
    S = sp.Symbol
    i, j, k = st.roles
    pi = st.pi.index if st.pi is not None else (0, 1, 2)
    pinv = st.pi.inverse().index if st.pi is not None else (0, 1, 2)
    hh = S("hh")
    lines = [f"double v{m + 1} = x{pi[m] + 1};" for m in range(3)]  # v = x·π
    lines.append(f"double hh = {st.hsign} * h;")
    a = [sp.sympify(e).xreplace({G.h: hh}) for e in st.a]
    fc = sp.sympify(st.fc).xreplace({G.h: hh})

    def at(comp, vi, vj, vk):  # a_comp at the point with slots (i, j, k) = (vi, vj, vk)
        return a[comp].xreplace({G.x[i]: vi, G.x[j]: vj, G.x[k]: vk})

    def Fc(vi, u, vk):  # f_c(x_i, u, x_k) = ∫_c^u w(s) ds, from the lower limit cc
        return fc.xreplace({G.x[i]: vi, CORR_S: u, G.x[k]: vk, CORR_C: S("cc")})

    z, vi, vj, vk = S("z"), S(f"v{i + 1}"), S(f"v{j + 1}"), S(f"v{k + 1}")
    solves = []

    def solve(var, g, guess, tag):
        if guess != "0.0":
            lines.extend(_assign([f"{tag}_guess"], [guess], {}, f"{tag}i"))
            guess = f"{tag}_guess"
        lines.extend(_solve_c(var, g, {}, guess, st.newton, tag, newton, fixed))
        solves.append(tag)

    if not st.inverse:
        solve("cc", S("z") - hh * at(j, vi, z, vk), "0.0", "n1")  # the lower limit c
        solve("uj", z - vj - hh * at(j, vi, z, vk) + Fc(vi, z, vk),
              vj + hh * at(j, vi, vj, vk), "n2")
        lines += _assign(["ui"], [vi + hh * at(i, vi, S("uj"), vk)], {}, "ei")
        lines += _assign(["uk"], [vk + hh * at(k, S("ui"), S("uj"), vk)], {}, "ek")
    else:  # vi, vj, vk are X_i, X_j, X_k
        solve("uk", z + hh * at(k, vi, vj, z) - vk, vk - hh * at(k, vi, vj, vk), "n1")
        solve("ui", z + hh * at(i, z, vj, S("uk")) - vi, vi - hh * at(i, vi, vj, S("uk")), "n2")
        solve("cc", z - hh * at(j, S("ui"), z, S("uk")), "0.0", "n3")
        lines += _assign(["uj"], [vj - hh * at(j, S("ui"), vj, S("uk"))
                                  + Fc(S("ui"), vj, S("uk"))], {}, "ej")
    out = {i: "ui", j: "uj", k: "uk"}
    lines += [f"double Y{m + 1} = {out[m]};" for m in range(3)]
    lines += [f"X{m + 1} = Y{pinv[m] + 1};" for m in range(3)]  # X = Y·π⁻¹
    if fixed:
        oks = " * ".join(f"{t}_ok" for t in solves)
        return lines + [f"ok = {oks} * (_VP_FINITE(X1, X2, X3) ? 1.0 : 0.0);"]
    sts = [f"{t}_st" for t in solves]
    merged = sts[-1]
    for t in reversed(sts[:-1]):
        merged = f"({t} ? {t} : {merged})"
    return lines + [f"code = {merged};",
                    f"code = (code == 0 && !_VP_FINITE(X1, X2, X3)) ? {RESULTS.nonfinite} : code;"]


def _theta_c(st: ThetaStage, w: tuple[str, str, str], tag: str, newton: bool,
             fixed: bool) -> list[str]:
    """One θ-stage as ``dl_stage`` computes it: q₁ by Newton on g_q(q₁) = q₁ − q₀ − h∂_pH(q_θ, p̄(q₁))
    from q₀ + h∂_pH(q₀, p₀), where every evaluation solves p̄(q₁) (inner, from p₀, its status
    ignored) of g_p(p̄) = p̄ − p₀ + h(1−θ)∂_qH(q_θ, p̄), and dg_q/dq₁ carries the implicit-function
    derivative dp̄/dq₁ = −∂_{q₁}g_p/∂_p̄ g_p (what autodiff through ``newton_scalar`` gives); then
    p̄ at the root (its status kept) and p₁ = p̄ − hθ∂_qH(q_θ, p̄). ``w`` = C names of (q₀, p₀, c);
    they receive (q₁, p₁). Defines ``{tag}_st`` (exact) or ``{tag}_ok`` (vectorised pass: outer,
    final and every inner solve decided within the fixed iterations)."""
    S = sp.Symbol
    q, p, c = DL_QPC
    q0, p0, cc, h, z = S(w[0]), S(w[1]), S(w[2]), _C["h"], _C["z"]
    q1, pb = S(f"{tag}_q1"), S(f"{tag}_pb")
    th = sp.Rational(st.theta)  # exact: θ = 0 drops its terms, as 0.0·(…) does in JAX
    Hq, Hp = sp.diff(st.H, q), sp.diff(st.H, p)
    at = {q: q0 + th * (q1 - q0), p: pb, c: cc}
    gp = pb - p0 + h * (1 - th) * Hq.xreplace(at)
    gq = q1 - q0 - h * Hp.xreplace(at)
    dgq = sp.diff(gq, q1) - sp.diff(gq, pb) * sp.diff(gp, q1) / sp.diff(gp, pb)

    def inner(t):  # p̄ at q₁ = {tag}_q1: defines {tag}_pb and {t}_st / {t}_ok
        return _solve_c(f"{tag}_pb", gp, {pb: z}, w[1], st.newton, t, newton, fixed)

    lines = _assign([f"{tag}_guess"], [q0 + h * Hp.xreplace({q: q0, p: p0, c: cc})], {}, f"{tag}gc")
    if q1 not in gp.free_symbols:  # θ = 0 or 1: p̄ does not depend on q₁ (symplectic Euler) — solve
        # it once (every inner solve of dl_stage gives this same p̄), then g_q is explicit in q₁
        lines += inner(f"{tag}f")
        lines += _solve_c(f"{tag}_Q1", gq, {q1: z}, f"{tag}_guess", st.newton, f"{tag}o",
                          newton, fixed)
        lines += [f"double {tag}_q1 = {tag}_Q1;"] + ([f"double {tag}_okin = 1.0;"] if fixed else [])
    else:
        with data.scope():  # the outer iteration's body is a C block
            body = [f"double {tag}_q1 = z;", *inner(f"{tag}i")]
            body += [f"{tag}_okin = {tag}_okin * {tag}i_ok;"] if fixed else []
            body += _assign([f"{tag}o_g", f"{tag}o_dg"], [gq, dgq], {}, f"{tag}oc")
        lines += [f"double {tag}_okin = 1.0;"] if fixed else []
        lines += (_newton_fixed_c if fixed else _newton_c)(f"{tag}_Q1", f"{tag}_guess", body,
                                                            st.newton, f"{tag}o")
        lines += [f"double {tag}_q1 = {tag}_Q1;", *inner(f"{tag}f")]
    lines += _assign([f"{tag}_P1"], [pb - h * th * Hq.xreplace(at)], {}, f"{tag}pc")
    lines += [f"{w[0]} = {tag}_Q1; {w[1]} = {tag}_P1;"]
    if fixed:
        return lines + [f"double {tag}_ok = {tag}o_ok * {tag}f_ok * {tag}_okin;"]
    return lines + [f"int {tag}_st = {tag}o_st ? {tag}o_st : {tag}f_st;"]


def _dl_body(st: DLStage, newton: bool, fixed: bool) -> list[str]:
    """A DL step as ``DLPredictor._stages``: its θ-stages in sequence on a working copy of x, the
    status ``merge_status(s₁, s₂, finite(X))``."""
    lines = ["double w1 = x1, w2 = x2, w3 = x3;"]
    tags = [f"t{k}" for k in range(len(st.stages))]
    for ts, t in zip(st.stages, tags):
        with data.scope():  # a stage reassigns w: nothing evaluated at w before it is reused
            lines += _theta_c(ts, tuple(f"w{i + 1}" for i in ts.idx), t, newton, fixed)
    lines.append("X1 = w1; X2 = w2; X3 = w3;")
    if fixed:
        return lines + [(f"ok = {' * '.join(f'{t}_ok' for t in tags)} * "
                         "(_VP_FINITE(X1, X2, X3) ? 1.0 : 0.0);")]
    merged = f"{tags[-1]}_st"
    for t in reversed(tags[:-1]):
        merged = f"({t}_st ? {t}_st : {merged})"
    return lines + [f"code = {merged};",
                    f"code = (code == 0 && !_VP_FINITE(X1, X2, X3)) ? {RESULTS.nonfinite} : code;"]


def _rk4_body(field) -> list[str]:
    s = G.x
    a = list(field_exprs(field))
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


def _stage_fn(name: str, body: list[str], fixed: bool) -> str:
    """A stage: the exact one returns its status ``code``; the vectorised pass (``fixed``) its
    success flag ``ok`` (1.0: converged, finite; anything else is redone exactly). Its linkage is
    ``_VP_STAGE`` (:func:`_kernel`: inlined, or compiled once and called). ``ga``: the field a at
    the step's start, written there by the stage with ``gnew`` (the first: for the guard and the
    later stages' guesses on a spline field), read by the others; NULL where the caller has none."""
    step = "\n    ".join(body)
    ret, init = ("double", "double ok = 1.0;") if fixed else ("int", "int code = 0;")
    return f"""static _VP_STAGE {ret} {name}(double x1, double x2, double x3, double h,
                           double *restrict o1, double *restrict o2, double *restrict o3,
                           const double *restrict fd, double *restrict ga, int gnew) {{
    double X1, X2, X3; {init}
    {step}
    *o1 = X1; *o2 = X2; *o3 = X3;
    return {"ok" if fixed else "code"};
}}
"""


def _stage_body(stage: Any, newton: bool, fixed: bool) -> list[str]:
    if isinstance(stage, RK4Stage):  # explicit: the kernel's finiteness test is its status
        return _rk4_body(stage.field) + (["ok = _VP_FINITE(X1, X2, X3) ? 1.0 : 0.0;"] if fixed else [])
    if isinstance(stage, CorrectionStage):
        return _correction_body(stage, newton, fixed)
    if isinstance(stage, DLStage):
        return _dl_body(stage, newton, fixed)
    return _map_body(stage, newton, fixed)


def _guard_c(field: Any, kappa: float | None, fixed: bool,
             given: bool = False) -> tuple[list[str], list[str]]:
    """The consistency guard of :mod:`vpforms._guard` in C, and the domain test of a gridded
    field (``Method._accept``: a failed step whose Euler point is off the grid or not finite
    ``left_domain``): (lines at the step's start: the predictor E = x + h a(x); lines at its end:
    the tests on the result y). Empty without either. ``given``: a(x) is read from ``gd_ax``,
    which the first stage wrote (the lines then follow the stages, :func:`_step_fn`)."""
    box = splines.domain_test(field) if field is not None else []
    if field is None or (kappa is None and not box) or field_reason(field) is not None:
        return [], []
    xs = {G.x[i]: _C[f"x{i + 1}"] for i in range(3)}
    pre = ([f"double gd_a{i + 1} = gd_ax[{i}];" for i in range(3)] if given else
           _assign([f"gd_a{i + 1}" for i in range(3)], list(field_exprs(field)), xs, "gd"))
    pre += [f"double gd_e{i} = x{i} + h*gd_a{i};" for i in (1, 2, 3)]
    out = []
    if box and not fixed:  # a success is never changed by it: the vectorised pass needs nothing
        tests = " && ".join(f"gd_e{a + 1} >= {_data(lo)} && gd_e{a + 1} <= {_data(hi)}"
                            for a, lo, hi in box)
        out = [f"int gd_in = _VP_FINITE(gd_e1, gd_e2, gd_e3) && {tests};",
               f"code = (code == 0 && !_VP_FINITE(y1, y2, y3)) ? {RESULTS.nonfinite} : code;",
               f"code = (code != 0 && !gd_in) ? {RESULTS.left_domain} : code;"]
    if kappa is None:
        return pre, out

    def mx(a, b, c):  # max without fmax (which does not vectorise: NaN semantics)
        return f"({a} > {b} ? ({a} > {c} ? {a} : {c}) : ({b} > {c} ? {b} : {c}))"

    d = [f"gd_d{i}" for i in (1, 2, 3)]
    post = [f"double gd_d{i} = fabs(y{i} - gd_e{i}), gd_s{i} = fabs(gd_e{i} - x{i}), "
            f"gd_x{i} = fabs(x{i});" for i in (1, 2, 3)]
    post += [
        f"double gd_def = {mx(*d)};",
        (f"double gd_bound = {float(kappa)!r} * {mx('gd_s1', 'gd_s2', 'gd_s3')} + "
         f"{float(GUARD_FLOOR)!r} * DBL_EPSILON * (1.0 + {mx('gd_x1', 'gd_x2', 'gd_x3')});"),
    ]
    # the vectorised pass keeps its state in doubles (gcc if-converts, see _newton_fixed_c): a lane
    # that misses the bound (or is not finite) is redone by the exact pass, which gives the status
    post += (["ok = ok * ((gd_def <= gd_bound) ? 1.0 : 0.0);"] if fixed else
             ["int gd_bad = !(gd_def <= gd_bound) & _VP_FINITE(y1, y2, y3);",
              f"code = (code == 0 && gd_bad) ? {RESULTS.inconsistent} : code;"])
    return pre, post + out


def _same(a: tuple, b: tuple) -> bool:
    """Whether two field expressions are the same SymPy expressions (so the same a(x))."""
    return len(a) == len(b) and all(sp.sympify(u) == sp.sympify(v) for u, v in zip(a, b))


def _data(ref) -> str:
    """A data scalar (:class:`.data.DataRef`) as C: its read of the data array."""
    return _printer.doprint(data.e_sub(ref))


def _step_fn(name: str, calls: list[str], fixed: bool, guard=([], []), given: bool = False) -> str:
    """One step: the stages' ``calls``, the guard's lines (:func:`_guard_c`: its predictor before
    the stages, or after them where the first stage gives a(x), ``given``; its tests after)."""
    body = "\n    ".join([*calls, *guard[0], *guard[1]] if given else [*guard[0], *calls, *guard[1]])
    init = "double ok = 1.0;" if fixed else "int code = 0, c;"
    return f"""static _VP_STAGE {"double" if fixed else "int"} {name}(double x1, double x2, double x3, double h,
                          double *restrict o1, double *restrict o2, double *restrict o3,
                          const double *restrict fd) {{
    double y1 = x1, y2 = x2, y3 = x3; {init}
    {body}
    *o1 = y1; *o2 = y2; *o3 = y3;
    return {"ok" if fixed else "code"};
}}
"""


#: how the stages and the step are compiled (``_VP_STAGE``), by whether the kernel has a vectorised pass
_STAGE_LINKAGE = {
    True: "/* every stage inlined into the lane loop, however many (a call there blocks vectorisation) */\n"
          "#define _VP_STAGE inline _VP_INLINE\n",
    # no vectorised pass (splines, coils, quadratures: lanes step one at a time, a call costs
    # nothing next to a stage): each stage is compiled once and called. Inlined into each of an
    # order-4 composition's 10 calls and each entry's call sites, gcc took minutes (issue #41).
    False: "/* no vectorised pass: each stage and the step compiled once, and called */\n"
           "#define _VP_STAGE __attribute__((noinline))\n",
}

#: the vectorised pass of a kernel on quadrature potentials: it decides no lane (see kernel_source)
_FAST_NONE = """static inline _VP_INLINE double vp_step_fast(double x1, double x2, double x3, double h,
                          double *restrict o1, double *restrict o2, double *restrict o3,
                          const double *restrict fd) {
    *o1 = x1; *o2 = x2; *o3 = x3;
    return 0.0;
}
"""


def kernel_source(method: Any, engine: str = "auto", entry: str = "run") -> str:
    """The complete C source of ``vp_run`` for ``method`` (see :data:`CDEF`); with
    ``entry="sections"`` of ``vp_sections`` instead (:mod:`.sections`, :data:`.sections.SECTIONS_CDEF`:
    the same steps, recording the crossings of a section surface). See :func:`kernel_parts`."""
    return kernel_parts(method, engine, entry)[0]


def kernel_parts(method: Any, engine: str = "auto", entry: str = "run") -> tuple[str, Any]:
    """(the C source of ``vp_run`` — or, with ``entry="sections"``, of ``vp_sections``; with
    ``entry="wall"``, of ``vp_wall`` (:mod:`.walls`) — for ``method``, its run-time data ``fd``:
    the flat array of :func:`.data.field_data`, or None for a field without data).

    A kernel without a vectorised pass (splines, coils, quadratures: the stages are compiled once
    and called) defines every entry the method allows in one source, whichever is asked for
    (:mod:`.entries`; :func:`.entries.entries_cdef` declares them).

    ``engine="newton"`` iterates Newton on every solve, also where the equation is affine in its
    unknown (the same map; used to measure the engine against the closed form).

    Each step runs first as ``vp_step_fast`` (vectorised over the lanes of a block: closed-form
    solves and ``FIXED_ITERS`` masked Newton iterations); a lane it does not decide as a success
    (a failure, or a solve still iterating) is redone by ``vp_step_exact`` (scalar, the early-exit
    solves of :func:`vpforms._newton.newton_scalar`), which gives it its exact status."""
    if engine not in ("auto", "newton"):
        raise ValueError(f"engine must be 'auto' or 'newton', got {engine!r}")
    if entry not in ("run", "sections", "wall"):
        raise ValueError(f"entry must be 'run', 'sections' or 'wall', got {entry!r}")
    with data.collecting() as refs:
        source = _kernel(method, engine, entry)
    return source, data.field_data(refs)


def _wall_c(method: Any, lanes: dict[str, str]) -> str:
    """``vp_wall`` (:mod:`.walls`) for ``method``: its field's |B| in C and the entry."""
    field = getattr(method, "field", None)
    why = "the method has no field" if field is None else field_reason(field)
    if why is not None:
        raise ValueError(f"no native wall tracing: {why}")
    return wall_entry(lanes, speed_fn(field, field_exprs))


def _kernel(method: Any, engine: str, entry: str) -> str:
    stages = plan(method)
    if isinstance(stages, str):
        raise ValueError(stages)  # noqa: TRY004 - a method that cannot be generated
    # the guard of the JAX step and the domain test of a gridded field (left_domain), both of
    # Method._accept, on every vpforms method; RK4 has neither
    field = getattr(method, "field", None) if isinstance(method, Method) else None
    kappa = getattr(method, "guard_kappa", None) if isinstance(method, Method) else None
    fns, steps = {}, {}
    vectorised = True  # whether the kernel has a vectorised pass (see below)
    for kind, fixed in (("exact", False), ("fast", True)):
        if fixed and any(s in fns["exact"] + steps["exact"] for s in ("VP_GL_", "vp_cell(", "vp_coils")):
            # quadrature potentials: gcc vectorises the loops over the nodes, not the lane loop
            # around them, so masked fixed iterations would only add work — every lane takes the
            # exact early-exit step (measured 1.4× faster than FIXED_ITERS = 5 on ∇×(sin x₂x₃, …));
            # splines: gathers at data-dependent cells and a binary search, not vectorised either
            fns[kind], steps[kind] = "", _FAST_NONE
            vectorised = False
            continue
        # the first stage starts at x and evaluates a(x) there: in the exact pass the guard reads
        # it from that stage (the vectorised pass evaluates its own; gcc merges what it can)
        given = (not fixed and isinstance(stages[0][0], MapStage) and field is not None
                 and _same(stages[0][0].field_exprs, field_exprs(field)))
        with data.scope(function=True):
            guard = _guard_c(field, kappa, fixed, given)
        names: dict[str, str] = {}  # body → function name (stages with the same map share one)
        # a(x₀) of the first stage also for the others' guesses where they are on its field
        share = given and all(not isinstance(s, MapStage) or _same(s.field_exprs, stages[0][0].field_exprs)
                              for s, _ in stages)
        first = given and (guard[0] or share)
        calls = ["double gd_ax[3];"] if first else []
        for k, (stage, coef) in enumerate(stages):
            with data.scope(function=True):
                body = "\n".join(_stage_body(stage, engine == "newton", fixed))
            fn = names.setdefault(body, f"vp_{kind}{len(names)}")
            ga = "gd_ax, 1" if k == 0 and first else "gd_ax, 0" if share else "0, 0"
            call = f"{fn}(y1, y2, y3, {coef!r} * h, &y1, &y2, &y3, fd, {ga});"
            calls.append(f"ok *= {call}" if fixed else f"c = {call} code = code ? code : c;")
        fns[kind] = "".join(_stage_fn(fn, body.split("\n"), fixed) for body, fn in names.items())
        steps[kind] = _step_fn(f"vp_step_{kind}", calls, fixed, guard, given)
    fns, steps = fns["fast"] + fns["exact"], steps["fast"] + steps["exact"]
    lanes = lane_code()
    # the Gauss–Legendre rules the quadrature potentials loop over (_gl_loops)
    tables = "".join(_gl_table(n) for n in sorted({int(k) for k in re.findall(r"VP_GL_T(\d+)\[", fns)}))
    # the entry asked for; without a vectorised pass every entry the method allows (.entries)
    tails = []
    for e in ((entry,) if vectorised or not entries.ONE_OBJECT else ("run", "sections", "wall")):
        try:
            tails.append(sections_entry(lanes) if e == "sections" else _wall_c(method, lanes) if e == "wall"
                         else run_entry(lanes))
        except ValueError:  # no wall tracing for this method: an error only where it was asked for
            if e == entry:
                raise
    tail = "".join(tails)
    # helpers the stages and the entry call (the coils' segment loops, :mod:`.coils`)
    helpers = "".join(code for _, code in data.emission().helpers.values())
    return f"""
#include <math.h>
#include <stdint.h>
#include <float.h>
#define B {BLOCK}
#define _VP_INLINE __attribute__((always_inline))
#ifdef _OPENMP
#include <omp.h>
#endif
/* lanes per block: B, or fewer, so that a few lanes (20 field lines) still fill every thread
   (each lane's steps are its own: the answers do not depend on the blocks) */
static inline int64_t vp_block(int64_t N) {{
#ifdef _OPENMP
    int64_t t = omp_get_max_threads();
#else
    int64_t t = 1;
#endif
    int64_t per = (N + t - 1) / (t > 0 ? t : 1);
    return per < 1 ? 1 : per < B ? per : B;
}}
{_STAGE_LINKAGE[vectorised]}/* finite test that survives -ffast-math: NaN fails every comparison */
#define _VP_FINITE(a, b, c) ((fabs(a) <= DBL_MAX) & (fabs(b) <= DBL_MAX) & (fabs(c) <= DBL_MAX))
{_SIMD_DECLS}
{splines.C_HELPERS if "vp_cell(" in fns + steps else ""}{ring.C_HELPERS if "vp_ellip" in fns + steps else ""}
{tables}
{helpers}
{fns}
/* one step of {describe(method)}: {len(stages)} stage(s), generated from SymPy */
{steps}
""" + tail

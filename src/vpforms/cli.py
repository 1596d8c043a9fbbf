"""The ``vpforms`` command line (argparse + rich).

Subcommands: ``cases``, ``classify``, ``run``, ``poincare``, ``order``, ``drift``, ``errata``,
``demo`` — each with ``--help``.  ``main(argv) -> int`` never raises for bad input: it prints one
line ``vpforms: error: …`` and returns 2 (usage) or 1 (a failed computation).  Set
``VPFORMS_DEBUG=1`` to get the traceback instead.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from typing import Any

__all__ = ["main", "build_parser"]


class CLIError(Exception):
    """A bad argument or an unavailable feature: reported as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + message
        raise CLIError(f"{message} (see '{self.prog} --help')")


# --------------------------------------------------------------------------------------------
# Parsing helpers
# --------------------------------------------------------------------------------------------
def _parse_perm(text: str):
    from ._perm import Perm

    digits = [c for c in text if c.isdigit()]
    if len(digits) != 3 or any(not c.isdigit() and c not in "(), " for c in text):
        raise CLIError(f"{text!r} is not a permutation of (1, 2, 3); write e.g. 321, 3,2,1 or (3,2,1)")
    try:
        return Perm(tuple(int(c) for c in digits))
    except (ValueError, TypeError) as exc:
        raise CLIError(f"{text!r} is not a permutation of (1, 2, 3): {exc}") from None


def _parse_value(text: str):
    """An int or float literal, else a SymPy expression such as sqrt(2/3)."""
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    import sympy as sp

    try:
        return sp.sympify(text)
    except (sp.SympifyError, SyntaxError, TypeError) as exc:
        raise CLIError(f"cannot read parameter value {text!r}: {exc}") from None


def _parse_params(items: list[str] | None) -> dict[str, Any]:
    out = {}
    for item in items or []:
        for part in item.split(","):
            if not part.strip():
                continue
            if "=" not in part:
                raise CLIError(f"parameter {part!r} must be NAME=VALUE, e.g. --param C=0")
            k, v = part.split("=", 1)
            out[k.strip()] = _parse_value(v.strip())
    return out


def _checked(convert, ok, must_be: str):
    """An argparse ``type``: convert the text, then require ``ok(value)`` (one-line errors)."""
    noun = "an integer" if convert is int else "a number"

    def parse(text: str):
        try:
            v = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {noun}") from None
        if not ok(v):
            raise argparse.ArgumentTypeError(f"{text!r} must be {must_be}")
        return v

    return parse


_positive_float = _checked(float, lambda v: v > 0 and math.isfinite(v), "a positive number")
_finite_float = _checked(float, math.isfinite, "a finite number")
_positive_int = _checked(int, lambda v: v >= 1, "a positive integer")


def _float_list(text: str) -> list[float]:
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers") from None
    if not vals or any(not (v > 0 and math.isfinite(v)) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r} must list positive numbers")
    return vals


# --------------------------------------------------------------------------------------------
# Problems and methods (the APIs of issues #4 and #5)
# --------------------------------------------------------------------------------------------
def _problem(args):
    try:
        from . import problems
    except ImportError as exc:  # pragma: no cover - only while issue #4 is missing
        raise CLIError(f"the problem library (vpforms.problems) is not available: {exc}") from None
    params = _parse_params(getattr(args, "param", None))
    try:
        return problems.get(args.problem, **params)
    except KeyError as exc:
        raise CLIError(str(exc.args[0] if exc.args else exc)) from None
    except TypeError as exc:
        raise CLIError(f"bad parameters for problem {args.problem!r}: {exc}") from None


_METHODS: dict = {}


def _method(field, cls: str = "SE+SE", case=None, order: int = 1, fast: bool = False, theta=None):
    """A vpforms method (class representative or explicit case, composed to ``order``) or RK4.

    Methods are cached per (field, options) so that repeated in-process calls (tests, the demo)
    reuse their compiled kernels.
    """
    key = (id(field), str(cls).strip().upper(), case, order, fast, theta)
    hit = _METHODS.get(key)
    if hit is not None and hit[0] is field:
        return hit[1]
    m = _make_method(field, cls, case, order, fast, theta)
    _METHODS[key] = (field, m)
    return m


def _make_method(field, cls, case, order, fast, theta):
    from ._integrate import RK4

    if str(cls).strip().lower() == "rk4":
        if order != 1 or case is not None:
            raise CLIError("rk4 is the explicit baseline: --case and --order do not apply")
        return RK4(field)
    try:
        from ._methods import compose, scheme
    except ImportError as exc:  # pragma: no cover - only while issue #5 is missing
        raise CLIError(f"the methods (vpforms.scheme) are not available yet: {exc}") from None
    opts = {}
    if fast:
        opts["fast"] = True
    if theta is not None:
        opts["theta"] = theta
    try:
        m = scheme(field, case if case is not None else cls, **opts)
    except ValueError as exc:  # unknown class, option that does not apply, bad θ: a usage error
        raise CLIError(str(exc)) from None
    if order == 1:
        return m
    if order not in (2, 4, 6):
        raise CLIError(f"--order must be 1, 2, 4 or 6, not {order}")
    return compose(m, order=order)


def _method_from_args(args, field):
    case = None
    if getattr(args, "case", None):
        from ._case import Case

        case = Case(_parse_perm(args.case[0]), _parse_perm(args.case[1]))
    return _method(field, args.method, case, args.order, args.fast, args.theta)


def _parse_method_spec(spec: str) -> tuple[str, int]:
    """'SE+SE' → (SE+SE, 1); 'SE+SE:4' → (SE+SE, 4); 'rk4' → (rk4, 1)."""
    name, _, order = spec.partition(":")
    try:
        return name.strip(), int(order) if order else 1
    except ValueError:
        raise CLIError(f"method spec {spec!r} must be CLASS or CLASS:ORDER, e.g. SE+SE:4 or rk4") from None


def _spec_label(name: str, order: int) -> str:
    if name.lower() == "rk4":
        return "RK4"
    return name.upper() if order == 1 else f"{name.upper()} ∘ order {order}"


# --------------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------------
def _cases_table():
    from rich.table import Table

    from ._case import cases

    table = Table(title="The 36 cases (σ, Σ) of eq:volpot and their classes")
    for col in ("#", "σ", "Σ", "τ = σ⁻¹∘Σ", "sgn τ", "class", "x₊ x∘ x₋", "X₊ X∘ X₋"):
        table.add_column(col)
    for n, c in enumerate(cases(), start=1):
        table.add_row(
            str(n),
            c.sigma.one_line(),
            c.Sigma.one_line(),
            f"{c.tau.one_line()} = {c.tau.cycle_notation()}",
            f"{c.sign:+d}",
            c.cls,
            f"x{c.x_plus} x{c.x_circ} x{c.x_minus}",
            f"X{c.X_plus} X{c.X_circ} X{c.X_minus}",
        )
    return table


def _cmd_cases(args, console) -> int:
    from collections import Counter

    from ._case import cases

    console.print(_cases_table())
    counts = Counter(c.cls for c in cases())
    console.print("class counts: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0


def _cmd_classify(args, console) -> int:
    from ._case import Case

    c = Case(_parse_perm(args.sigma), _parse_perm(args.Sigma))
    console.print(f"case {c}: τ = σ⁻¹∘Σ = {c.tau.one_line()}, sgn τ = {c.sign:+d}, class [bold]{c.cls}[/bold]")
    r = c.roles
    console.print(
        f"roles: x₊ = x{r['x+']}, x∘ = x{r['x∘']}, x₋ = x{r['x-']};  "
        f"X₊ = X{r['X+']}, X∘ = X{r['X∘']}, X₋ = X{r['X-']}"
    )
    console.print(f"sign in (volpot2) must be sgn τ = {c.sign:+d}")
    return 0


def _summary_table(title: str, rows: dict[str, Any]):
    from rich.table import Table

    t = Table(title=title, show_header=False)
    t.add_column("", style="bold")
    t.add_column("", overflow="fold")
    for k, v in rows.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        t.add_row(str(k), str(v))
    return t


def _check_out(*paths: str) -> None:
    """Fail before the computation, not after it, when an output's folder does not exist."""
    for path in paths:
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise CLIError(f"cannot write {path!r}: folder {folder!r} does not exist")


def _cmd_run(args, console) -> int:
    import numpy as np

    from ._integrate import integrate

    _check_out(args.out)
    prob = _problem(args)
    method = _method_from_args(args, prob.field)
    x0 = prob.initial_conditions(args.particles, seed=args.seed)
    sol = integrate(method, x0, args.h, args.steps, save_every=args.save_every,
                    chunk_size=args.chunk_size, progress="auto")
    sol.save(args.out)
    rows = {
        "problem": prob.name,
        "method": sol.method,
        "particles": args.particles,
        "h": args.h,
        "steps": args.steps,
        "t final": float(sol.ts[-1]),
        "saved states per particle": int(sol.ts.size),
        "failed particles": sol.n_failed,
        "wall time (s, incl. compile)": round(sol.stats["wall_s"], 3),
        "ns per particle-step (incl. compile)": round(sol.stats["ns_per_particle_step"], 1),
    }
    if prob.invariants:
        from .diagnostics import invariant_drift

        for name, d in invariant_drift(prob.invariants, sol.xs[None] if sol.xs.ndim == 2 else sol.xs).items():
            rows[f"max |Δ {name}|"] = f"{float(np.max(np.abs(d))):.3e}"
    console.print(_summary_table("vpforms run", rows))
    console.print(f"written: {args.out}", soft_wrap=True)
    if sol.n_failed:
        idx = np.flatnonzero(np.atleast_1d(sol.status))
        console.print(f"[yellow]{sol.n_failed} particle(s) failed and were frozen; first: "
                      f"{idx[:5].tolist()} at steps {np.atleast_1d(sol.failed_step)[idx[:5]].tolist()}")
    return 0


def _default_period(prob, axis: int, given: float | None) -> float | None:
    if given is not None:
        if not (given >= 0 and math.isfinite(given)):
            raise CLIError(f"--period must be a positive number (0 = none), got {given}")
        return None if given == 0 else given
    per = getattr(prob, "periodic", None)
    return None if not per else per[axis]


def _cmd_poincare(args, console) -> int:
    from . import plots
    from .diagnostics import poincare_section

    _check_out(args.png, args.csv)
    prob = _problem(args)
    method = _method_from_args(args, prob.field)
    axis = args.axis - 1
    period = _default_period(prob, axis, args.period)
    x0 = prob.initial_conditions(args.particles, seed=args.seed)
    t = time.perf_counter()
    sec = poincare_section(method, x0, args.h, args.steps, axis=axis, value=args.value,
                           direction=args.direction, period=period, interpolation=args.interpolation,
                           progress="auto")
    wall = time.perf_counter() - t
    sec.to_csv(args.csv)
    plots.poincare_figure(sec, title=f"{prob.name}: {sec.method}, h = {args.h:g}", path=args.png)
    console.print(_summary_table("vpforms poincare", {
        "problem": prob.name,
        "method": sec.method,
        "plane": f"x{args.axis} = {args.value:g}"
        + ((" (mod 2π)" if abs(period - 2 * math.pi) < 1e-12 else f" (mod {period:.6g})") if period else ""),
        "orbits × steps": f"{args.particles} × {args.steps} (h = {args.h:g})",
        "crossings": int(sec.points.shape[0]),
        "dropped (buffer full)": sec.dropped,
        "interpolation": f"{sec.interpolation}: order {sec.interpolation_order}",
        "located by the chord (step family failed)": sec.n_fallback,
        "failed orbits": int((sec.status != 0).sum()),
        "wall time (s)": round(wall, 2),
    }))
    console.print(f"figure: {args.png}\ncrossings CSV: {args.csv}", soft_wrap=True)
    return 0


def _order_study(prob, specs, T, hs, n_particles, seed, console, fast=False):
    """Errors at T for each method spec over hs; returns label → OrderFit."""
    from rich.progress import Progress

    from .diagnostics import fit_order, reference_solution, step_size_errors

    x0 = prob.initial_conditions(n_particles, seed=seed)
    with console.status("reference solution (DOP853, rtol 1e-13)…"):
        ref = reference_solution(prob.field, x0, T)
    fits = {}
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("step-size sweep", total=len(specs) * len(hs))
        for name, order in specs:
            m = _method(prob.field, name, None, order, fast=fast and name.upper() == "SE+SE")
            errs = []
            for h in hs:
                errs.append(step_size_errors(m, x0, T, [h], ref)[0])
                bar.advance(task)
            fits[_spec_label(name, order)] = fit_order(hs, errs)
    return fits


def _order_table(fits, title):
    from rich.table import Table

    hs = next(iter(fits.values())).hs
    t = Table(title=title)
    t.add_column("h", justify="right")
    for name in fits:
        t.add_column(name, justify="right")
    for i, h in enumerate(hs):
        t.add_row(f"{h:.4g}", *[f"{f.errors[i]:.3e}" + ("" if f.used[i] else " ·") for f in fits.values()])
    t.add_row("order", *[f"[bold]{f.order:.2f}[/bold]" for f in fits.values()])
    return t


def _cmd_order(args, console) -> int:
    from . import plots

    _check_out(args.png)
    prob = _problem(args)
    specs = [_parse_method_spec(s) for s in (args.methods or ["SE+SE", "SE+SE:2", "SE+SE:4", "rk4"])]
    if args.hs:
        hs = sorted(args.hs, reverse=True)
    else:
        hs = [args.h_max / 2**k for k in range(args.levels)]
    for h in hs:
        if abs(args.T / h - round(args.T / h)) > 1e-9 * max(1.0, args.T / h):
            raise CLIError(f"T/h must be an integer for every h (T = {args.T}, h = {h})")
    fits = _order_study(prob, specs, args.T, hs, args.particles, args.seed, console, fast=args.fast)
    console.print(_order_table(fits, f"max error at T = {args.T:g} on {prob.name} ({args.particles} particles; · = not in fit)"))
    plots.order_figure(fits, title=f"Convergence on {prob.name} at T = {args.T:g}", path=args.png)
    console.print(f"figure: {args.png}", soft_wrap=True)
    return 0


def _drift_panels(prob, method, h, steps, n_particles, seed, console, label=None):
    """Volume (and invariant) drift of ``method`` and RK4 along the same orbits."""
    import numpy as np

    from .diagnostics import invariant_drift, log_det
    from ._integrate import RK4, integrate

    x0 = prob.initial_conditions(n_particles, seed=seed)
    label = label or "vpforms " + getattr(method, "name", "method")
    methods = {label: method, "RK4": RK4(prob.field)}
    vol, inv = {}, {}
    stats = {}
    for label, m in methods.items():
        with console.status(f"log |det J| along {n_particles} orbits × {steps} steps: {label}…"):
            ld = log_det(m, x0, h, steps)
        vol[label] = (ld.ts, np.abs(ld.accumulated))
        # a failed orbit's log det stops at its failure: say how many, next to the maximum
        stats[label] = {"max |log det|": ld.max_abs, "failed orbits": ld.n_failed}
        if prob.invariants:
            sol = integrate(m, x0, h, steps, save_every=max(1, steps // 200), progress="auto")
            for name, d in invariant_drift(prob.invariants, sol.xs).items():
                inv.setdefault(f"invariant {name}: |I(x(t)) − I(x(0))|", {})[label] = (sol.ts, np.abs(d))
                stats[label][f"max |Δ {name}|"] = float(np.max(np.abs(d)))
    panels = {"volume: |log det D(Ψⁿ)| = |Σ log |det DΨ(xₖ)||": vol, **inv}
    return panels, stats


def _cmd_drift(args, console) -> int:
    from rich.table import Table

    from . import plots

    _check_out(args.png)
    prob = _problem(args)
    method = _method_from_args(args, prob.field)
    panels, stats = _drift_panels(prob, method, args.h, args.steps, args.particles, args.seed, console)
    plots.drift_figure(panels, title=f"Drift on {prob.name}, h = {args.h:g}: vpforms vs RK4", path=args.png)
    t = Table(title=f"drift on {prob.name}, h = {args.h:g}, {args.steps} steps, {args.particles} orbits")
    keys = list(next(iter(stats.values())))
    t.add_column("method")
    for k in keys:
        t.add_column(k, justify="right")
    for label, row in stats.items():
        t.add_row(label, *[str(row[k]) if isinstance(row[k], int) else f"{row[k]:.3e}" for k in keys])
    console.print(t)
    console.print(f"figure: {args.png}", soft_wrap=True)
    return 0


def _errata_function():
    """The symbolic errata report of issue #3, if present: a callable returning text."""
    try:
        from . import symbolic
    except ImportError as exc:
        raise CLIError(f"the symbolic layer (vpforms.symbolic) is not available: {exc}") from None
    for mod_name in ("errata", "report"):
        try:
            mod = __import__(f"{symbolic.__name__}.{mod_name}", fromlist=["_"])
        except ImportError:
            continue
        for fn_name in ("errata_report", "report", "errata"):
            fn = getattr(mod, fn_name, None)
            if callable(fn):
                return fn
    for fn_name in ("errata_report", "errata"):
        fn = getattr(symbolic, fn_name, None)
        if callable(fn):
            return fn
    raise CLIError("the symbolic errata report (issue #3, vpforms.symbolic) is not available in this build")


def _cmd_errata(args, console) -> int:
    fn = _errata_function()
    kw = {}
    if args.matrix:
        import sympy as sp

        try:
            rows = [[sp.Rational(v.strip()) for v in r.split(",")] for r in args.matrix.split(";")]
            A = sp.Matrix(rows)
        except (ValueError, TypeError, sp.SympifyError) as exc:
            raise CLIError(f"--matrix must be 3 rows 'a,b,c;d,e,f;g,h,i' of numbers: {exc}") from None
        if A.shape != (3, 3) or A.trace() != 0:
            raise CLIError("--matrix must be a traceless 3×3 matrix, e.g. '1,2,3;-1,2,1;2,-2,-3'")
        kw["A"] = A
    fmt = "markdown" if args.markdown else "text"
    with console.status("checking the paper's formulas symbolically (about 30 s on a generic matrix)…"):
        try:
            out = fn(fmt=fmt, **kw)
        except TypeError:  # a report function without the fmt/A keywords
            out = fn()
    text = out if isinstance(out, str) else str(out)
    if not args.markdown:
        console.print("[bold]Errata of arXiv 1412.6345, measured symbolically[/bold] "
                      "(consistency M(0) = I, M'(0) = A, order and det of X = M(h)x)")
    print(text)
    return 0


def _cmd_demo(args, console) -> int:
    import numpy as np
    from rich.panel import Panel

    from . import plots, problems
    from .diagnostics import poincare_section

    quick = args.quick
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    t_all = time.perf_counter()
    console.print(Panel.fit(
        "vpforms demo: volume-preserving integrators from generating forms (arXiv 1412.6345)\n"
        f"figures → {out}", style="bold"))
    from collections import Counter

    from ._case import cases

    counts = Counter(c.cls for c in cases())
    console.print("36 cases (σ, Σ) in 5 classes: " + ", ".join(f"{k} {v}" for k, v in counts.items())
                  + "   (vpforms cases | vpforms classify 3,2,1 1,2,3)")

    abc = problems.get("abc")
    se = _method(abc.field, "SE+SE", fast=True)
    se2 = _method(abc.field, "SE+SE", order=2, fast=True)

    # 1. Poincaré section of the ABC flow
    n_orb, n_steps, h = (6, 400, 0.1) if quick else (200, 10000, 0.1)
    x0 = abc.initial_conditions(n_orb, seed=1)
    t = time.perf_counter()
    sec = poincare_section(se2, x0, h, n_steps, axis=2, value=0.0, direction=1, period=2 * math.pi,
                           progress="auto")
    png1 = os.path.join(out, "poincare_abc.png")
    plots.poincare_figure(sec, title=f"ABC flow (A, B, C) = (1, √(2/3), √(1/3)): SE+SE, order 2, h = {h:g}",
                          path=png1)
    sec.to_csv(os.path.join(out, "poincare_abc.csv"))
    console.print(f"[green]✓[/green] Poincaré section x₃ = 0 mod 2π: {sec.points.shape[0]} crossings of "
                  f"{n_orb} orbits over t = {n_steps * h:g} ({time.perf_counter() - t:.1f} s) → {png1}")

    # 2. Order plot
    T = 1.0
    hs = [0.2 / 2**k for k in range(3 if quick else 6)]
    specs = [("SE+SE", 1), ("SE+SE", 2), ("SE+SE", 4), ("rk4", 1)]
    t = time.perf_counter()
    fits = _order_study(abc, specs, T, hs, 2 if quick else 8, 2, console, fast=True)
    png2 = os.path.join(out, "order_abc.png")
    plots.order_figure(fits, title=f"Convergence on the ABC flow at T = {T:g}", path=png2)
    console.print(_order_table(fits, f"max error at T = {T:g} (ABC flow)"))
    console.print(f"[green]✓[/green] order plot ({time.perf_counter() - t:.1f} s) → {png2}")

    # 3. Drift plot vs RK4 (the rigid body has invariants; ABC has none)
    t = time.perf_counter()
    rb = problems.get("rigid_body")
    m_rb = _method(rb.field, "SE+SE", order=4)
    steps = 200 if quick else 5000
    panels, stats = _drift_panels(rb, m_rb, 0.1, steps, 4 if quick else 16, 0, console,
                                  label="vpforms SE+SE, order 4")
    png3 = os.path.join(out, "drift_rigid_body.png")
    plots.drift_figure(panels, title="Free rigid body, h = 0.1: vpforms (order 4) vs RK4 (order 4)", path=png3)
    lines = []
    for label, row in stats.items():
        lines.append(f"{label}: " + ", ".join(f"{k} = {v}" if isinstance(v, int) else f"{k} = {v:.2e}"
                                             for k, v in row.items()))
    console.print("\n".join(lines))
    console.print(f"[green]✓[/green] drift plot ({time.perf_counter() - t:.1f} s) → {png3}")
    console.print(Panel.fit(f"demo finished in {time.perf_counter() - t_all:.1f} s; figures in {out}:\n"
                            f"  {png1}\n  {png2}\n  {png3}", style="green"))
    del np
    return 0


# --------------------------------------------------------------------------------------------
# Parser
# --------------------------------------------------------------------------------------------
def _add_problem_args(p, default_problem="abc"):
    p.add_argument("--problem", default=default_problem,
                   help=f"test problem (vpforms.problems.names(): abc, abc_gi, linear, lotka_volterra, "
                        f"stokes_sphere, tokamak, rigid_body); default {default_problem}")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="problem parameter, repeatable or comma-separated, e.g. --param C=0 or "
                        "--param B=sqrt(2/3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the initial conditions (default 0)")


def _add_method_args(p, default_order=1):
    p.add_argument("--method", default="SE+SE", metavar="CLASS",
                   help="class representative: SE+SE, SE+DL (= DL+SE), DL+DL, S1, S2, or rk4 "
                        "(the explicit baseline); default SE+SE")
    p.add_argument("--case", nargs=2, metavar=("SIGMA", "SIGMA2"),
                   help="an explicit case (σ, Σ) instead of the class representative, e.g. --case 2,3,1 1,3,2")
    p.add_argument("--order", type=int, default=default_order, choices=(1, 2, 4, 6),
                   help=f"composition order (1 = the bare method); default {default_order}")
    p.add_argument("--fast", action="store_true", help="closed-form SE+SE path (no Newton)")
    p.add_argument("--theta", type=_finite_float, default=None,
                   help="θ of the discrete Lagrangian (DL classes): 0 or 0.5")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="vpforms",
        description="Volume-preserving generating forms in R³ (Verdier, Xue, Zanna, arXiv 1412.6345): "
                    "integrators, particle tracing, Poincaré sections and diagnostics.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("cases", help="print the 36-case classification table",
                       description="Print the 36 cases (σ, Σ), τ = σ⁻¹∘Σ, its sign and class.")
    p.set_defaults(func=_cmd_cases)

    p = sub.add_parser("classify", help="classify a case (σ, Σ)",
                       description="Class, sign and roles of the case (σ, Σ).")
    p.add_argument("sigma", help="σ in one-line notation, e.g. 3,2,1 or 321")
    p.add_argument("Sigma", help="Σ in one-line notation, e.g. 1,2,3")
    p.set_defaults(func=_cmd_classify)

    p = sub.add_parser("run", help="trace particles and write an .npz",
                       description="Integrate particles of a test problem; write ts, xs, status to an .npz "
                                   "and print a summary.")
    _add_problem_args(p)
    _add_method_args(p)
    p.add_argument("--h", type=_positive_float, default=0.1, help="step size (default 0.1)")
    p.add_argument("--steps", type=_positive_int, default=1000, help="number of steps (default 1000)")
    p.add_argument("--particles", type=_positive_int, default=100, help="number of particles (default 100)")
    p.add_argument("--save-every", type=_positive_int, default=None,
                   help="save every k-th state (default: only the initial and final states)")
    p.add_argument("--chunk-size", type=_positive_int, default=None, help="particles per compiled call")
    p.add_argument("--out", default="vpforms-run.npz", help="output .npz (default vpforms-run.npz)")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("poincare", help="Poincaré section: PNG + crossings CSV",
                       description="Non-terminating crossings of the plane x_AXIS = VALUE (mod the "
                                   "problem's period), located on the method's own step family.")
    _add_problem_args(p)
    _add_method_args(p, default_order=2)
    p.add_argument("--h", type=_positive_float, default=0.1, help="step size (default 0.1)")
    p.add_argument("--steps", type=_positive_int, default=5000, help="steps per orbit (default 5000)")
    p.add_argument("--particles", type=_positive_int, default=60, help="number of orbits (default 60)")
    p.add_argument("--axis", type=int, default=3, choices=(1, 2, 3), help="normal coordinate (default 3)")
    p.add_argument("--value", type=float, default=0.0, help="plane position (default 0)")
    p.add_argument("--direction", type=int, default=1, choices=(-1, 0, 1),
                   help="+1 increasing, -1 decreasing, 0 both (default +1)")
    p.add_argument("--period", type=float, default=None,
                   help="period of the normal coordinate (default: the problem's, e.g. 2π for abc; 0 = none)")
    p.add_argument("--interpolation", choices=("step", "linear"), default="step",
                   help="crossing location: 'step' (Ψ_{θh}, the method's order) or 'linear' (chord)")
    p.add_argument("--png", default="vpforms-poincare.png", help="figure (default vpforms-poincare.png)")
    p.add_argument("--csv", default="vpforms-poincare.csv", help="crossings (default vpforms-poincare.csv)")
    p.set_defaults(func=_cmd_poincare)

    p = sub.add_parser("order", help="convergence study: PNG + table",
                       description="Errors at time T against a DOP853 reference for a step-size sweep, "
                                   "and the observed orders (plateau-aware log-log fit).")
    _add_problem_args(p)
    p.add_argument("--methods", nargs="+", metavar="SPEC",
                   help="CLASS or CLASS:ORDER or rk4 (default: SE+SE SE+SE:2 SE+SE:4 rk4)")
    p.add_argument("--T", type=_positive_float, default=1.0, help="final time (default 1)")
    p.add_argument("--h-max", type=_positive_float, default=0.2, help="largest step (default 0.2)")
    p.add_argument("--levels", type=_positive_int, default=6, help="number of halvings (default 6)")
    p.add_argument("--hs", type=_float_list, default=None, help="explicit comma-separated step sizes")
    p.add_argument("--particles", type=_positive_int, default=4, help="particles (default 4)")
    p.add_argument("--fast", action="store_true", help="closed-form SE+SE path for SE+SE specs")
    p.add_argument("--png", default="vpforms-order.png", help="figure (default vpforms-order.png)")
    p.set_defaults(func=_cmd_order)

    p = sub.add_parser("drift", help="volume/invariant drift vs RK4: PNG",
                       description="log |det J| accumulated along orbits (forward-mode AD) and invariant "
                                   "drift, vpforms against RK4 on the same problem and step.")
    _add_problem_args(p, default_problem="rigid_body")
    _add_method_args(p, default_order=2)
    p.add_argument("--h", type=_positive_float, default=0.1, help="step size (default 0.1)")
    p.add_argument("--steps", type=_positive_int, default=2000, help="number of steps (default 2000)")
    p.add_argument("--particles", type=_positive_int, default=16, help="number of orbits (default 16)")
    p.add_argument("--png", default="vpforms-drift.png", help="figure (default vpforms-drift.png)")
    p.set_defaults(func=_cmd_drift)

    p = sub.add_parser("errata", help="the paper's errata, checked symbolically",
                       description="Print the symbolic errata report (every printed formula that is wrong, "
                                   "with the corrected one, re-derived by SymPy).")
    p.add_argument("--markdown", action="store_true", help="print raw Markdown")
    p.add_argument("--matrix", default=None, metavar="'a,b,c;d,e,f;g,h,i'",
                   help="check on this traceless rational matrix instead of the generic symbolic one "
                        "(faster, but a special matrix can hide a defect)")
    p.set_defaults(func=_cmd_errata)

    p = sub.add_parser("demo", help="a one-minute tour that writes figures to a folder",
                       description="Poincaré section of the ABC flow, order plot, drift plot vs RK4.")
    p.add_argument("--out", default="vpforms-demo", help="output folder (default ./vpforms-demo)")
    p.add_argument("--quick", action="store_true", help="tiny sizes (for tests)")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 failed computation, 2 bad arguments)."""
    from rich.console import Console

    console = Console()
    debug = bool(os.environ.get("VPFORMS_DEBUG"))
    try:
        args = build_parser().parse_args(argv)
    except CLIError as exc:
        _error(str(exc))
        return 2
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    try:
        return int(args.func(args, console) or 0)
    except CLIError as exc:
        _error(str(exc))
        return 2
    except KeyboardInterrupt:
        print("vpforms: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `vpforms errata | head`
        sys.stdout = open(os.devnull, "w")
        return 0
    except Exception as exc:  # one line, no traceback, for any failure
        if debug:
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        _error(f"{type(exc).__name__}: {msg}")
        return 1


def _error(msg: str) -> None:
    """The one-line error report (plain stderr: never wrapped)."""
    print("vpforms: error: " + " ".join(msg.split()), file=sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""Studies against references: ``order`` (convergence) and ``drift`` (volume/invariants vs RK4)."""

from __future__ import annotations

import numpy as np
from rich.progress import Progress
from rich.table import Table

from .. import plots
from .._integrate import RK4, integrate
from ..diagnostics import (
    fit_order,
    invariant_drift,
    log_det,
    reference_solution,
    step_size_errors,
)
from ._common import (
    CLIError,
    _add_method_args,
    _add_problem_args,
    FIGURE_SUFFIXES,
    _check_out,
    _written,
    _float_list,
    _method,
    _method_from_args,
    _parse_method_spec,
    _positive_float,
    _positive_int,
    _problem,
    _spec_label,
    refuse_unless,
)
from ._explain import explain_rerun


def _order_study(prob, specs, T, hs, x0, console, fast=False):
    """Errors at T for each method spec over hs, from the initial conditions x0 (N, 3); returns
    label → OrderFit."""
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
    existing = _check_out(args, ("png", FIGURE_SUFFIXES))
    refuse_unless(args, ("h_max", "levels"), not args.hs, "with --hs (it lists the step sizes)")
    specs = [_parse_method_spec(s) for s in (args.methods or ["SE+SE", "SE+SE:2", "SE+SE:4", "rk4"])]
    refuse_unless(args, ("fast",), any(name.upper() == "SE+SE" for name, _ in specs),
                  "without an SE+SE spec in --methods (it is the closed-form SE+SE path)")
    prob = _problem(args)
    if args.hs:
        hs = sorted(args.hs, reverse=True)
    else:
        hs = [args.h_max / 2**k for k in range(args.levels)]
    for h in hs:
        if abs(args.T / h - round(args.T / h)) > 1e-9 * max(1.0, args.T / h):
            raise CLIError(f"T/h must be an integer for every h (T = {args.T}, h = {h})")
    x0 = prob.initial_conditions(args.particles, seed=args.seed)  # the points of --x0, if given
    fits = _order_study(prob, specs, args.T, hs, x0, console, fast=args.fast)
    console.print(_order_table(fits, f"max error at T = {args.T:g} on {prob.name} ({len(x0)} particles; · = not in fit)"))
    plots.order_figure(fits, title=f"Convergence on {prob.name} at T = {args.T:g}", path=args.png)
    console.print(f"figure: {_written(args.png, existing)}", soft_wrap=True)
    return 0


def _drift_panels(prob, method, h, steps, x0, console, label=None, failures=None):
    """Volume (and invariant) drift of ``method`` and RK4 along the same orbits, from x0 (N, 3).

    ``failures`` (a dict), when given, receives label → (method, x0, per-orbit status) for every
    method with failed orbits (to explain them, issue #12)."""
    label = label or "vpforms " + getattr(method, "name", "method")
    methods = {label: method, "RK4": RK4(prob.field)}
    vol, inv = {}, {}
    stats = {}
    for label, m in methods.items():
        with console.status(f"log |det J| along {len(x0)} orbits × {steps} steps: {label}…"):
            ld = log_det(m, x0, h, steps)
        vol[label] = (ld.ts, np.abs(ld.accumulated))
        # a failed orbit's log det stops at its failure: say how many, next to the maximum
        stats[label] = {"max |log det|": ld.max_abs, "failed orbits": ld.n_failed}
        if failures is not None and ld.n_failed:
            failures[label] = (m, x0, ld.status)
        if prob.invariants:
            sol = integrate(m, x0, h, steps, save_every=max(1, steps // 200), progress="auto")
            for name, d in invariant_drift(prob.invariants, sol.xs).items():
                inv.setdefault(f"invariant {name}: |I(x(t)) − I(x(0))|", {})[label] = (sol.ts, np.abs(d))
                stats[label][f"max |Δ {name}|"] = float(np.max(np.abs(d)))
    panels = {"volume: |log det D(Ψⁿ)| = |Σ log |det DΨ(xₖ)||": vol, **inv}
    return panels, stats


def _cmd_drift(args, console) -> int:
    existing = _check_out(args, ("png", FIGURE_SUFFIXES))
    prob = _problem(args)
    method = _method_from_args(args, prob.field)
    failures: dict = {}
    x0 = prob.initial_conditions(args.particles, seed=args.seed)  # the points of --x0, if given
    panels, stats = _drift_panels(prob, method, args.h, args.steps, x0, console, failures=failures)
    plots.drift_figure(panels, title=f"Drift on {prob.name}, h = {args.h:g}: vpforms vs RK4", path=args.png)
    t = Table(title=f"drift on {prob.name}, h = {args.h:g}, {args.steps} steps, {len(x0)} orbits")
    keys = list(next(iter(stats.values())))
    t.add_column("method", no_wrap=True, min_width=max(map(len, stats)))  # never cut the name
    for k in keys:
        t.add_column(k, justify="right")
    for label, row in stats.items():
        t.add_row(label, *[str(row[k]) if isinstance(row[k], int) else f"{row[k]:.3e}" for k in keys])
    console.print(t)
    console.print(f"figure: {_written(args.png, existing)}", soft_wrap=True)
    for label, (m, x0, status) in failures.items():  # why orbits failed, with a hint (issue #12)
        explain_rerun(console, status, m, x0, args.h, args.steps, f"failed orbits of {label}")
    return 0


def register(sub) -> None:
    """Add this group's subcommands to the subparsers ``sub``."""
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
    p.add_argument("--png", default="vpforms-order.png", help="figure: .png, .pdf or .svg (default vpforms-order.png)")
    p.set_defaults(func=_cmd_order)

    p = sub.add_parser("drift", help="volume/invariant drift vs RK4: PNG",
                       description="log |det J| accumulated along orbits (forward-mode AD) and invariant "
                                   "drift, vpforms against RK4 on the same problem and step.")
    _add_problem_args(p, default_problem="rigid_body")
    _add_method_args(p, default_order=2)
    p.add_argument("--h", type=_positive_float, default=0.1, help="step size (default 0.1)")
    p.add_argument("--steps", type=_positive_int, default=2000, help="number of steps (default 2000)")
    p.add_argument("--particles", type=_positive_int, default=16, help="number of orbits (default 16)")
    p.add_argument("--png", default="vpforms-drift.png", help="figure: .png, .pdf or .svg (default vpforms-drift.png)")
    p.set_defaults(func=_cmd_drift)

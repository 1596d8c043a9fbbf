"""Particle tracing: ``run`` (trajectories to a file) and ``poincare`` (sections)."""

from __future__ import annotations

import math
import time

import numpy as np

from .. import plots
from .._integrate import integrate
from ..backends import NativeUnavailableError
from ..diagnostics import invariant_drift, poincare_section
from . import _distributed
from ._common import (
    CLIError,
    _add_method_args,
    _add_problem_args,
    CSV_SUFFIXES,
    FIGURE_SUFFIXES,
    RUN_SUFFIXES,
    _check_out,
    _written,
    _method_from_args,
    _positive_float,
    _positive_int,
    _problem,
    _summary_table,
    refuse_unless,
)
from ._explain import explain_rerun, explain_solution, recovered_text


def _cmd_run(args, console) -> int:
    existing = _check_out(args, ("out", RUN_SUFFIXES))
    store = str(args.out).endswith(".zarr")
    refuse_unless(args, STORE_OPTIONS, store, "without a .zarr store (--out run.zarr): an .npz run is in process")
    refuse_unless(args, ("chunk_size",), not store, "with a .zarr store (its tasks are --chunk-particles)")
    refuse_unless(args, ("workers",), args.scheduler == "local",
                  "without --scheduler local (a remote scheduler has its own workers; no scheduler: in process)")
    prob = _problem(args)
    method = _method_from_args(args, prob.field)
    x0 = prob.initial_conditions(args.particles, seed=args.seed)
    if store:  # a store run: chunked, resumable, optionally distributed
        return _distributed.cmd_run_store(args, prob, method, x0, console)
    try:
        sol = integrate(method, x0, args.h, args.steps, save_every=args.save_every,
                        chunk_size=args.chunk_size, progress="auto", backend=args.backend)
    except NativeUnavailableError as exc:
        raise CLIError(str(exc)) from None
    written = sol.save(args.out)  # the name ends in .npz (_check_out): written as given
    rows = {
        "problem": prob.name,
        "method": sol.method,
        "backend": f"{sol.stats['backend']} ({sol.stats['backend_reason']})",
        "particles": len(x0),
        "h": args.h,
        "steps": args.steps,
        "t final": float(sol.ts[-1]),
        "saved states per particle": int(sol.ts.size),
        "failed particles": sol.n_failed,
        "recovered steps": recovered_text(sol, method),
        **({"divergence check": prob.field.divergence_check} if getattr(prob, "source", None) == "user" else {}),
        "wall time (s, incl. compile)": round(sol.stats["wall_s"], 3),
        "ns per particle-step (incl. compile)": round(sol.stats["ns_per_particle_step"], 1),
    }
    if prob.invariants:
        for name, d in invariant_drift(prob.invariants, sol.xs[None] if sol.xs.ndim == 2 else sol.xs).items():
            rows[f"max |Δ {name}|"] = f"{float(np.max(np.abs(d))):.3e}"
    console.print(_summary_table("vpforms run", rows))
    console.print(f"written: {_written(written, existing)}", soft_wrap=True)
    explain_solution(console, sol, method)  # breakdown by reason, first failures, hint (issue #12)
    return 0


#: the options of a .zarr store run (:func:`._distributed.add_args`): refused without a store
STORE_OPTIONS = ("scheduler", "workers", "resume", "chunk_particles", "checkpoint_every")


def _default_period(prob, axis: int, given: float | None) -> float | None:
    if given is not None:
        if not (given >= 0 and math.isfinite(given)):
            raise CLIError(f"--period must be a positive number (0 = none), got {given}")
        return None if given == 0 else given
    per = getattr(prob, "periodic", None)
    return None if not per else per[axis]


def _cmd_poincare(args, console) -> int:
    existing = _check_out(args, ("png", FIGURE_SUFFIXES), ("csv", CSV_SUFFIXES))
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
        "orbits × steps": f"{len(x0)} × {args.steps} (h = {args.h:g})",
        "crossings": int(sec.points.shape[0]),
        "dropped (buffer full)": sec.dropped,
        "interpolation": f"{sec.interpolation}: order {sec.interpolation_order}",
        "located by the chord (step family failed)": sec.n_fallback,
        "failed orbits": int((sec.status != 0).sum()),
        "wall time (s)": round(wall, 2),
    }))
    console.print(f"figure: {_written(args.png, existing)}\ncrossings CSV: {_written(args.csv, existing)}",
                  soft_wrap=True)
    explain_rerun(console, sec.status, method, x0, args.h, args.steps, "failed orbits")
    return 0


def register(sub) -> None:
    """Add this group's subcommands to the subparsers ``sub``."""
    p = sub.add_parser("run", help="trace particles and write an .npz",
                       description="Integrate particles of a test problem; write ts, xs, status to an .npz "
                                   "and print a summary.")
    _add_problem_args(p)
    _add_method_args(p, backend=True)
    p.add_argument("--h", type=_positive_float, default=0.1, help="step size (default 0.1)")
    p.add_argument("--steps", type=_positive_int, default=1000, help="number of steps (default 1000)")
    p.add_argument("--particles", type=_positive_int, default=100, help="number of particles (default 100)")
    p.add_argument("--save-every", type=_positive_int, default=None,
                   help="save every k-th state (default: only the initial and final states)")
    p.add_argument("--chunk-size", type=_positive_int, default=None, help="particles per compiled call")
    p.add_argument("--out", default="vpforms-run.npz", help="output: an .npz file, or a .zarr store (resumed when it holds this run; default vpforms-run.npz)")
    _distributed.add_args(p)
    p.set_defaults(func=_cmd_run)
    _distributed.register(sub)

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
    p.add_argument("--png", default="vpforms-poincare.png", help="figure: .png, .pdf or .svg (default vpforms-poincare.png)")
    p.add_argument("--csv", default="vpforms-poincare.csv", help="crossings: .csv (default vpforms-poincare.csv)")
    p.set_defaults(func=_cmd_poincare)

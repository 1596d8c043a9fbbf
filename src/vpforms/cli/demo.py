"""``demo``: the one-minute tour that writes figures to a folder."""

from __future__ import annotations

import math
import os
import time
from collections import Counter

from rich.panel import Panel

from .. import plots
from .._case import cases
from ..diagnostics import poincare_section
from ._common import (
    _method,
)
from .studies import _drift_panels, _order_study, _order_table


def _cmd_demo(args, console) -> int:
    from .. import problems

    quick = args.quick
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    t_all = time.perf_counter()
    console.print(Panel.fit(
        "vpforms demo: volume-preserving integrators from generating forms (arXiv 1412.6345)\n"
        f"figures → {out}", style="bold"))
    counts = Counter(c.cls for c in cases())
    console.print("36 cases (σ, Σ) in 5 classes: " + ", ".join(f"{k} {v}" for k, v in counts.items())
                  + "   (vpforms cases | vpforms classify 3,2,1 1,2,3)")

    abc = problems.get("abc")
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
    csv1 = os.path.join(out, "poincare_abc.csv")
    sec.to_csv(csv1)
    console.print(f"[green]✓[/green] Poincaré section x₃ = 0 mod 2π: {sec.points.shape[0]} crossings of "
                  f"{n_orb} orbits over t = {n_steps * h:g} ({time.perf_counter() - t:.1f} s) → {png1}")

    # 2. Order plot
    T = 1.0
    hs = [0.2 / 2**k for k in range(3 if quick else 6)]
    specs = [("SE+SE", 1), ("SE+SE", 2), ("SE+SE", 4), ("rk4", 1)]
    t = time.perf_counter()
    fits = _order_study(abc, specs, T, hs, abc.initial_conditions(2 if quick else 8, seed=2), console, fast=True)
    png2 = os.path.join(out, "order_abc.png")
    plots.order_figure(fits, title=f"Convergence on the ABC flow at T = {T:g}", path=png2)
    console.print(_order_table(fits, f"max error at T = {T:g} (ABC flow)"))
    console.print(f"[green]✓[/green] order plot ({time.perf_counter() - t:.1f} s) → {png2}")

    # 3. Drift plot vs RK4 (the rigid body has invariants; ABC has none)
    t = time.perf_counter()
    rb = problems.get("rigid_body")
    m_rb = _method(rb.field, "SE+SE", order=4)
    steps = 200 if quick else 5000
    panels, stats = _drift_panels(rb, m_rb, 0.1, steps, rb.initial_conditions(4 if quick else 16, seed=0),
                                  console, label="vpforms SE+SE, order 4")
    png3 = os.path.join(out, "drift_rigid_body.png")
    plots.drift_figure(panels, title="Free rigid body, h = 0.1: vpforms (order 4) vs RK4 (order 4)", path=png3)
    lines = []
    for label, row in stats.items():
        lines.append(f"{label}: " + ", ".join(f"{k} = {v}" if isinstance(v, int) else f"{k} = {v:.2e}"
                                             for k, v in row.items()))
    console.print("\n".join(lines))
    console.print(f"[green]✓[/green] drift plot ({time.perf_counter() - t:.1f} s) → {png3}")
    console.print(Panel.fit(f"demo finished in {time.perf_counter() - t_all:.1f} s; figures in {out}:\n"
                            f"  {png1}\n  {png2}\n  {png3}\ncrossings CSV: {csv1}", style="green"))
    return 0


def register(sub) -> None:
    """Add this group's subcommands to the subparsers ``sub``."""
    p = sub.add_parser("demo", help="a one-minute tour that writes figures to a folder",
                       description="Poincaré section of the ABC flow, order plot, drift plot vs RK4.")
    p.add_argument("--out", default="vpforms-demo", help="output folder (default ./vpforms-demo)")
    p.add_argument("--quick", action="store_true", help="tiny sizes (for tests)")
    p.set_defaults(func=_cmd_demo)

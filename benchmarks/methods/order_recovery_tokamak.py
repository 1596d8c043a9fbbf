"""Observed order of the recovering tokamak DL+DL composed to order 4 (issue #19, items 4 and 5;
notes/issue-23.md): the default form (nested θ-stages) and the engine form (``fast=False``).

    python benchmarks/methods/order_recovery_tokamak.py   # writes benchmarks/methods/results_order_recovery.md
"""
import os
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")
import vpforms  # noqa: E402
from vpforms import problems  # noqa: E402
from vpforms.diagnostics import reference_solution  # noqa: E402

P = problems.get("tokamak")
x0 = P.initial_conditions(20, seed=1)
T = 4.0
ref = np.asarray(reference_solution(P.field, x0, T))
lines = ["# Tokamak DL+DL composed to order 4, with recovery (issue #19 items 4–5, #23)", "",
         "20 field lines (seed 1), T = 4, max error against DOP853 (`reference_solution`); "
         "`backend=\"auto\"`. Since issue #19 the DL classes run as their nested θ-stages by default "
         "(native); `fast=False` is the engine form (JAX).", ""]
for label, opts in (("default (θ-stages)", {}), ("engine form (fast=False)", {"fast": False})):
    m = vpforms.compose(vpforms.scheme(P.field, "DL+DL", **opts), 4)
    hs, errs = [], []
    lines += [f"## {label}", "", "| h | error | recovered steps | by | backend | wall (s) |", "|---|---|---|---|---|---|"]
    for h in (0.2, 0.1, 0.05, 0.025):
        t = time.perf_counter()
        n = int(round(T / h))
        sol = vpforms.integrate(m, x0, h, n, progress=False)
        wall = time.perf_counter() - t
        e = np.max(np.abs(np.asarray(sol.x_final) - ref))
        hs.append(h)
        errs.append(e)
        rec = int(np.sum(sol.recovered))
        lines.append(f"| {h} | {e:.3e} | {rec} of {20 * n} | {sol.stats.get('recovered_how') or '—'} | "
                     f"{sol.stats['backend']} | {wall:.1f} |")
        print(label, f"h={h} err={e:.3e} failed={sol.n_failed} recovered={rec} {sol.stats['backend']} {wall:.1f}s",
              flush=True)
    slopes = np.diff(np.log(errs)) / np.diff(np.log(hs))
    lines += ["", "Observed order (slopes between successive h): " + ", ".join(f"{v:.3f}" for v in slopes), ""]
lines += ["(wall times include compilation: the first h of each form compiles its method)", ""]
open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "results_order_recovery.md"), "w").write("\n".join(lines))

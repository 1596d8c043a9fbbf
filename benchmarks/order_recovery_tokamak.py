"""Observed order of the recovering tokamak DL+DL composed to order 4 (issue #19, item 5; notes/issue-23.md).

    python benchmarks/order_recovery_tokamak.py   # writes benchmarks/results_order_recovery.md
"""
import os
import numpy as np, warnings, time
warnings.simplefilter("ignore")
import vpforms
from vpforms import problems
from vpforms.diagnostics import fit_order, reference_solution
P = problems.get("tokamak")
x0 = P.initial_conditions(20, seed=1)
T = 4.0
ref = np.asarray(reference_solution(P.field, x0, T)) if True else None
m = vpforms.compose(vpforms.scheme(P.field, "DL+DL"), 4)
hs, errs = [], []
lines = ["# Tokamak DL+DL composed to order 4, with recovery (issue #19 item 5, #23)", "",
         "20 field lines (seed 1), T = 4, max error against DOP853 (`reference_solution`).", "",
         "| h | error | recovered steps | by |", "|---|---|---|---|"]
for h in (0.2, 0.1, 0.05, 0.025):
    t = time.time()
    sol = vpforms.integrate(m, x0, h, int(round(T/h)), progress=False)
    e = np.max(np.abs(np.asarray(sol.x_final) - ref))
    hs.append(h); errs.append(e)
    lines.append(f"| {h} | {e:.3e} | {int(np.sum(sol.recovered))} of {20*int(round(T/h))} | {sol.stats.get('recovered_how')} |")
    print(f"h={h} err={e:.3e} failed={sol.n_failed} recovered={int(np.sum(sol.recovered))} of {20*int(round(T/h))} how={sol.stats.get('recovered_how')} {time.time()-t:.0f}s", flush=True)
slopes = np.diff(np.log(errs)) / np.diff(np.log(hs))
print("slopes", slopes)
lines += ["", "Observed order (slopes between successive h): " + ", ".join(f"{v:.3f}" for v in slopes), ""]
open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "results_order_recovery.md"), "w").write("\n".join(lines))

"""Which composition pays (issue #24, item 2): global error against work for orders 2 to 8.

For SE+SE composed to order 2, 4 (Suzuki, Blanes–Moan), 6 (Yoshida, Kahan–Li, Blanes–Moan) and 8
(Kahan–Li s17odr8, Suzuki–Umeno, Yoshida D, triple jump), on the ABC flow and the tokamak field:
the max error at a fixed time T over a sweep of step counts n (h = T/n, n growing by 2^{1/4}), the
fitted observed order and error constant C (error ≈ C·h^p), and, for the accuracy targets 1e-6,
1e-9 and 1e-12, the fewest order-1 stages (n × stages per step, ``compose.stages``) that reach
the target. Work is counted in stages, not seconds: it is what a composition costs on any backend
(one stage = one step of the order-1 method). The reference x(T) is DOP853 at rtol 2.3e-14; the
error floor it leaves is measured (finest order-8 run against it) and reported.

    python benchmarks/methods/bench_orders.py [--smoke] [--out benchmarks/methods/results_orders.md]
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser, write_results

from vpforms import compose, integrate, scheme
from vpforms._methods._compose import stages
from vpforms.diagnostics import fit_order, reference_solution
from vpforms.problems import get

METHODS = [(2, None), (4, "suzuki"), (4, "blanes_moan"), (6, "yoshida"), (6, "kahan_li"),
           (6, "blanes_moan"), (8, "kahan_li"), (8, "suzuki_umeno"), (8, "yoshida"), (8, "triple_jump")]
TARGETS = (1e-6, 1e-9, 1e-12)
T = 4.0
RATIO = 2.0 ** 0.25
MAX_WORK = 400_000  # stages per trajectory in one run: the sweep stops there (order 2 stops early)
FLOOR = 1e-13  # the sweep stops once the error is below this (the reference's own error is ~1e-13)


def label(order, name):
    return f"{order}" if name is None else f"{order} {name}"


def problem_points(pname, smoke):
    prob = get(pname)
    if pname == "abc":
        x0 = prob.initial_conditions(2 if smoke else 8, seed=0)
    else:
        x0 = np.asarray(prob.x0)  # 5 field lines, ρ = 0.1 … 0.35 around the magnetic axis
        x0 = x0[:2] if smoke else x0
    return prob, x0


def sweep(method, s, x0, ref, n0, smoke):
    """(n, error) over n = n0·RATIO^k until the error is below FLOOR, stops falling, or the work cap."""
    rows, n, best = [], n0, np.inf
    max_work = 2_000 if smoke else MAX_WORK
    while n * s <= max_work:
        sol = integrate(method, x0, T / n, n, progress=False, backend="jax")
        # a step that fails (a Newton solve of the generic SE+SE at a large h) makes that n "failed"
        err = float(np.max(np.abs(np.asarray(sol.x_final) - ref))) if sol.ok else np.inf
        rows.append((n, err))
        if err < FLOOR or (len(rows) >= 4 and err > 0.7 * best and best < 1e-11):  # on the rounding floor
            break
        best = min(best, err)
        n = max(n + 1, round(n * RATIO))
    return rows


def constant(order, rows):
    """Observed order (plateau-aware fit over errors in [1e-12, 1e-4]) and C = median(err / h^p)."""
    hs = np.array([T / n for n, _ in rows])
    es = np.array([e for _, e in rows])
    sel = (es >= 1e-12) & (es <= 1e-4)
    if sel.sum() < 3:
        return float("nan"), float("nan")
    fit = fit_order(hs[sel], es[sel])
    return fit.order, float(np.median(es[sel] / hs[sel] ** order))


def work_for(target, rows, s):
    """Stages n*·s for the error to reach the target: n* from the last crossing of the sweep (the
    error ≤ target at every larger n swept), by log–log interpolation between the two swept n
    that bracket it, rounded up to a whole step."""
    i = len(rows)
    while i > 0 and rows[i - 1][1] <= target:
        i -= 1
    if i == len(rows):
        return None  # not reached
    n1, e1 = rows[i]
    if i == 0 or not np.isfinite(rows[i - 1][1]):
        return n1 * s
    n0, e0 = rows[i - 1]
    if e0 <= e1:  # flat or rising between them: no interpolation
        return n1 * s
    ln = np.log(n0) + (np.log(target) - np.log(e0)) * (np.log(n1) - np.log(n0)) / (np.log(e1) - np.log(e0))
    return int(np.ceil(np.exp(ln) - 1e-9)) * s


def main(argv=None) -> int:
    warnings.simplefilter("ignore")
    args = parser(__doc__, os.path.join(HERE, "results_orders.md"), rounds=1).parse_args(argv)
    t_start = time.perf_counter()
    methods = METHODS[:2] + METHODS[6:7] if args.smoke else METHODS
    results = {}
    floors = {}
    for pname in ("abc", "tokamak"):
        prob, x0 = problem_points(pname, args.smoke)
        ref = np.asarray(reference_solution(prob.field, x0, T, rtol=2.3e-14, atol=1e-16))
        for order, name in methods:
            t = time.perf_counter()
            m = compose(scheme(prob.field, "SE+SE", recover=False), order, name)
            s = stages(order, name)
            n0 = {2: 16, 4: 4, 6: 3, 8: 2}[order]
            rows = sweep(m, s, x0, ref, n0, args.smoke)
            p, C = constant(order, rows)
            results[pname, order, name] = (s, rows, p, C)
            print(f"{pname:8s} {label(order, name):18s} stages {s:3d}  p = {p:5.2f}  C = {C:9.3e}  "
                  f"min err {min(e for _, e in rows):.1e} at n ≤ {rows[-1][0]}  {time.perf_counter() - t:.1f} s",
                  flush=True)
        floors[pname] = min(e for (pn, o, _), (_, rows, _, _) in results.items() if pn == pname and o == 8
                            for _, e in rows) if not args.smoke else float("nan")

    lines = [
        "# Which composition pays: error against work, orders 2 to 8 (SE+SE, ABC and tokamak)"
        + (" (smoke mode: not a measurement)" if args.smoke else ""),
        "",
        machine("bench_orders.py", time.perf_counter() - t_start, args.smoke),
        "",
        (f"Global error = max over the points of |x_n − x(T)|_∞ at T = {T:g} with h = T/n, against DOP853 "
        "(rtol 2.3e-14, `reference_solution`); ABC: 8 points `initial_conditions(8, seed=0)`; tokamak: "
        "its 5 field lines `x0` (ρ = 0.1 … 0.35 on the midplane). `vpforms.integrate(..., backend=\"jax\")`, "
        "SE+SE without recovery (`recover=False`: the bare composition) composed by "
        "`compose(m, order, scheme)`; a run in which a step fails (large h only) is listed as `failed`. "
        "Work = order-1 stages for the whole run, n × stages per step (`compose.stages`): the cost on "
        "any backend, one stage = one SE+SE step."),
        "",
        (f"Smallest error any order-8 run reached (the floor of reference + rounding): ABC {floors['abc']:.1e}, "
        f"tokamak {floors['tokamak']:.1e}."),
        "",
        "## Observed order and error constant",
        "",
        ("p: plateau-aware log–log slope (`fit_order`) over the errors in [1e-12, 1e-4]; C: median of "
        "err / h^p (p the nominal order) there, so err ≈ C·h^p at this T. Between two methods of the same "
        "order, equal work means h ∝ stages, so the one with the smaller C·stages^p is cheaper at every "
        "accuracy (last columns, relative to the best of its order)."),
        "",
        "| order, scheme | stages | p (ABC) | C (ABC) | p (tokamak) | C (tokamak) | C·s^p rel. (ABC) | C·s^p rel. (tokamak) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    eff = {}
    for pname in ("abc", "tokamak"):
        for order, name in methods:
            s, _, _, C = results[pname, order, name]
            eff[pname, order, name] = C * s**order
    for order, name in methods:
        s = results["abc", order, name][0]
        cells = []
        for pname in ("abc", "tokamak"):
            _, _, p, C = results[pname, order, name]
            cells += [f"{p:.2f}", f"{C:.2e}"]
        rel = []
        for pname in ("abc", "tokamak"):
            best = min(eff[pname, o, n] for o, n in methods if o == order)
            rel.append(f"{eff[pname, order, name] / best:.2f}")
        lines.append(f"| {label(order, name)} | {s} | " + " | ".join(cells) + " | " + " | ".join(rel) + " |")

    lines += ["", "## Pick per accuracy target", "",
              ("Order-1 stages (n × stages, whole run to T) for the error to reach the target: n is the "
              "step count where the sweep last crosses the target (the error is ≤ it at every larger n "
              "swept), interpolated log–log between the two swept n that bracket it and rounded up to a "
              "whole step; — : not reached within the sweep (at most "
              f"{MAX_WORK:,} stages; order 2 is stopped by that cap, not by rounding). **Bold**: the fewest."), ""]
    head = "| order, scheme | " + " | ".join(f"{pn} ≤ {tg:.0e}" for pn in ("abc", "tokamak") for tg in TARGETS) + " |"
    lines += [head, "|---|" + "---:|" * (2 * len(TARGETS))]
    works = {}
    for pname in ("abc", "tokamak"):
        for order, name in methods:
            s, rows, _, _ = results[pname, order, name]
            for tg in TARGETS:
                works[pname, tg, order, name] = work_for(tg, rows, s)
    best = {}
    for pname in ("abc", "tokamak"):
        for tg in TARGETS:
            vals = [(w, o, n) for (pn, t, o, n), w in works.items() if pn == pname and t == tg and w is not None]
            best[pname, tg] = min(vals) if vals else None
    for order, name in methods:
        cells = []
        for pname in ("abc", "tokamak"):
            for tg in TARGETS:
                w = works[pname, tg, order, name]
                c = "—" if w is None else f"{w:,}"
                if best[pname, tg] is not None and w == best[pname, tg][0]:
                    c = f"**{c}**"
                cells.append(c)
        lines.append(f"| {label(order, name)} | " + " | ".join(cells) + " |")
    lines += ["", ("Summary: the composition with the fewest stages, then any within 10 % of it (a tie at "
                   "this resolution), with their stage counts:"), "",
              "| target | ABC | tokamak |", "|---|---|---|"]
    for tg in TARGETS:
        cells = []
        for pname in ("abc", "tokamak"):
            if best[pname, tg] is None:
                cells.append("—")
                continue
            w0 = best[pname, tg][0]
            near = sorted((w, o, n) for (pn, t, o, n), w in works.items()
                          if pn == pname and t == tg and w is not None and w <= 1.1 * w0)
            cells.append("; ".join(f"{'**' if w == w0 else ''}order {label(o, n)}{'**' if w == w0 else ''} ({w:,})"
                                   for w, o, n in near))
        lines.append(f"| {tg:.0e} | " + " | ".join(cells) + " |")

    lines += ["", "## The sweeps", "", "n: error, per method (the raw data of the tables above).", ""]
    for pname in ("abc", "tokamak"):
        lines += [f"### {pname}", ""]
        for order, name in methods:
            s, rows, _, _ = results[pname, order, name]
            lines.append(f"* {label(order, name)} ({s} stages): "
                         + ", ".join(f"{n}: {e:.1e}" if np.isfinite(e) else f"{n}: failed" for n, e in rows))
        lines.append("")
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())

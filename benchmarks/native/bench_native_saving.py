"""What saving costs on the native backend (issue #19 item 2), written to results_native_saving.md.

The generated kernel writes the saved states itself (``vpforms.backends.native.runner.run_saving``:
at most ``CALLS`` kernel calls a run); before, the runner called the kernel once per saved step
(``run_points`` with every saved step as a target — still there, timed here as "one call per
save"). Rows, best of ``--rounds`` after a warm-up, one process:

* ABC, SE+SE (closed form), N = 10⁵ particles × 40 steps: no saves, ``save_every=1``, and one call
  per save;
* the same for N = 100 particles × 4000 steps (few particles, many saves: a Poincaré study's shape).

    PYTHONPATH=src python benchmarks/native/bench_native_saving.py [--smoke]
"""

from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import best_of, machine, native_missing, parser, write_results

import vpforms
from vpforms import problems
from vpforms._solution import saved_steps
from vpforms.backends.native.runner import CALLS, run_points


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_native_saving.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    prob = problems.get("abc")
    m = vpforms.scheme(prob.field, "SE+SE", fast=True, recover=False)
    shapes = [(1000, 10)] if args.smoke else [(100_000, 40), (100, 4000)]
    rounds = 1 if args.smoke else args.rounds
    rows = []
    for N, n in shapes:
        x0 = prob.initial_conditions(N, seed=0)
        runs = {
            "no saves": lambda x0=x0, n=n: vpforms.integrate(m, x0, 0.1, n, progress=False, backend="native"),
            "save_every=1 (the kernel saves)": lambda x0=x0, n=n: vpforms.integrate(
                m, x0, 0.1, n, save_every=1, progress=False, backend="native"),
            "save_every=1, one kernel call per save": lambda x0=x0, n=n: run_points(m, x0, 0.1, saved_steps(n, 1)),
        }
        for f in runs.values():
            f()  # compile / load the kernel, warm the caches
        times = {k: best_of(f, rounds)[0] for k, f in runs.items()}
        base = times["no saves"]
        for k, t in times.items():
            rows.append(f"| N = {N:,} × {n} steps | {k} | {t * 1e9 / (N * n):.1f} | {t / base:.2f}× |")
    lines = ["# What saving costs on the native backend (issue #19 item 2)", "",
             (f"ABC, SE+SE (closed form), native, 2 OpenMP threads. ns per particle-step (best of {rounds}) and "
              f"the ratio to the same run without saves. The kernel now writes the saves itself: ≤ {CALLS} "
              "kernel calls a run; 'one kernel call per save' is the former runner."), "",
             "| run | saving | ns / particle-step | × no saves |", "|---|---|---:|---:|", *rows, "",
             f"Load average at the end: {os.getloadavg()[0]:.1f}.", "",
             machine("bench_native_saving.py", time.perf_counter() - t0, args.smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

"""Cost of the consistency guard (issue #23) when nothing fails, written to results_guard.md.

ABC SE+SE (recover=False) through ``vpforms.integrate``, the same points, with the guard
(``guard_kappa`` = vpforms._guard.KAPPA, the default) and without (``guard_kappa = None``), on the
JAX backend and on the native one; rounds interleaved, best of each.  The guard costs one
evaluation of the field per step (the Euler predictor x + h a(x)).

    python benchmarks/methods/bench_guard.py [--smoke] [--rounds R] [--out benchmarks/methods/results_guard.md]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser  # noqa: E402

import vpforms  # noqa: E402
from vpforms.problems import get  # noqa: E402


def _method(guard: bool):
    m = vpforms.scheme(get("abc").field, "SE+SE", recover=False)
    if not guard:
        m.guard_kappa = None
    return m


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_guard.md"), rounds=5).parse_args(argv)
    t_start = time.perf_counter()
    P = get("abc")
    rows = []
    for backend, N, steps in (("jax", 20_000, 40), ("native", 100_000, 40)):
        if args.smoke:
            N, steps = 500, 4
        if backend == "native" and not vpforms.native.available():
            continue
        x0 = P.initial_conditions(N, seed=0)
        methods = {"guard": _method(True), "no guard": _method(False)}
        best = {k: np.inf for k in methods}
        out = {}
        for k, m in methods.items():  # compile / build first
            out[k] = vpforms.integrate(m, x0, 0.1, steps, progress=False, backend=backend)
        for _ in range(1 if args.smoke else args.rounds):
            for k, m in methods.items():
                t = time.perf_counter()
                sol = vpforms.integrate(m, x0, 0.1, steps, progress=False, backend=backend)
                np.asarray(sol.x_final)
                best[k] = min(best[k], time.perf_counter() - t)
        # the guard changes no step where nothing fails; the compiled code differs, so the results
        # may differ by rounding (XLA fusion, gcc's contraction): the largest difference
        same = float(np.max(np.abs(np.asarray(out["guard"].x_final) - np.asarray(out["no guard"].x_final))))
        ns = {k: 1e9 * v / (N * steps) for k, v in best.items()}
        rows.append((backend, N, steps, ns["guard"], ns["no guard"], ns["guard"] / ns["no guard"],
                     same, int(out["guard"].n_failed)))
    lines = [
        "# Cost of the consistency guard (issue #23)",
        "",
        "ABC SE+SE, h = 0.1, nothing fails; ns per particle-step, best of interleaved rounds "
        "(`vpforms.integrate`, one process).",
        "",
        "| backend | N | steps | with guard (ns) | without (ns) | ratio | max abs Δx (rounding) | failed |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {b} | {N:,} | {s} | {g:.2f} | {n:.2f} | {r:.3f} | {same:.1e} | {f} |"
              for b, N, s, g, n, r, same, f in rows]
    lines += ["", machine("bench_guard.py", time.perf_counter() - t_start, args.smoke), ""]
    open(args.out, "w").write("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Cost of composition in the JAX backend (issue #9): order 1, 2, 4 side by side on ABC.

ns per particle-step through ``vpforms.integrate`` for the SE+SE fast path (order 1), its order-2
composition Ψ*_{h/2}∘Ψ_{h/2} and Suzuki's 5-stage order 4, plus the generic (engine) SE+SE and its
compositions; the ratios to the order-1 step of the same backend. The rounds are interleaved and the
best of each taken (the machine may be shared).

    python benchmarks/methods/bench_compose.py [--smoke] [--out benchmarks/methods/results_compose.md]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser, write_results  # noqa: E402

from vpforms import compose, integrate, scheme
from vpforms.problems import get

H, STEPS = 0.1, 20


def methods(field):
    out = {}
    for label, fast in (("fast", True), ("generic", False)):
        m1 = scheme(field, "SE+SE", fast=fast)
        out[(label, 1)] = m1
        out[(label, 2)] = compose(m1, 2)
        out[(label, 4)] = compose(m1, 4)
    return out


def time_run(method, x0, steps):
    t = time.perf_counter()
    sol = integrate(method, x0, H, steps, progress=False)
    np.asarray(sol.x_final)
    return time.perf_counter() - t


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_compose.md"), rounds=5).parse_args(argv)
    t_start = time.perf_counter()
    sizes = (64,) if args.smoke else (10_000, 100_000)
    rounds = 1 if args.smoke else args.rounds
    steps = 2 if args.smoke else STEPS
    field = get("abc").field
    ms = methods(field)
    rng = np.random.default_rng(0)
    best = {}
    for N in sizes:
        x0 = rng.uniform(0.0, 2 * np.pi, size=(N, 3))
        for m in ms.values():  # compile (and warm) every method first
            time_run(m, x0[: min(N, 8192)], steps)
        for _ in range(rounds):  # interleaved rounds, best of each
            for key, m in ms.items():
                dt = time_run(m, x0, steps) / (N * steps) * 1e9
                best[key, N] = min(best.get((key, N), np.inf), dt)
    # check: the fast and generic compositions are the same map
    x = rng.uniform(0.0, 2 * np.pi, size=(16, 3))
    diff = max(
        float(np.max(np.abs(np.asarray(ms["fast", k].step(x, H)) - np.asarray(ms["generic", k].step(x, H)))))
        for k in (1, 2, 4)
    )
    lines = [
        f"# Composition cost in the JAX backend: ABC, h = {H}, {steps} steps per run"
        + (" (smoke mode: not a measurement)" if args.smoke else ""),
        "",
        machine("bench_compose.py", time.perf_counter() - t_start, args.smoke),
        "",
        "ns per particle-step via `vpforms.integrate` (compile excluded; best of "
        f"{rounds} interleaved rounds) and, in brackets, the ratio to the order-1 step of the same row "
        "group (order 1 = SE+SE, order 2 = SE+SE*∘SE+SE, order 4 = Suzuki 5-stage of order 2).",
        "",
        "| SE+SE | N | order 1 | order 2 | order 4 |",
        "|---|---:|---:|---:|---:|",
    ]
    for label in ("fast", "generic"):
        for N in sizes:
            b1 = best[(label, 1), N]
            cells = [f"{best[(label, k), N]:,.0f} ({best[(label, k), N] / b1:.2f}×)" for k in (1, 2, 4)]
            lines.append(f"| {label} | {N:,} | " + " | ".join(cells) + " |")
    lines += ["", f"Check: max |fast − generic| after one step, orders 1, 2, 4, 16 points = {diff:.1e} (the same map)", ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())

"""What a Poincaré section costs on the native backend (issue #21 item 1), written to results_native_sections.md.

The kernel's ``vp_sections`` records the steps where a line crosses the section surface, and only
those are located on the method's step family (``vp_locate``; the JAX locator for the few it
leaves undecided). Side by side in one process, best of ``--rounds`` after a warm-up:

* the plain native trace (``vpforms.integrate(..., backend="native")``, no saves);
* the native section of the same particle-steps;
* the JAX section (reference; one round; not at 10⁴ lines × 2000 steps, where it runs for minutes).

Problems: the tokamak in toroidal coordinates (u, φ, Z), SE+SE order 2, the section φ = 0 (both
directions), h = 0.05, N lines × 2000 steps; ABC, SE+SE order 2, the planes x₃ = 0 (mod 2π),
N = 10⁵ particles × 40 steps.

    PYTHONPATH=src python benchmarks/native/bench_native_sections.py [--smoke]
"""

from __future__ import annotations

import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import interleaved, jax_cell, native_missing, parser, results_tail, write_results

import vpforms
from vpforms import problems
from vpforms.diagnostics import poincare_section
from vpforms.fieldlines import toroidal_section


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_native_sections.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    tok = problems.get("tokamak", coordinates="toroidal")
    abc = problems.get("abc")
    mt = vpforms.compose(vpforms.scheme(tok.field, "SE+SE"), 2)
    ma = vpforms.compose(vpforms.scheme(abc.field, "SE+SE"), 2)
    h = 0.05
    if args.smoke:
        cases = [("tokamak φ = 0", mt, tok, 20, 50, True), ("ABC x₃ = 0 mod 2π", ma, abc, 200, 10, True)]
    else:  # (label, method, problem, N, steps, with the JAX reference)
        cases = [("tokamak φ = 0", mt, tok, 100, 2000, True), ("tokamak φ = 0", mt, tok, 1000, 2000, True),
                 ("tokamak φ = 0", mt, tok, 10_000, 2000, False), ("ABC x₃ = 0 mod 2π", ma, abc, 100_000, 40, True)]
    rounds = 1 if args.smoke else args.rounds
    rows = []
    for label, m, prob, N, n, with_jax in cases:
        x0 = prob.initial_conditions(N, seed=0)
        hh = h if prob is tok else 0.1

        def trace(m=m, x0=x0, n=n, hh=hh):
            return vpforms.integrate(m, x0, hh, n, progress=False, backend="native")

        def section(backend, m=m, x0=x0, n=n, hh=hh, prob=prob):
            if prob is tok:
                return toroidal_section(m, x0, hh, n, phi=0.0, progress=False, backend=backend).section
            return poincare_section(m, x0, hh, n, axis=2, value=0.0, period=2 * math.pi, direction=0,
                                    progress=False, backend=backend)

        trace(), section("native")  # compile / load the kernels, warm the caches
        times, out = interleaved({"trace": trace, "native": lambda: section("native")}, rounds)
        sec = out["native"]
        assert sec.backend == "native" and sec.n_fallback == 0
        cell = "—"
        if with_jax:
            cell, ref = jax_cell(lambda: section("jax"), N * n, times["native"])
            assert ref.points.shape == sec.points.shape
        M = sec.points.shape[0]
        rows.append(f"| {label} | {N:,} × {n} | {M:,} | {times['trace'] * 1e9 / (N * n):.1f} | "
                    f"{times['native'] * 1e9 / (N * n):.1f} | **{times['native'] / times['trace']:.2f}×** | "
                    f"{cell} |")
    lines = ["# What a Poincaré section costs on the native backend (issue #21 item 1)", "",
             (f"SE+SE order 2, native, 2 OpenMP threads; ns per particle-step (best of {rounds} interleaved "
              "rounds): the plain native trace (no saves), the native section of the same particle-steps "
              "(crossing steps recorded by the kernel, located by `vp_locate` on the step family), their "
              "ratio (goal ≤ 1.3×), and the JAX section (one round) for reference. The JAX and native "
              "sections are the same crossings (asserted: same count)."), "",
             "| problem | lines × steps | crossings | trace ns | section ns | section / trace | JAX section ns |",
             "|---|---|---:|---:|---:|---:|---:|", *rows, "",
             *results_tail("bench_native_sections.py", time.perf_counter() - t0, args.smoke)]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

"""What a wall costs on the native backend (issue #21 item 4), written to results_native_walls.md.

The kernel's ``vp_wall`` stops each line at the first step outside the (R, Z) polygon and
accumulates the connection length and the toroidal angle; the exits are then located on the step
family (JAX, only for the lines that hit). Side by side in one process, best of ``--rounds`` after a
warm-up:

* the plain native trace of the same lines and steps (``vpforms.integrate(..., backend="native")``,
  no saves, no wall);
* the native wall trace (``trace_to_wall(..., backend="native")``), everything included;
* the JAX wall trace (reference; one round; not at 10⁴ lines).

Walls: a box no line reaches (the pure cost of the test and the accumulators: every line runs all
its steps, as in the plain trace) and a 128-gon that cuts the outer flux surfaces (lines stop, so the
wall trace does fewer steps than the plain one). Problems: the tokamak in toroidal coordinates
(u, φ, Z) and in Cartesian coordinates, SE+SE order 2, h = 0.05, N lines × 2000 steps.

    PYTHONPATH=src python benchmarks/native/bench_native_walls.py [--smoke]
"""

from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import interleaved, jax_cell, native_missing, parser, results_tail, write_results

import numpy as np

import vpforms
from vpforms import problems
from vpforms.fieldlines import Wall, trace_to_wall


def _starts(N: int, toroidal: bool) -> np.ndarray:
    """N lines on the outboard midplane, R ∈ [1.02, 1.24], Z = 0 (the axis is at R = 1)."""
    R = np.linspace(1.02, 1.24, N)
    if toroidal:
        return np.stack([R**2 / 2, 0 * R, 0 * R], 1)
    return np.stack([R, 0 * R, 0 * R], 1)


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_native_walls.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    h = 0.05
    walls = {"box, no hit": Wall.box(0.3, 1.7, -0.8, 0.8), "128-gon, cuts": Wall.circle(1.0, 0.0, 0.25, 128)}
    fields = {"tokamak (u, φ, Z)": (problems.get("tokamak", coordinates="toroidal"), True),
              "tokamak Cartesian": (problems.get("tokamak"), False)}
    if args.smoke:
        sizes = [(20, 50, True)]
    else:  # (N, steps, with the JAX reference)
        sizes = [(100, 2000, True), (1000, 2000, True), (10_000, 2000, False)]
    rounds = 1 if args.smoke else args.rounds
    rows = []
    for flabel, (prob, tor) in fields.items():
        m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), 2)
        for N, n, with_jax in sizes:
            x0 = _starts(N, tor)

            def trace(m=m, x0=x0, n=n):
                return vpforms.integrate(m, x0, h, n, progress=False, backend="native")

            trace()
            for wlabel, wall in walls.items():
                def walled(backend, m=m, x0=x0, n=n, wall=wall):
                    return trace_to_wall(m, x0, h, n, wall, progress=False, backend=backend)

                walled("native")  # compile / load the kernel and the exit locator
                times, out = interleaved({"trace": trace, "native": lambda: walled("native")}, rounds)
                hits = out["native"]
                assert hits.backend == "native" and hits.n_failed == 0
                cell = "—"
                if with_jax:
                    cell, ref = jax_cell(lambda: walled("jax"), N * n, times["native"])
                    assert np.array_equal(ref.step, hits.step) and np.array_equal(ref.status, hits.status)
                ps = N * n
                rows.append(f"| {flabel} | {wlabel} | {N:,} × {n} | {hits.n_hit:,} | "
                            f"{times['trace'] * 1e9 / ps:.1f} | {times['native'] * 1e9 / ps:.1f} | "
                            f"**{times['native'] / times['trace']:.2f}×** | {cell} |")
    lines = ["# What a wall costs on the native backend (issue #21 item 4)", "",
             (f"SE+SE order 2, h = {h}, native, 2 OpenMP threads; ns per requested particle-step (best of "
              f"{rounds} interleaved rounds): the plain native trace (no saves, no wall), the native wall trace "
              "of the same lines and steps (the kernel's test, connection length and angle; the exits "
              "located on the step family), their ratio, and the JAX wall trace (one round) for reference. "
              "JAX and native stop the same lines at the same steps (asserted). With the box no line hits: "
              "every line runs all its steps in both, so the ratio is the wall's own cost; with the "
              "128-gon the lines that hit stop early."), "",
             "| field | wall | lines × steps | hits | trace ns | wall ns | wall / trace | JAX wall ns |",
             "|---|---|---|---:|---:|---:|---:|---:|", *rows, "",
             *results_tail("bench_native_walls.py", time.perf_counter() - t0, args.smoke)]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

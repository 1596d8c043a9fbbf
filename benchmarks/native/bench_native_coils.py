"""Coils traced directly (Biot–Savart, no grid) on the native backend (issue #20, "coils in C"),
written to results_native_coils.md.

One coil set — the l = 2 stellarator of :func:`vpforms.coils.l2_stellarator` with coarser polygons
(``--points-tf`` vertices per TF coil, ``--points-period`` per field period of each helical
winding) — traced by SE+SE (recover=False), h = 0.01, in (u = R²/2, φ, Z), three ways, in one
process:

* native, direct: the coils' Hanson–Hirshman A evaluated in generated C, the segments passed at
  run time, the SE gauge integral along φ by the 32-node Gauss–Legendre rule (the JAX nodes);
* JAX, direct: the same map (``toroidal_field(coils, box)``), few lines and steps — it is slow;
* native, spline: the same coils' A sampled on a 40×32×40 (R, φ, Z) grid and splined
  (:func:`vpforms.problems.coil_fields.spline_coil_field`), the cheap approximation.

ns per particle-step = (best of R runs of 2n steps − best of R runs of n steps) / (N·n): the cost
of stepping without a run's fixed costs (JAX direct: best run of n steps / (N·n)); compile = first
call − best call. The native direct and
JAX direct rows start from the same points, and the report gives their largest difference.

    PYTHONPATH=src python benchmarks/native/bench_native_coils.py [--smoke] [--rounds R] [--out ...]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import best_of, native_missing, parser, results_tail, write_results

import vpforms
from vpforms.coils import l2_stellarator
from vpforms.problems.coil_fields import spline_coil_field
from vpforms.toroidal import box_from_cylindrical, to_toroidal, toroidal_field

R_AXIS = 0.983112  # the l2_stellarator's magnetic axis at φ = 0 (vpforms.coils.library)


def main(argv=None) -> int:
    p = parser(__doc__, os.path.join(HERE, "results_native_coils.md"), rounds=2)
    p.add_argument("--points-tf", type=int, default=8, help="vertices per TF coil (default 8)")
    p.add_argument("--points-period", type=int, default=4, help="helical vertices per period (default 4)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    smoke = args.smoke
    rounds = 1 if smoke else args.rounds
    ptf, ppp = (6, 4) if smoke else (args.points_tf, args.points_period)
    coils = l2_stellarator(points_per_tf=ptf, points_per_period=ppp)
    n_seg = int(coils.segments()[0].shape[0])
    # well inside the windings (r ≤ 0.15 m), as bench_real_fields.py's direct field
    box = box_from_cylindrical((0.88, 1.1), (0.0, 2 * np.pi / coils.nfp), (-0.1, 0.1))
    direct = toroidal_field(coils, box, name="stellarator coils (Biot–Savart)", origin=(0.5, 0.0, 0.0))
    grid = (12, 8, 12) if smoke else (40, 32, 40)
    spline, spline_err = spline_coil_field(coils, (0.80, 1.18), (-0.18, 0.18), n_R=grid[0], n_phi=grid[1],
                                           n_Z=grid[2], name="stellarator coils (spline)")
    rng = np.random.default_rng(0)
    N, NJ, n, nj = (8, 2, 2, 1) if smoke else (16, 2, 4, 1)
    r = rng.uniform(0.02, 0.08, N)
    x0 = np.asarray(to_toroidal(np.c_[R_AXIS + r, np.zeros(N), np.zeros(N)]))
    h = 0.01
    runs = [  # (label, backend, method, x0, n)
        ("direct (Biot–Savart)", "native", vpforms.scheme(direct, "SE+SE", recover=False), x0, n),
        ("direct (Biot–Savart)", "jax", vpforms.scheme(direct, "SE+SE", recover=False), x0[:NJ], nj),
        (f"spline of A ({grid[0]}×{grid[1]}×{grid[2]})", "native", vpforms.scheme(spline, "SE+SE", recover=False),
         x0, 20 * n),
    ]
    rows, per, finals = [], {}, {}
    for label, backend, m, x, steps in runs:
        def go(k, m=m, x=x, backend=backend):
            return vpforms.integrate(m, x, h, k, progress=False, backend=backend)

        tc = time.perf_counter()
        go(steps)
        first = time.perf_counter() - tc
        best, sol1 = best_of(lambda k=steps: go(k), rounds)
        best2, sol = best_of(lambda k=2 * steps: go(k), rounds)
        assert sol.stats["backend"] == backend, sol.stats
        # JAX direct: one step is ~1 s, its run's fixed costs are noise; the difference of two
        # such runs is noise too, so the best n-step run / (N·n) (fixed costs included)
        per[label, backend] = (best if backend == "jax" else best2 - best) * 1e9 / (len(x) * steps)
        finals[label, backend] = np.asarray(sol1.xs)[:, -1]
        failed = int(np.sum(np.asarray(sol.status) != 0))
        rows.append((label, backend, len(x), steps, per[label, backend], first - best, failed))
        print(rows[-1], flush=True)
    d = "direct (Biot–Savart)"
    # the same map: the native and JAX direct lines after nj steps (native run again for nj steps)
    xn = np.asarray(vpforms.integrate(runs[0][2], x0[:NJ], h, nj, progress=False, backend="native").xs)[:, -1]
    agree = float(np.max(np.abs(xn - finals[d, "jax"])))
    nat = per[d, "native"]
    lines = ["# Coils traced directly on the native backend (issue #20, coils in C)", "",
             (f"l2_stellarator(points_per_tf={ptf}, points_per_period={ppp}): {len(coils)} coils, "
              f"{n_seg} segments, nfp = {coils.nfp}. SE+SE (recover=False), h = {h}, in (u = R²/2, φ, Z), "
              "`vpforms.integrate`, one process; ns per particle-step = (best of "
              f"{rounds} runs of 2n steps − best of {rounds} runs of n steps) / (N·n) (JAX direct: best "
              "run of n steps / (N·n), its fixed costs included); compile = first call − best call. Direct: the coils' A (Hanson–Hirshman) inside the SE gauge integral "
              "along φ (32-node Gauss–Legendre); native reads the segments at run time. Spline: A "
              f"sampled on the grid and splined, max|B_spline − B_coils|/max|B_coils| = {spline_err:.2g}. "
              f"Native and JAX direct after {nj} steps from the same {NJ} points differ by at most "
              f"{agree:.2g}."), "",
             "| field | backend | N | n | ns / particle-step | ÷ native direct | compile (s) | failed |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, backend, Np, steps, t, comp, failed in rows:
        lines.append(f"| {label} | {backend} | {Np:,} | {steps} | {t:,.0f} | {t / nat:.3g} | {comp:.1f} | {failed} |")
    lines += ["", (f"JAX direct ÷ native direct: **{per[d, 'jax'] / nat:.1f}×**; native direct ÷ native "
                   f"spline: {nat / per[runs[2][0], 'native']:.0f}×."), ""]
    lines += results_tail("bench_native_coils.py", time.perf_counter() - t0, smoke)
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())

"""S1/S2 (Quispel's correction maps) on the native backend where f_c is a quadrature (issue #20),
written to results_native_corrections.md.

Quispel's correction integral f_c = ∫_c^u w(s) ds has a closed form only for SymPy fields whose
integrand is polynomial in s; elsewhere the JAX method takes the n-point Gauss–Legendre rule, and
the native kernel now loops over the same nodes (``codegen/potentials._correction_quadrature``).
One process, recover=False, h = 0.01, ``vpforms.integrate``; ns per particle-step = (best of
``--rounds`` runs of 2n steps − best of runs of n steps) / (N·n), so a run's fixed costs cancel;
compile = first call − best call (n steps). Rows:

* Lotka–Volterra (SymPy; ``integral="quadrature"`` forces the rule its closed form would avoid);
* the tokamak's vector potential splined on a 48×32×48 (R, φ, Z) grid, in (u, φ, Z)
  (``bench_native_splines.tokamak_spline``): the integrand evaluates the spline at Q(s), a point
  that holds a spline value;
* the l = 2 stellarator's coils traced directly (Biot–Savart A, Hanson–Hirshman), native only:
  JAX compiles this quadrature of a quadrature for minutes.

    PYTHONPATH=src python benchmarks/native/bench_native_corrections.py [--smoke]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import fresh_native_cache, machine, native_missing, parser, per_step, write_results
from bench_native_splines import tokamak_spline

import vpforms
from vpforms import problems
from vpforms.coils import l2_stellarator
from vpforms.toroidal import box_from_cylindrical, to_toroidal, toroidal_field


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_native_corrections.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    smoke = args.smoke
    rounds = 1 if smoke else args.rounds
    fresh_native_cache()
    # (native N, JAX N, n) per field: a spline step costs ~100× a formula's, a coil step ~10⁴×
    sizes = ({"lv": (100, 10, 4), "spl": (100, 10, 4), "co": (4, 0, 2)} if smoke else
             {"lv": (20_000, 500, 50), "spl": (2_000, 50, 20), "co": (16, 0, 4)})
    h = 0.01
    N = max(v[0] for v in sizes.values())
    NC = sizes["co"][0]
    lv = problems.get("lotka_volterra")
    tok = problems.get("tokamak")
    spl = tokamak_spline(*((12, 8, 12) if smoke else (48, 32, 48)))
    coils = l2_stellarator(points_per_tf=8, points_per_period=4)
    box = box_from_cylindrical((0.88, 1.1), (0.0, 2 * np.pi / coils.nfp), (-0.1, 0.1))
    direct = toroidal_field(coils, box, name="l2 stellarator coils (Biot–Savart)", origin=(0.5, 0.0, 0.0))
    x_lv = np.asarray(lv.initial_conditions(N, seed=0))
    x_tor = np.asarray(to_toroidal(tok.initial_conditions(N, seed=0)))
    rng = np.random.default_rng(0)  # near the l2_stellarator's axis (R ≈ 0.983 at φ = 0)
    x_co = np.asarray(to_toroidal(np.c_[0.983112 + 0.02 * rng.uniform(-1, 1, NC), np.zeros(NC),
                                         0.02 * rng.uniform(-1, 1, NC)]))
    runs = []  # (field label, class, backend, method, x0, n)
    for label, field, x, kw, (Nn, NJ, n) in (
            ("Lotka–Volterra (SymPy, quadrature forced)", lv.field, x_lv, {"integral": "quadrature"}, sizes["lv"]),
            ("tokamak (spline of A)", spl, x_tor, {}, sizes["spl"]),
            ("l2 stellarator coils (Biot–Savart)", direct, x_co, {}, sizes["co"])):
        for cls in ("S1", "S2") if NJ else ("S1",):
            m = vpforms.scheme(field, cls, recover=False, **kw)
            assert m.integral.startswith("quadrature"), (label, m.integral)
            runs.append((label, cls, "native", m, x[:Nn], n))
            if NJ:
                runs.append((label, cls, "jax", m, x[:NJ], n))
    rows, per = [], {}
    for label, cls, backend, m, x0, n in runs:
        def go(steps, m=m, x0=x0, backend=backend):
            return vpforms.integrate(m, x0, h, steps, progress=False, backend=backend)

        per[label, cls, backend], compile_s, sol = per_step(go, n, len(x0), rounds, strict=not smoke)
        assert sol.stats["backend"] == backend, sol.stats
        failed = int(np.sum(np.asarray(sol.status) != 0))
        rows.append((label, cls, backend, len(x0), n, per[label, cls, backend], compile_s, failed))
        print(rows[-1], flush=True)
    lines = ["# S1/S2 correction maps with a quadrature f_c on the native backend (issue #20)", "",
             (f"recover=False, h = {h}, `vpforms.integrate`, one process; ns per particle-step = "
              f"(best of {rounds} runs of 2n steps − best of {rounds} runs of n steps) / (N·n); "
              "compile = first call − best call. f_c by the 32-node Gauss–Legendre rule in both "
              "backends. The coils are traced natively only (JAX compiles them for minutes)."), "",
             "| field | class | backend | N | n | ns / particle-step | JAX ÷ native (same field) | compile (s) | failed |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, cls, backend, Np, n, t, comp, failed in rows:
        jn = (per[label, cls, "jax"] / t) if backend == "native" and (label, cls, "jax") in per else None
        lines.append(f"| {label} | {cls} | {backend} | {Np:,} | {n} | {t:,.0f} | "
                     f"{'' if jn is None else f'{jn:.0f}×'} | {comp:.1f} | {failed} |")
    lines += ["", f"Load average at the end: {os.getloadavg()[0]:.1f}.", "",
              machine("bench_native_corrections.py", time.perf_counter() - t0, smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

"""Cost of tracing the fields people have (issue #20), written to results_real_fields.md.

One process, SE+SE (recover=False) through ``vpforms.integrate``, ns per particle-step after
compilation (best of interleaved rounds), compile time reported separately:

* the closed-form tokamak of the problem library (``tokamak``: polynomial potentials), JAX and
  native — the baseline;
* ``coil_stellarator``: the l = 2 stellarator's coils → cubic spline of A on a 40×32×40
  (u, φ, Z) grid → B = ∇×A, JAX (the native backend does not evaluate splines yet);
* ``coil_tokamak``: TF coils splined + the plasma ring's exact elliptic-integral potential, JAX;
* with ``--direct``, the stellarator's coils directly: Hanson–Hirshman A of 1760 segments in
  (u, φ, Z), the pairs by periodic-aware Gauss–Legendre quadrature (32 nodes) of A — JAX. Not in
  the default run: measured 134 s and 19.7 GB peak memory for the first call (two lines, two
  steps; `/usr/bin/time -v`), i.e. not a practical way to trace coils; the spline is.

    python benchmarks/fields/bench_real_fields.py [--smoke] [--direct] [--rounds R] [--out benchmarks/fields/results_real_fields.md]
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
from vpforms.coils import l2_stellarator  # noqa: E402
from vpforms.problems import get  # noqa: E402
from vpforms.toroidal import box_from_cylindrical, toroidal_field  # noqa: E402


def _direct_stellarator():
    coils = l2_stellarator()
    # a box well inside the windings (r ≤ 0.15 m): the 32-node quadrature of A along a grid line
    # that passes close to a conductor does not reach the 1e-8 the potential check asks for
    box = box_from_cylindrical((0.88, 1.1), (0.0, 2 * np.pi / coils.nfp), (-0.1, 0.1))
    return toroidal_field(coils.A, box, nfp=coils.nfp, name="stellarator coils (Biot–Savart)",
                          origin=(0.5, 0.0, 0.0))


def main(argv=None) -> int:
    p = parser(__doc__, os.path.join(HERE, "results_real_fields.md"), rounds=3)
    p.add_argument("--direct", action="store_true", help="also trace the coils directly (slow, ~20 GB)")
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    stell = get("coil_stellarator")
    cases = [
        ("tokamak (closed form)", get("tokamak").field, get("tokamak").initial_conditions, "jax", 2000, 50),
        ("tokamak (closed form)", get("tokamak").field, get("tokamak").initial_conditions, "native", 20000, 50),
        ("coil_stellarator (spline of A)", stell.field, stell.initial_conditions, "jax", 2000, 50),
        ("coil_tokamak (spline + exact ring)", get("coil_tokamak").field, get("coil_tokamak").initial_conditions,
         "jax", 2000, 50),
    ]
    if args.direct:
        cases.append(("stellarator coils, direct Biot–Savart", _direct_stellarator(), stell.initial_conditions,
                      "jax", 2, 2))
    rows = []
    for label, field, sampler, backend, N, steps in cases:
        if args.smoke:
            N, steps = min(N, 20), min(steps, 3)
        if backend == "native" and not vpforms.native.available():
            continue
        x0 = sampler(N, seed=0)
        if "direct" in label:  # inside its box
            x0 = x0[np.sqrt(2 * x0[:, 0]) < 1.09][:N] if len(x0) else x0
        m = vpforms.scheme(field, "SE+SE", recover=False)
        t = time.perf_counter()
        sol = vpforms.integrate(m, x0, 0.01, steps, progress=False, backend=backend)
        np.asarray(sol.x_final)
        first = time.perf_counter() - t
        best = np.inf
        for _ in range(1 if args.smoke else args.rounds):
            t = time.perf_counter()
            sol = vpforms.integrate(m, x0, 0.01, steps, progress=False, backend=backend)
            np.asarray(sol.x_final)
            best = min(best, time.perf_counter() - t)
        rows.append((label, backend, N, steps, 1e9 * best / (N * steps), first - best, int(sol.n_failed)))
        print(rows[-1], flush=True)
    base = {b: ns for lab, b, _, _, ns, _, _ in rows if lab.startswith("tokamak (closed")}
    lines = [
        "# Tracing coil and gridded fields (issue #20)",
        "",
        "SE+SE (recover=False), h = 0.01, `vpforms.integrate`, one process; ns per particle-step "
        "(best of rounds, after compilation); compile = first call − best call.",
        "",
        "| field | backend | N | steps | ns / particle-step | × closed-form tokamak (JAX) | "
        "× closed-form tokamak (native) | compile (s) | failed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for lab, b, N, s, ns, comp, fail in rows:
        rj = ns / base["jax"] if "jax" in base else float("nan")
        rn = ns / base["native"] if "native" in base else float("nan")
        lines.append(f"| {lab} | {b} | {N:,} | {s} | {ns:,.0f} | {rj:.2f} | {rn:.1f} | {comp:.1f} | {fail} |")
    lines += ["", machine("bench_real_fields.py", time.perf_counter() - t_start, args.smoke), ""]
    open(args.out, "w").write("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

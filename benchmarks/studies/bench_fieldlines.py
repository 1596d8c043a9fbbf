"""Cost of the field-line studies (issue #21) against the plain trace, written to results_fieldlines.md.

One process, the tokamak problem in (u = R²/2, φ, Z) (ε = 0.01, (2, 1) islands), SE+SE composed to
order 2 (recover=False), JAX backend, N lines × S steps; best of interleaved rounds after compilation
(compile time reported separately):

* ``integrate`` — the plain trace of the same particle-steps, JAX (baseline) and native C;
* ``toroidal_section`` at φ = 0 — detection inside the scan, location on the step family after;
* ``rotational_transform`` — the weighted Birkhoff sums inside the scan;
* ``trace_to_wall`` — a box wall that no line reaches (the scan with its per-step wall test);
* ``magnetic_axis`` — Newton on the return map with its exact Jacobian, and the ι of the axis.

    python benchmarks/studies/bench_fieldlines.py [--smoke] [--rounds R] [--out benchmarks/studies/results_fieldlines.md]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import best_of, machine, parser, write_results  # noqa: E402

import vpforms  # noqa: E402
from vpforms import problems  # noqa: E402
from vpforms.fieldlines import Wall, magnetic_axis, rotational_transform, toroidal_section, trace_to_wall  # noqa: E402


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_fieldlines.md"), rounds=3).parse_args(argv)
    t_start = time.perf_counter()
    N, S = (4, 64) if args.smoke else (100, 2000)
    rounds = 1 if args.smoke else args.rounds
    prob = problems.get("tokamak", coordinates="toroidal")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE", recover=False), order=2)
    h = 0.05
    R = np.linspace(1.05, 1.35, N)
    x0 = np.stack([0.5 * R * R, np.zeros(N), np.zeros(N)], axis=1)
    wall = Wall.box(0.4, 1.6, -0.7, 0.7)
    runs = {
        "integrate, JAX (baseline)": lambda: vpforms.integrate(m, x0, h, S, progress=False, backend="jax"),
        "integrate, native C": lambda: vpforms.integrate(m, x0, h, S, progress=False, backend="native"),
        "toroidal_section φ = 0": lambda: toroidal_section(m, x0, h, S, progress=False, backend="jax"),
        "rotational_transform": lambda: rotational_transform(m, x0, h, S, (1.0, 0.0), progress=False),
        "trace_to_wall (no hit)": lambda: trace_to_wall(m, x0, h, S, wall, progress=False),
    }
    compile_s, best = {}, dict.fromkeys(runs, np.inf)
    for name, fn in runs.items():
        t = time.perf_counter()
        fn()
        compile_s[name] = time.perf_counter() - t
    for _ in range(rounds):
        for name, fn in runs.items():
            best[name] = min(best[name], best_of(fn, 1)[0])
    t = time.perf_counter()
    ax = magnetic_axis(m, (1.02, 0.01), h)
    t_axis_first = time.perf_counter() - t
    t_axis, ax = best_of(lambda: magnetic_axis(m, (1.02, 0.01), h), rounds)
    sec = runs["toroidal_section φ = 0"]()
    base = best["integrate, JAX (baseline)"]
    lines = [
        "# Field-line studies: cost against the plain trace (issue #21)",
        "",
        machine("bench_fieldlines.py", time.perf_counter() - t_start, args.smoke),
        "",
        f"Tokamak in (u, φ, Z), ε = 0.01; SE+SE ∘ order 2 (recover=False), h = {h}; {N} lines × {S} steps "
        f"(≈ {S * h * 1.8 / (2 * np.pi):.0f} transits), JAX; best of {rounds} interleaved rounds after compilation.",
        "",
        "| study | wall time (s) | ns / line-step | × plain trace | first call incl. compile (s) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name in runs:
        lines.append(f"| {name} | {best[name]:.3f} | {best[name] / (N * S) * 1e9:.0f} | {best[name] / base:.2f} | "
                     f"{compile_s[name]:.1f} |")
    lines += [
        "",
        f"Section: {len(sec)} crossings located on the step family ({sec.section.n_fallback} by the chord).",
        f"Magnetic axis: (R, Z) = ({ax.R:.12g}, {ax.Z:.3g}), residual {ax.residual:.1e}, {ax.kind}, "
        f"ι = {ax.iota:.10g} (q = {ax.q:.10g}); {t_axis:.2f} s per call after compilation, "
        f"{t_axis_first:.1f} s for the first (compiles the return map, its Jacobian and the tangent winding; "
        "later calls reuse them).",
        "",
        "These rows run on JAX (the section pinned to backend=\"jax\"); native sections: results_native_sections.md.",
    ]
    return write_results(args.out, "\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())

"""W7-X with φ as the time on a domain that follows the plasma (issue #38), against simsopt's reference.

    PYTHONPATH=$PWD/src python benchmarks/peers/bench_w7x_phi_time.py [--inset 0.1] [--grid-A 96x192x96]
        [--grid-K 96x128x96] [--degree 5] [--fit quasi] [--degree-K 5] [--fit-K interpolate]
        [--settings 6:40,6:80,8:60,6:60:blanes_moan] [--long 1000]

The field is :func:`vpforms.problems.devices.phi_time_grid_field`'s: the spline of A (by default of
degree 5, its quasi-interpolant on the whole box), and K of the φ-time field fitted on the image of a
smaller domain (the default one moved ``--inset`` m inward), where B^φ keeps its sign — on the rectangular
box it does not (coils). The 20 lines of ``w7x_reference.py`` are traced with the φ-exact SE+SE
composed to ``order`` at ``n`` steps per field period (natively): every n-th step is a bean plane.
φ increases (B^φ < 0: backwards along B), so by stellarator symmetry the k-th period end is the
reference's crossing 2(k + 1) with Z negated. Per setting: the error at 50 transits (max and
median over the lines) and the wall time of 50 and of ``--long`` transits (the kernel compiled
before). Writes ``results_w7x_phi_time.md`` and ``.json`` (``--append``: adds to them), which
``bench_vpforms_w7x.py`` draws in its figure of error against wall time.

``--simsopt PYTHON`` (simsopt's own virtual environment; never in CI): after vpforms' rows, in the
same invocation, ``run_simsopt_w7x.py interp`` runs each ``--simsopt-settings`` (degree:k:tol, cells
(20, 40, 10)·k) with that interpreter on one thread, one setting after the other (nothing else
running), and the results file gets simsopt's rows and, per vpforms row at ≤ 1e-5 m, the ratio of
its wall time to that of simsopt's fastest setting at ≤ 1e-5 m (issue #38's measure) — side by
side, from one run.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from w7x_reference import load_reference, section_error  # noqa: E402

NFP = 5


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", default=str(HERE / "data" / "w7x_reference.npz"))
    ap.add_argument("--inset", type=float, default=0.1)
    ap.add_argument("--grid-A", default="96x192x96")
    ap.add_argument("--grid-K", default="96x128x96")
    ap.add_argument("--settings", default="6:40,6:80,8:60",
                    help="order:steps per field period[:composition], … (composition: vpforms.compose's scheme, "
                         "default its default for the order)")
    ap.add_argument("--long", type=int, default=1000)
    ap.add_argument("--degree", type=int, default=5, help="of the spline of A")
    ap.add_argument("--fit", default="quasi", choices=("interpolate", "quasi"),
                    help="of A; quasi: the local quasi-interpolant on the whole box, coils inside")
    ap.add_argument("--degree-K", type=int, default=None, help="of the spline of K (default: --degree)")
    ap.add_argument("--fit-K", default="interpolate", choices=("interpolate", "quasi"))
    ap.add_argument("--out", default=str(HERE / "results_w7x_phi_time.md"))
    ap.add_argument("--append", action="store_true", help="add this run's table to the results file")
    ap.add_argument("--jax-cache", action="store_true",
                    help="JAX's persistent compilation cache on, as the command line has it (a second run "
                         "then builds without compiling)")
    ap.add_argument("--simsopt", default=None, metavar="PYTHON",
                    help="simsopt's interpreter: run its InterpolatedField settings after vpforms' (module docstring)")
    ap.add_argument("--simsopt-settings", default="5:2:1e-10,5:1:1e-11",
                    help="degree:k:tol, … (k: cells (20, 40, 10)·k; one process per degree:k, its tols in it)")
    args = ap.parse_args(argv)
    if args.jax_cache:
        from vpforms._cache import enable_jax_cache

        enable_jax_cache()

    import vpforms
    from vpforms.phitime import from_phi_time, phi_time_scheme, to_phi_time
    from vpforms.problems.devices import grid_field, phi_time_grid_field

    ref = load_reference(args.reference)
    R0 = np.asarray(ref["start_R"], float)
    gA, gK = (tuple(int(v) for v in g.split("x")) for g in (args.grid_A, args.grid_K))
    load = os.getloadavg()[0]
    t = time.perf_counter()
    grid_field("w7x", gA, degree=args.degree, fit=args.fit)  # A alone (cached: phi_time_grid_field reuses it)
    t_A = time.perf_counter() - t
    t = time.perf_counter()
    k_K = args.degree if args.degree_K is None else args.degree_K
    pf, err_A = phi_time_grid_field("w7x", gA, gK, inset=args.inset, degree=args.degree, fit=args.fit,
                                    degree_K=k_K, fit_K=args.fit_K)
    t_K = time.perf_counter() - t
    y0 = np.asarray(to_phi_time(pf, np.c_[R0 ** 2 / 2, 0 * R0, 0 * R0]))
    rows = []
    for s in args.settings.split(","):
        order, n, *comp = s.split(":")
        order, n, comp = int(order), int(n), (comp[0] if comp else None)
        m = phi_time_scheme(pf, "SE+SE", order=order, composition=comp)
        h = 2 * np.pi / NFP / n
        vpforms.integrate(m, y0[:2], h, n, backend="native", progress=False)  # the kernel compiled
        t = time.perf_counter()
        sol = vpforms.integrate(m, y0, h, n * NFP * 50, save_every=n, backend="native", progress=False)
        t50 = time.perf_counter() - t
        x = np.asarray(from_phi_time(pf, sol.xs[:, 1:]))
        R, Z = np.sqrt(2 * x[..., 0]), x[..., 2]
        nl, nk = R.shape
        line, j = np.repeat(np.arange(nl), nk), np.tile(2 * (np.arange(nk) + 1), nl)
        emax, emed = section_error(ref, R.ravel(), -Z.ravel(), line, j, plane="bean")
        t, c = time.perf_counter(), time.process_time()
        long = vpforms.integrate(m, y0, h, n * NFP * args.long, save_every=n, backend="native", progress=False)
        t_long, c_long = time.perf_counter() - t, time.process_time() - c
        rows.append((order if comp is None else f"{order} ({comp})", n, emax, emed, int(sol.n_failed), t50, t_long,
                     c_long, int(long.n_failed)))
        print(rows[-1], flush=True)
    sims = _simsopt_runs(args.simsopt, args.simsopt_settings, args.long) if args.simsopt else []
    lines = [
        "# W7-X, φ as the time on a domain that follows the plasma (issue #38)", "",
        f"`python benchmarks/peers/bench_w7x_phi_time.py {' '.join(argv if argv is not None else sys.argv[1:])}` — "
        f"vpforms {vpforms.__version__}, {os.cpu_count()} cores, load {load:.1f} before. A: {args.grid_A} spline of degree "
        f"{args.degree}, " + ("its quasi-interpolant within reach of the default domain (coils in that reach)"
                               if args.fit == "quasi" else "interpolating, on the default domain") +
        f", built in {t_A:.1f} s, B error {err_A:.1e} on the default domain; K: {args.grid_K} spline of degree {k_K} "
        f"({'quasi-interpolant' if args.fit_K == 'quasi' else 'interpolating'}) on the default domain moved "
        f"{args.inset:g} m inward, built in {t_K:.1f} s (JAX's compilation cache "
        f"{'on' if args.jax_cache else 'off'}), b error {pf.phi_time_spline_error:.1e} where defined "
        f"({pf.phi_time_spline_coverage:.0%} of the domain). 20 lines, error on the bean planes against simsopt's "
        f"tol-1e-12 reference. Peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB. The native "
        f"kernel runs the 20 lines as {min(int(os.environ.get('OMP_NUM_THREADS') or os.cpu_count() or 1), 20)} "
        "blocks, one per OpenMP thread (vp_block); CPU s: the process's "
        "(time.process_time).", "",
        f"| order | steps per period | error@50 max (m) | median (m) | failed | 50 transits s | {args.long} transits s "
        f"| {args.long} transits CPU s | failed |",
        "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {o} | {n} | {a:.2e} | {b:.2e} | {f} | {t1:.2f} | {t2:.1f} | {c2:.1f} | {f2} |"
              for o, n, a, b, f, t1, t2, c2, f2 in rows]
    if sims:
        lines += ["", f"simsopt in the same invocation (`run_simsopt_w7x.py interp`, {args.simsopt}, OMP_NUM_THREADS=1, "
                  "after vpforms' rows): InterpolatedField, 20 lines, the same reference; its build apart.", "",
                  f"| simsopt setting | build s | error@50 max (m) | {args.long} transits s | CPU s | load before |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| degree {r['degree']}, {'×'.join(map(str, r['cells']))}, tol {r['tol']:g} | {r['build_s']:.1f} "
                  f"| {r['error_max_m']:.2e} | {r['long_s']:.1f} | {r['long_cpu_s']:.1f} | {r['load'][0]:.2f} |" for r in sims]
        lines += ["", "| vpforms row | error@50 max (m) | s | simsopt's fastest at ≤ 1e-5 m | its s | ratio |",
                  "|---|---|---|---|---|---|"]
        for o, n, a, _, _, _, t2, _, _ in rows:
            ok = [r for r in sims if r["error_max_m"] <= 1e-5] if a <= 1e-5 else []
            if ok:
                best = min(ok, key=lambda r: r["long_s"])
                lines.append(f"| {o}, n = {n} | {a:.2e} | {t2:.1f} | degree {best['degree']}, "
                             f"{'×'.join(map(str, best['cells']))}, tol {best['tol']:g} ({best['error_max_m']:.2e}) "
                             f"| {best['long_s']:.1f} | **{t2 / best['long_s']:.2f}×** |")
    text = "\n".join(lines) + "\n"
    if args.append and Path(args.out).is_file():
        text = Path(args.out).read_text() + "\n" + "\n".join(lines[2:]) + "\n"
    Path(args.out).write_text(text)
    js = Path(args.out).with_suffix(".json")
    runs = json.loads(js.read_text())["runs"] if args.append and js.is_file() else []
    runs.append({"grid_A": args.grid_A, "grid_K": args.grid_K, "inset": args.inset, "degree": args.degree, "fit": args.fit,
                 "degree_K": k_K, "fit_K": args.fit_K, "build_A_s": t_A, "build_K_s": t_K,
                 "A_error": err_A, "K_error": pf.phi_time_spline_error, "load_before": load,
                 "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                 "rows": [dict(zip(("order", "n", "error_max_m", "error_median_m", "failed", "t50_s", "long_s",
                                    "long_cpu_s", "long_failed"), r)) for r in rows], "long_transits": args.long,
                 "simsopt": sims})
    js.write_text(json.dumps({"tool": "vpforms φ-time", "version": vpforms.__version__, "runs": runs}, indent=1))
    print("\n".join(lines))
    return 0


def _simsopt_runs(python: str, settings: str, transits: int) -> list[dict]:
    """simsopt's InterpolatedField settings (degree:k:tol, …) run by ``run_simsopt_w7x.py interp`` with
    ``python`` on one thread, one process per degree:k (its build once), in order: a row per tol."""
    import subprocess
    import tempfile

    groups: dict[tuple[int, int], list[float]] = {}
    for item in settings.split(","):
        d, k, tol = item.split(":")
        groups.setdefault((int(d), int(k)), []).append(float(tol))
    out = []
    with tempfile.TemporaryDirectory() as work:
        for (d, k), tols in groups.items():
            cmd = [python, str(HERE / "run_simsopt_w7x.py"), "interp", "--degree", str(d), "--k", str(k),
                   "--tols", *map(str, tols), "--transits", str(transits), "--work", work]
            subprocess.run(cmd, check=True, cwd=HERE, env={**os.environ, "OMP_NUM_THREADS": "1"})
            part = json.loads((Path(work) / f"interp_d{d}_k{k}.json").read_text())
            for r in part["runs"]:
                out.append({"degree": d, "cells": part["cells"], "tol": r["tol"], "build_s": part["build_seconds"],
                            "error_max_m": r["errors"]["bean_max_m"], "long_s": r["seconds"],
                            "long_cpu_s": r["cpu_seconds"], "load": r["load"]})
                print(out[-1], flush=True)
    return out


if __name__ == "__main__":
    raise SystemExit(main())

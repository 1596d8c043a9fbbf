"""vpforms on W7-X against simsopt's reference (issue #38 item 5; vpforms' side, in vpforms' venv, never in CI).

    PYTHONPATH=$PWD/src python benchmarks/peers/bench_vpforms_w7x.py [--grids 48x96x48,64x128x64]
        [--orders 2,4] [--h 0.05,0.025] [--long 1000] [--reference benchmarks/peers/data/w7x_reference.npz]

The reference (``run_simsopt_w7x.py reference``, simsopt's ``compute_fieldlines`` on its direct
``BiotSavart``, tol 1e-12) holds the crossings of 20 lines started on the outboard midplane of φ = 0
from the axis to the last closed surface; ``w7x_reference.py`` says how they are numbered. vpforms
traces the same field — W7-X's coils by simsopt's own quadrature (``device("w7x",
rule="quadrature")``: the same B to 1e-15) — splined on a grid that follows the default domain
(:func:`vpforms.problems.devices.grid_field`), with SE+SE composed to order 2 or 4 at fixed h (time
t with dx/dt = B in (u = R²/2, φ, Z), natively), and its crossings of the bean planes φ ≡ 0 (mod
2π/5) are compared with the reference's (crossing j = 2(k + 1) for vpforms' k-th crossing, k from 0).

Per setting: the grid's build time and its B error on the domain, the error at 50 transits (max and
median over the 20 lines, bean planes), the wall time of 20 lines × ``--long`` transits (crossings
only; the kernel's compile apart: it is timed on a second, identical call), the peak RSS. Writes
``benchmarks/peers/results_vpforms_w7x.json`` and ``.md`` (a table), and — with simsopt's results
file beside it (``results_simsopt_w7x.json``) — the figure ``w7x_error_vs_time.png``: error at 50
transits against the wall time of 1 000 transits, both tools.
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

TRANSITS_ACCURACY = 50


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _trace(method, x0, h, transits, nfp, steps_per_transit):
    """Crossings (R, Z, line, k) of the bean planes over ``transits`` transits, and the seconds."""
    from vpforms.fieldlines import toroidal_section

    n = int(np.ceil(transits * steps_per_transit * 1.02)) + 4
    t = time.perf_counter()
    sec = toroidal_section(method, x0, h, n, phi=0.0, nfp=nfp, direction=0, progress=False)
    dt = time.perf_counter() - t
    keep = sec.t > 1e-12  # the start on φ = 0 is not a crossing
    R, Z, line = sec.R[keep], sec.Z[keep], sec.line[keep]
    k = np.concatenate([np.arange(np.count_nonzero(line == i)) for i in range(len(x0))])
    order = np.lexsort((sec.t[keep], line))
    return R[order], Z[order], line[order], k, dt, sec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", default=str(HERE / "data" / "w7x_reference.npz"))
    ap.add_argument("--grids", default="48x96x48,64x128x64")
    ap.add_argument("--orders", default="2,4")
    ap.add_argument("--h", default="0.05,0.025")
    ap.add_argument("--long", type=int, default=1000, help="transits of the timed long run (default 1000)")
    ap.add_argument("--out", default=str(HERE / "results_vpforms_w7x"))
    ap.add_argument("--figure-only", action="store_true",
                    help="only redraw the figure from the results files (this one's JSON, simsopt's, the φ-time bench's)")
    args = ap.parse_args(argv)
    if args.figure_only:
        _figure(json.loads(Path(args.out + ".json").read_text()), HERE / "results_simsopt_w7x.json",
                HERE / "w7x_error_vs_time.png")
        return 0

    import jax

    import vpforms
    from vpforms.problems.devices import grid_field
    from vpforms.toroidal import to_toroidal

    ref = load_reference(args.reference)
    nfp = 5
    R0 = np.asarray(ref["start_R"], float)
    Z0 = np.asarray(ref["start_Z"], float) if "start_Z" in ref else np.zeros_like(R0)
    x0 = np.asarray(to_toroidal(np.c_[R0, np.zeros_like(R0), Z0]))
    load = os.getloadavg()[0]
    rows = []
    for g in args.grids.split(","):
        grid = tuple(int(v) for v in g.split("x"))
        t = time.perf_counter()
        field, err = grid_field("w7x", grid)
        t_build = time.perf_counter() - t
        print(f"grid {g}: built in {t_build:.1f} s, B error on the domain {err:.2e}", flush=True)
        for order in (int(o) for o in args.orders.split(",")):
            t = time.perf_counter()
            m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=order)
            t_method = time.perf_counter() - t
            for h in (float(v) for v in args.h.split(",")):
                # steps per transit from one step's dφ on the middle line
                x1 = np.asarray(m.step_with_status(x0[len(x0) // 2], h)[0])
                spt = 2 * np.pi / abs(float(x1[1] - x0[len(x0) // 2][1]))
                tc = time.perf_counter()
                R, Z, line, k, dt_first, sec = _trace(m, x0, h, TRANSITS_ACCURACY, nfp, spt)
                t_first = time.perf_counter() - tc
                failed = int(np.count_nonzero(sec.status != 0))
                sel = k < TRANSITS_ACCURACY * nfp
                emax, emed = section_error(ref, R[sel], Z[sel], line[sel], 2 * (k[sel] + 1), plane="bean")
                # the long run, timed on a second call (the kernel is compiled by then)
                _, _, _, _, dt_long, sec_long = _trace(m, x0, h, args.long, nfp, spt)
                row = {"grid": g, "grid_build_s": t_build, "spline_error": err, "order": order, "h": h,
                       "steps_per_transit": spt, "method_build_s": t_method, "first_50_transits_s": t_first,
                       "error_max_m": emax, "error_median_m": emed, "failed_lines": failed,
                       "long_transits": args.long, "long_s": dt_long,
                       "long_failed_lines": int(np.count_nonzero(sec_long.status != 0)),
                       "backend": sec.section.backend, "peak_rss_mb": _peak_rss_mb()}
                rows.append(row)
                print(json.dumps(row), flush=True)
    out = {"tool": "vpforms", "version": vpforms.__version__, "jax": jax.__version__, "load_before": load,
           "cores": os.cpu_count(), "reference": os.path.relpath(args.reference, HERE.parent.parent),
           "reference_tol": float(ref["tol"]), "rows": rows}
    Path(args.out + ".json").write_text(json.dumps(out, indent=1))
    lines = ["# vpforms on W7-X against simsopt's tol-1e-12 reference (issue #38 item 5)", "",
             f"`{' '.join(['python', 'benchmarks/peers/bench_vpforms_w7x.py'] + (argv or sys.argv[1:]))}` — "
             f"vpforms {vpforms.__version__}, {os.cpu_count()} cores, load {load:.1f} before; 20 lines, error on the "
             f"bean planes at {TRANSITS_ACCURACY} transits; the long run's time excludes the kernel's compile.", "",
             "| grid | build s | B error (domain) | order | h | steps/transit | error@50 max (m) | median (m) "
             f"| {args.long} transits s | failed | peak RSS MB |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['grid']} | {r['grid_build_s']:.1f} | {r['spline_error']:.1e} | {r['order']} | {r['h']:g} "
                     f"| {r['steps_per_transit']:.0f} | {r['error_max_m']:.2e} | {r['error_median_m']:.2e} "
                     f"| {r['long_s']:.1f} | {r['failed_lines']} | {r['peak_rss_mb']:.0f} |")
    Path(args.out + ".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    _figure(out, HERE / "results_simsopt_w7x.json", HERE / "w7x_error_vs_time.png")
    return 0


def _figure(ours: dict, simsopt_path: Path, path: Path) -> None:
    """Error at 50 transits against the wall time of the long run, vpforms and simsopt."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6), constrained_layout=True)
    for r in ours["rows"]:
        ax.loglog(r["long_s"], r["error_max_m"], "o", color="C0")
        ax.annotate(f"{r['grid']} o{r['order']} h={r['h']:g}", (r["long_s"], r["error_max_m"]), fontsize=7)
    ax.plot([], [], "o", color="C0", label="vpforms (grid on the domain, SE+SE in t)")
    phi_time = HERE / "results_w7x_phi_time.json"  # bench_w7x_phi_time.py: φ as the time on a domain
    if phi_time.is_file():
        for run in json.loads(phi_time.read_text())["runs"]:
            for r in run["rows"]:
                ax.loglog(r["long_s"], r["error_max_m"], "^", color="C2")
                ax.annotate(f"A {run['grid_A']} K {run['grid_K']} o{r['order']} n={r['n']}",
                            (r["long_s"], r["error_max_m"]), fontsize=6)
        ax.plot([], [], "^", color="C2", label="vpforms φ-time (K on the plasma's domain, φ-exact SE+SE)")
    if simsopt_path.is_file():  # results_simsopt_w7x.json: parts → interp_* (runs per tol), direct_*
        s = json.loads(simsopt_path.read_text())
        for key, part in s.get("parts", {}).items():
            if key.startswith("interp_"):
                for r in part.get("runs", []):
                    ax.loglog(r["seconds"], r["errors"]["bean_max_m"], "s", color="C3")
                    ax.annotate(f"d{part['degree']} {'×'.join(map(str, part['cells']))} tol {r['tol']:g}",
                                (r["seconds"], r["errors"]["bean_max_m"]), fontsize=6)
        ax.plot([], [], "s", color="C3", label="simsopt InterpolatedField (compute_fieldlines)")
    # simsopt re-run in the session of a φ-time run (run_simsopt_w7x.py interp --work …, its part
    # copied to data/simsopt_w7x_interp_d<degree>_k<k>_s<session>.json): the table above ran on a loaded machine
    reruns = sorted((HERE / "data").glob("simsopt_w7x_interp_*_s*.json"))
    for p in reruns:
        part = json.loads(p.read_text())
        for r in part.get("runs", []):
            ax.loglog(r["seconds"], r["errors"]["bean_max_m"], "D", color="C1")
            ax.annotate(f"d{part['degree']} {'×'.join(map(str, part['cells']))} tol {r['tol']:g} "
                        f"({p.stem.rsplit('_', 1)[1]})", (r["seconds"], r["errors"]["bean_max_m"]), fontsize=6)
    if reruns:
        ax.plot([], [], "D", color="C1", label="simsopt InterpolatedField, re-run beside the φ-time bench")
    ax.set_xlabel(f"wall time, 20 lines × {ours['rows'][0]['long_transits']} transits (s)")
    ax.set_ylabel("section error at 50 transits, max over lines (m)")
    ax.set_title("W7-X: accuracy against wall time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())

"""Accuracy against wall time, and surfaces at equal wall time: vpforms (φ as the time) and DESC on the
coil stellarator (issue #24, item 4) — never in CI.

The problem of ``bench_peers_issue_size.py``: the l = 2, m = 5 stellarator coils as one MAKEGRID file,
100 field lines from (R, Z) = (R_axis + 0.02 … 0.12 m, 0) on φ = 0, sections at φ = 2πk/5.

1. **Accuracy against wall time**: 100 lines × ``--transits`` (100) transits. Error = the max over all
   lines of the (R, Z) distance of the section points from scipy DOP853 (rtol 1e-12) on the coils' own
   Biot–Savart B; wall = the 100 lines × 100 transits call, with the fixed cost per call (a first
   2-line, 1-transit call: compilation, or the kernel's load from the cache) apart.
   * vpforms, native: the φ-time field of the 96×64×96 spline of A with K splined on a 48×256×96
     (v, φ, Z) grid (``phi_time_field(..., grid=)``), the φ-exact SE+SE composed to order 2, 4 and 6,
     n steps per field period; section points are step boundaries (``save_every=n``), mapped back
     to (R, Z) by U (timed with the run).
   * DESC (``peers/run_desc.py``): Biot–Savart of the polylines at every stage, Tsit5 in φ, one
     accuracy run per tolerance ``--rtols`` (rtol = atol).
2. **One surface at equal wall time**: the line of the 100 nearest R = R_axis + 0.0867 m (1.0698 m;
   ``bench_peers_surfaces.py`` follows the one at 1.0587 m): vpforms φ-time for ``--long-transits`` (10⁵) transits, and for 10⁴;
   DESC at rtol 1e-8 (its default) for ``--desc-long-transits`` (10⁴: 10⁵ would take ~30 min).
   Each row gives its wall time and the distance of the section points from the Fourier curve fitted
   to the first 20 transits (``bench_peers_surfaces.thickness``: RMS over the fit window, over the last
   1000 transits, and the linear trend per 1000 transits), so that rows of equal wall time compare.

    PYTHONPATH=src python benchmarks/peers/bench_peers_curves.py [--tools vpforms,desc] [--reuse desc] [--smoke]
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # the peer scripts, _peer_common.py; benchmarks/_bench.py
from _bench import machine, parser, write_results  # noqa: E402
from _peer_common import dop853_section  # noqa: E402
from bench_peers import R_AXIS, RK_TOL, _fit_residual  # noqa: E402
from bench_peers_issue_size import BOX_R, BOX_Z, NFP, _error, run_peers  # noqa: E402
from bench_peers_surfaces import thickness  # noqa: E402

PNG = os.path.join(os.path.dirname(os.path.dirname(HERE)), "docs", "figures", "stellarator_accuracy_time.png")  # the docs show it


def phi_time_of_coils(coils, grid, kgrid):
    """(φ-time field, B error of the spline of A, build seconds): the coils' A splined on ``grid``
    (R, φ, Z), then K splined on ``kgrid`` (v, φ, Z)."""
    from vpforms.phitime import phi_time_field
    from vpforms.problems.coil_fields import spline_coil_field

    t = time.perf_counter()
    field, spline_err = spline_coil_field(coils, BOX_R, BOX_Z, n_R=grid[0], n_phi=grid[1], n_Z=grid[2], name="peers")
    pf = phi_time_field(field, grid=kgrid, name="peers φ-time")
    return pf, spline_err, time.perf_counter() - t


def trace(pf, m, x_R, n, transits, warm=False):
    """Section points (R, Z), shape (sections, lines), of ``transits`` transits with n steps per
    field period: every n-th step is on φ = 2πk/5, mapped back to (R, Z) by U. ``warm``: only compile
    the map back (U's vectorised Newton, JAX) for this shape, so that the timed call does not."""
    import vpforms
    from vpforms.phitime import from_phi_time, to_phi_time

    y0 = np.asarray(to_phi_time(pf, np.c_[x_R**2 / 2, np.zeros_like(x_R), np.zeros_like(x_R)]))
    if warm:
        return from_phi_time(pf, np.repeat(y0[:, None], NFP * transits, axis=1))
    sol = vpforms.integrate(m, y0, 2 * np.pi / NFP / n, n * NFP * transits, save_every=n, backend="native",
                            progress=False)
    x = np.asarray(from_phi_time(pf, sol.xs[:, 1:]))
    return np.sqrt(2 * x[..., 0]).T, x[..., 2].T, sol.n_failed


def reference(coils, x_R, n_tr, work):
    """((R, Z) section points, seconds): scipy DOP853 (rtol 1e-12) on the coils' Biot–Savart B for
    the lines from (x_R, 0) over n_tr transits, kept in ``work`` and read back when it is there."""
    import jax

    path = os.path.join(work, f"reference_{len(x_R)}x{n_tr}.npz")
    if os.path.exists(path):
        z = np.load(path)
        return (z["R"], z["Z"]), float(z["t"])
    B = jax.jit(coils.B)
    t = time.perf_counter()
    ref = dop853_section(lambda x: np.asarray(B(x)), x_R, np.zeros(len(x_R)), NFP, n_tr * NFP)
    t_ref = time.perf_counter() - t
    np.savez(path, R=ref[0], Z=ref[1], t=t_ref)
    return ref, t_ref


def timed_trace(pf, m, x_R, n, n_tr):
    """(R, Z, failed, wall, fixed): the lines traced for n_tr transits, timed apart from the fixed
    cost (a 2-line, 1-transit call: the kernel's compilation or its load) and from U's compilation."""
    t = time.perf_counter()
    trace(pf, m, x_R[:2], n, 1)
    fixed = time.perf_counter() - t
    trace(pf, m, x_R, n, n_tr, warm=True)
    t = time.perf_counter()
    R, Z, failed = trace(pf, m, x_R, n, n_tr)
    return R, Z, failed, time.perf_counter() - t, fixed


def run_vpforms(pf, x_R, ref, settings, n_tr):
    """One accuracy row per (order, n)."""
    from vpforms.phitime import phi_time_scheme

    rows = []
    for order, n in settings:
        m = phi_time_scheme(pf, "SE+SE", order=order)
        R, Z, failed, wall, t_fixed = timed_trace(pf, m, x_R, n, n_tr)
        err, _ = _error(R, Z, *ref, n_tr * NFP)
        rows.append(dict(tool="vpforms", setting=f"φ-exact SE+SE ∘ order {order}, {n} steps per field period "
                         f"({n * NFP} per transit)", error=err, wall=wall, fixed=t_fixed, failed=failed,
                         load=os.getloadavg()[0]))
        print(rows[-1], flush=True)
    return rows


def surface(R, Z):
    """thickness() and the mean residual over the last 1000 transits: a drift of the line off its
    surface moves the mean; a line that stays on its surface (or librates in an island about it)
    keeps it, whatever its spread."""
    fl, tail, slope, tr = thickness(R, Z)
    t, d = _fit_residual(np.asarray(R), np.asarray(Z), 20)
    return fl, tail, slope, tr, float(np.mean(d[t > t[-1] - 1000]))


def run_vpforms_long(pf, R0, order, n, transits):
    """The long line: (R, Z) of its section points and the wall time, per number of transits."""
    from vpforms.phitime import phi_time_scheme

    m = phi_time_scheme(pf, "SE+SE", order=order)
    trace(pf, m, np.array([R0]), n, 1)  # compiled / loaded apart
    out = []
    for tr in transits:
        trace(pf, m, np.array([R0]), n, tr, warm=True)
        t = time.perf_counter()
        R, Z, failed = trace(pf, m, np.array([R0]), n, tr)
        out.append((tr, R[:, 0], Z[:, 0], time.perf_counter() - t, failed))
        print("vpforms long", tr, out[-1][3], flush=True)
    return out


def plot(rows, path, n_tr):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for tool, marker in (("vpforms", "o"), ("DESC", "s")):
        rr = sorted((r for r in rows if r["tool"] == tool), key=lambda r: r["wall"])
        if rr:
            ax.loglog([r["wall"] for r in rr], [r["error"] for r in rr], marker=marker, label=tool)
            for r in rr:
                ax.annotate(r["short"], (r["wall"], r["error"]), fontsize=7, xytext=(4, 3),
                            textcoords="offset points")
    ax.set_xlabel(f"wall time, 100 lines × {n_tr} transits, compile excluded (s, 2 cores)")
    ax.set_ylabel(f"max section error over {n_tr} transits (m)")
    ax.set_title("l = 2 stellarator coils: accuracy against wall time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_peers_curves.md"), rounds=1)
    ap.add_argument("--venvs", default=os.environ.get("VPFORMS_PEER_VENVS", "/work/peers"))
    ap.add_argument("--work", default=None, help="work folder (default: a temporary one); the reference is kept there")
    ap.add_argument("--tools", default="vpforms,desc", help="comma-separated subset to run")
    ap.add_argument("--reuse", default="", help="desc: its <work>/desc.json of an earlier run is re-analysed")
    ap.add_argument("--rtols", default="1e-6,1e-8,1e-10", help="DESC's tolerances (rtol = atol)")
    ap.add_argument("--transits", type=int, default=100)
    ap.add_argument("--long-transits", type=int, default=100_000)
    ap.add_argument("--desc-long-transits", type=int, default=10_000)
    ap.add_argument("--png", default=PNG)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    from vpforms.coils import l2_stellarator, write_makegrid

    smoke = args.smoke
    n_lines, n_tr = (4, 2) if smoke else (100, args.transits)
    grid, kgrid = ((12, 8, 12), (8, 16, 8)) if smoke else ((96, 64, 96), (48, 256, 96))
    settings = [(2, 4)] if smoke else [(2, 16), (2, 32), (4, 12), (4, 20), (6, 12), (6, 16), (6, 24)]
    long_order, long_n = (2, 4) if smoke else (4, 20)
    long_tr = [3, 6] if smoke else sorted({10_000, args.long_transits})
    desc_long = 3 if smoke else args.desc_long_transits
    rtols = [float(t) for t in args.rtols.split(",")]
    work = args.work or tempfile.mkdtemp(prefix="vpforms-peers-curves-")
    os.makedirs(work, exist_ok=True)
    coils = l2_stellarator()
    write_makegrid(coils, os.path.join(work, "coils.l2_stellarator"))
    x_R = R_AXIS + np.linspace(0.02, 0.12, n_lines)
    long_i = int(np.argmin(np.abs(x_R - (R_AXIS + 0.0867))))
    rng = np.random.default_rng(0)
    Rc, ph, Zc = rng.uniform(0.9, 1.1, 5), rng.uniform(0, 2 * np.pi, 5), rng.uniform(-0.08, 0.08, 5)
    with open(os.path.join(work, "problem.json"), "w") as fh:
        json.dump({"coils_file": "coils.l2_stellarator", "nfp": NFP, "R0": x_R.tolist(), "Z0": [0.0] * n_lines,
                   "accuracy_transits": n_tr, "short_transits": 1, "long_line": long_i,
                   "long_transits": {"desc": desc_long}, "rk_tol": RK_TOL, "rk_tols": rtols,
                   "check_points": np.c_[Rc * np.cos(ph), Rc * np.sin(ph), Zc].tolist(), "own_reference": False}, fh)

    ref, t_ref = reference(coils, x_R, n_tr, work)
    print(f"reference {t_ref:.0f} s", flush=True)

    tools = args.tools.split(",")
    rows, long_rows, field_note = [], [], ""
    if "vpforms" in tools:
        pf, spline_err, t_build = phi_time_of_coils(coils, grid, kgrid)
        field_note = (f"vpforms' field: the {grid[0]}×{grid[1]}×{grid[2]} spline of A (B error {spline_err:.1e} "
                      f"against the coils), K on a {kgrid[0]}×{kgrid[1]}×{kgrid[2]} (v, φ, Z) grid (b error "
                      f"{pf.phi_time_spline_error:.1e}); built once in {t_build:.0f} s, not in the wall times.")
        rows += run_vpforms(pf, x_R, ref, settings, n_tr)
        for tr, R, Z, wall, failed in run_vpforms_long(pf, x_R[long_i], long_order, long_n, long_tr):
            long_rows.append(("vpforms", f"φ-exact SE+SE ∘ order {long_order}, {long_n} steps per field period",
                              tr, wall, surface(R, Z), failed))
    results, failures = run_peers([t for t in tools if t == "desc"], args.venvs, work)
    reused = []
    if "desc" in args.reuse.split(",") and "desc" not in tools and os.path.exists(os.path.join(work, "desc.json")):
        with open(os.path.join(work, "desc.json")) as fh:
            results["desc"] = json.load(fh)
        reused.append("desc")
    for res in results.values():
        for run in res["runs"]:
            if run["label"] == "long":
                long_rows.append((res["tool"], f"{res['version']}: Tsit5 rtol=atol={run['rtol']:g}", run["transits"],
                                  run["t"], surface(np.asarray(run["R"])[:, 0], np.asarray(run["Z"])[:, 0]), 0))
                continue
            err, _ = _error(run["R"], run["Z"], *ref, n_tr * NFP)
            # DESC recompiles per call: its wall less its 1-transit call (compilation + 1 transit)
            rows.append(dict(tool=res["tool"], setting=f"{res['version']}: {run['label']}", error=err,
                             wall=run["t_acc"] - run["t_short"], call=run["t_acc"], fixed=run["t_short"], failed=0,
                             load=res["loadavg_end"][0]))
    for r in rows:
        r["short"] = (r["setting"].split("∘ ")[1].split(" (")[0].replace("order ", "o").replace(" steps per field period", "/period")
                      if r["tool"] == "vpforms" else r["setting"].split("rtol=atol=")[1])
    png = os.path.join(os.path.dirname(os.path.abspath(args.out)), os.path.basename(args.png)) if smoke else args.png
    if rows:
        plot(rows, png, n_tr)

    t1 = [f"| tool | settings | error at {n_tr} transits, {n_lines} lines (m) | wall time, {n_lines} lines × {n_tr} "
          "transits, compile excluded (s) | the call as timed (s) | fixed cost per call (s) | failed | load |",
          "|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in sorted(rows, key=lambda r: (r["tool"] != "vpforms", -r["error"])):
        t1.append(f"| {r['tool']} | {r['setting']} | {r['error']:.1e} | {r['wall']:.1f} | {r.get('call', r['wall']):.1f} | "
                  f"{r['fixed']:.1f} | {r['failed']} | {r['load']:.1f} |")
    t2 = ["| tool | settings | transits | wall time (s) | RMS residual, fit window (m) | RMS residual, last 1000 "
          "transits (m) | mean residual, last 1000 transits (m) | trend per 1000 transits (m) |",
          "|---|---|---:|---:|---:|---:|---:|---:|"]
    for tool, setting, tr, wall, (fl, tail, slope, _, mean), failed in long_rows:
        t2.append(f"| {tool} | {setting} | {tr} | {wall:.1f} | {fl:.1e} | {tail:.1e} | {mean:+.1e} | {slope:+.1e} |"
                  + (f" ({failed} failed)" if failed else ""))
    text = "\n".join([
        "# Accuracy against wall time, and one surface at equal wall time: vpforms (φ as the time) and DESC", "",
        (f"The l = 2 stellarator coils of `results_peers.md` (one MAKEGRID file); {n_lines} lines from R = R_axis + "
         f"0.02 … 0.12 m, Z = 0. Error = max over all lines of the (R, Z) distance of the {n_tr * NFP} section points "
         f"(φ = 2πk/5, {n_tr} transits) from scipy DOP853 (rtol 1e-12) on the coils' Biot–Savart B ({t_ref:.0f} s). "
         "vpforms: native; its accuracy is bounded below by its spline of A and of K (the B and b errors "
         "below), not by the method. DESC: Biot–Savart of the polylines at every Tsit5 stage; it recompiles "
         "on every call, so its wall time with compile excluded is its call less its 1-transit call (the fixed "
         "cost). The plot shows the wall times with compile excluded. One tool at a time on the same 2 cores."), "",
        *([field_note, ""] if field_note else []),
        f"![accuracy against wall time]({os.path.relpath(png, os.path.dirname(os.path.abspath(args.out)))})", "",
        "## Accuracy against wall time", "", *t1, "",
        (f"## One surface at equal wall time: the line from R = {x_R[long_i]:.4f} m"), "",
        ("Residual: distance of each section point from the Fourier curve ρ(θ) fitted to its first 20 transits "
         "(`bench_peers_surfaces.thickness`). A line that drifts off its surface moves the mean residual and "
         "has a trend; a line that stays on its surface keeps its mean, whatever the spread of its points "
         "(a line in a thin island chain librates about its fitted curve). Compare rows of equal wall time."), "",
        *t2, "",
        *([f"* {t}: {why}" for t, why in failures.items()] + [""] if failures else []),
        *([f"* Re-analysed from an earlier run of this script (same work folder, not re-run): {', '.join(reused)}.", ""]
          if reused else []),
        machine("bench_peers_curves.py", time.perf_counter() - t0, smoke), ""])
    return write_results(args.out, text)


if __name__ == "__main__":
    sys.exit(main())

"""vpforms against its peers (DESC, ESSOS) on one coil set, written to results_peers.md — never part of CI.

The common problem: vpforms' l = 2, m = 5 stellarator coils (``vpforms.coils.l2_stellarator``,
22 polylines, 1760 straight segments), written as a MAKEGRID ``coils.*`` file that every tool reads;
three field lines from (R, Z) = (R_axis + 0.04 | 0.08 | 0.12 m, 0) on φ = 0 (good flux surfaces);
section points at φ = 2πk/5. Each tool runs in its own process and virtual environment
(``benchmarks/peers/run_<tool>.py``, see ``benchmarks/peers/README.md``); a peer whose environment
is absent is skipped. Measured:

1. section accuracy over the first 20 transits (100 section points per line) against DOP853
   (rtol 1e-12) on the coils' own Biot–Savart B (the polylines), and against DOP853 on the field the
   tool actually traces (its "own field": vpforms' spline of A, ESSOS' Fourier-fitted coils);
   wall time per transit per line after compilation, and the compile / fixed cost per call;
2. a long run of the middle line: the distance of its section points from the curve fitted to its
   own first 20 transits (Fourier series ρ(θ) about the axis), against the transit — a tracer that
   does not preserve volume drifts off its surface, an exactly volume-preserving one does not;
3. what each pipeline needs (coils evaluated directly vs a grid).

    python benchmarks/peers/bench_peers.py [--smoke] [--venvs /work/peers] [--out benchmarks/peers/results_peers.md]
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
PEERS = HERE  # the run_<tool>.py scripts and _peer_common.py
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import parser, write_results  # noqa: E402
from _peer_common import dop853_section  # noqa: E402

R_AXIS, NFP = 0.983112, 5
RK_TOL = 1e-8
PIPELINES = {
    "vpforms": "MAKEGRID coils → `read_makegrid` → A of the polylines (closed form) sampled once on a "
               "40×32×40 (R, φ, Z) grid → C² spline of A in (u = R²/2, φ, Z) → B = ∇×A of the spline "
               "(divergence free as a function) → SE+SE ∘ order 2, fixed step, exactly volume preserving; "
               "sections located on the step family. Needs a grid (built from the coils in the run); "
               "tracing never evaluates the coils.",
    "DESC": "MAKEGRID coils → `MixedCoilSet.from_makegrid_coilfile` (SplineXYZCoil) → Biot–Savart "
            "(Hanson–Hirshman segments) of all coils at every RK stage → `field_line_integrate` "
            "(diffrax Tsit5, φ as the time, PID step control; output at the section angles). Coils "
            "directly, no grid (DESC can also trace `SplineMagneticField.from_mgrid`, which "
            "interpolates B).",
    "ESSOS": "No MAKEGRID reader: the polylines are fitted by ESSOS Fourier curves "
             "(`fit_dofs_from_coils`) → `BiotSavart` quadrature at every RK stage → `Tracing` "
             "(`FieldLineAdaptative`: Cartesian dx/dt = B, diffrax Dopri8, PID), saved points; "
             "sections by interpolating the saved trajectory (ESSOS' `poincare_plot`: linear; here "
             "cubic Hermite). Coils directly, no grid.",
}


def _fit_residual(R, Z, fit_transits, harmonics=24):
    """Distance of each section point from the Fourier curve ρ(θ) (about the axis) fitted to the
    points of the first ``fit_transits`` transits; returns (transit number, residual ρ − ρ_fit)."""
    rho, th = np.hypot(R - R_AXIS, Z), np.arctan2(Z, R - R_AXIS)

    def basis(t):
        k = np.arange(1, harmonics + 1)
        return np.c_[np.ones_like(t), np.cos(np.outer(t, k)), np.sin(np.outer(t, k))]

    n_fit = fit_transits * NFP
    coef, *_ = np.linalg.lstsq(basis(th[:n_fit]), rho[:n_fit], rcond=None)
    return (np.arange(len(R)) + 1) / NFP, rho - basis(th) @ coef


def _drift(R, Z, fit_transits, at):
    """(RMS residual over the fit window, mean residual over the 10 transits before ``at``)."""
    tr, d = _fit_residual(R, Z, fit_transits)
    floor = float(np.sqrt(np.mean(d[: fit_transits * NFP] ** 2)))
    win = (tr > at - 10) & (tr <= at)
    return floor, float(np.mean(d[win])) if win.any() else float("nan"), tr, d


def _run_peer(tool, python, work, log):
    script = os.path.join(PEERS, f"run_{tool}.py")
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    if tool == "vpforms":
        env["PYTHONPATH"] = os.path.join(os.path.dirname(os.path.dirname(HERE)), "src") + os.pathsep + env.get("PYTHONPATH", "")
    load0 = os.getloadavg()
    t = time.perf_counter()
    p = subprocess.run([python, script, work], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    log.append(f"{tool}: exit {p.returncode} in {wall:.0f} s, load average before {load0[0]:.1f}")
    out = os.path.join(work, f"{tool}.json")
    if p.returncode != 0 or not os.path.exists(out):
        tail = (p.stderr or p.stdout).strip().splitlines()[-8:]
        return None, "\n".join(tail)
    with open(out) as fh:
        res = json.load(fh)
    res["wall_process_s"], res["loadavg_start"] = wall, load0
    return res, None


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_peers.md"), rounds=1)
    ap.add_argument("--venvs", default=os.environ.get("VPFORMS_PEER_VENVS", "/work/peers"),
                    help="folder holding the peers' virtual environments <venvs>/desc, <venvs>/essos")
    ap.add_argument("--work", default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--tools", default="vpforms,desc,essos", help="comma-separated subset to run")
    ap.add_argument("--reuse", action="store_true", help="reuse <work>/<tool>.json where present (re-analyse)")
    ap.add_argument("--png", default=os.path.join(PEERS, "drift_peers.png"))
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    from vpforms.coils import l2_stellarator, write_makegrid

    work = args.work or tempfile.mkdtemp(prefix="vpforms-peers-")
    os.makedirs(work, exist_ok=True)
    coils = l2_stellarator()
    write_makegrid(coils, os.path.join(work, "coils.l2_stellarator"))
    smoke = args.smoke
    acc, short = (2, 1) if smoke else (20, 2)
    long_tr = {"vpforms": 6, "desc": 3, "essos": 3} if smoke else {"vpforms": 1000, "desc": 60, "essos": 400}
    rng = np.random.default_rng(0)
    R, ph, Z = rng.uniform(0.9, 1.1, 50), rng.uniform(0, 2 * np.pi, 50), rng.uniform(-0.08, 0.08, 50)
    check = np.c_[R * np.cos(ph), R * np.sin(ph), Z]
    R0 = R_AXIS + np.array([0.04, 0.08, 0.12])
    problem = {
        "coils_file": "coils.l2_stellarator", "nfp": NFP, "R0": R0.tolist(), "Z0": [0.0, 0.0, 0.0],
        "accuracy_transits": acc, "short_transits": short, "long_line": 1, "long_transits": long_tr,
        "rk_tol": RK_TOL, "check_points": check.tolist(),
        # (label, h, transits): the long run (all three lines) and a smaller step for accuracy
        "vpforms_runs": [["h = 0.05", 0.05, long_tr["vpforms"]], ["h = 0.0125", 0.0125, 40 if not smoke else 3]],
    }
    with open(os.path.join(work, "problem.json"), "w") as fh:
        json.dump(problem, fh)

    # the reference: DOP853 in φ on the polylines' Biot–Savart B (vpforms' closed form)
    import jax

    B = jax.jit(coils.B)
    B_check = np.asarray(B(check))
    t = time.perf_counter()
    ref_R, ref_Z = dop853_section(lambda x: np.asarray(B(x)), R0, np.zeros(3), NFP, acc * NFP)
    t_ref = time.perf_counter() - t

    log, results, failures = [], {}, {}
    pythons = {"vpforms": sys.executable, "desc": os.path.join(args.venvs, "desc", "bin", "python"),
               "essos": os.path.join(args.venvs, "essos", "bin", "python")}
    for tool, py in pythons.items():
        if tool not in args.tools.split(","):
            continue
        if not os.path.exists(py):
            failures[tool] = f"no virtual environment at {os.path.dirname(os.path.dirname(py))} (skipped)"
            log.append(f"{tool}: skipped (no {py})")
            continue
        if args.reuse and os.path.exists(os.path.join(work, f"{tool}.json")):
            with open(os.path.join(work, f"{tool}.json")) as fh:
                res, err = json.load(fh), None
            log.append(f"{tool}: reused {work}/{tool}.json (load average at its end "
                       f"{res.get('loadavg_end', [float('nan')])[0]:.1f})")
        else:
            res, err = _run_peer(tool, py, work, log)
        if res is None:
            failures[tool] = f"the run failed:\n```\n{err}\n```"
        else:
            results[tool] = res
        print(log[-1], flush=True)

    n_acc = acc * NFP

    def errs(R, Z, rR, rZ):
        n = min(n_acc, len(R))
        return float(np.max(np.hypot(np.asarray(R)[:n] - rR[:n], np.asarray(Z)[:n] - rZ[:n])))

    bscale = np.abs(B_check).max()
    rows, long_rows, curves = [], [], {}
    fit_tr = 20 if not smoke else 1
    common_at = min(long_tr.values())
    for tool, res in results.items():
        name = res["tool"]
        fdiff = float(np.abs(np.asarray(res["field_check_B"]) - B_check).max() / bscale)
        if tool == "vpforms":
            own_R, own_Z = np.asarray(res["own_ref_R"]), np.asarray(res["own_ref_Z"])
            for run in res["runs"]:
                Rr, Zr = np.asarray(run["R"]), np.asarray(run["Z"])
                per = run["best_s"] / float(np.sum(run["traced_transits"]))
                rows.append((name, f"SE+SE ∘ order 2, {run['label']}", errs(Rr, Zr, ref_R, ref_Z),
                             errs(Rr, Zr, own_R, own_Z), per * 1e3, run["compile_s"], fdiff))
            lr = res["runs"][0]
            Rl, Zl = np.asarray(lr["R"])[:, 1], np.asarray(lr["Z"])[:, 1]
        else:
            own_R = np.asarray(res.get("own_ref_R", ref_R))
            own_Z = np.asarray(res.get("own_ref_Z", ref_Z))
            run, lr = res["runs"]
            Rr, Zr = np.asarray(run["R"]), np.asarray(run["Z"])
            per = (run["t_acc"] - run["t_short"]) / ((run["transits"] - run["short_transits"]) * run["lines"])
            fixed = run["t_short"] - per * run["short_transits"] * run["lines"]
            rows.append((name, run["label"], errs(Rr, Zr, ref_R, ref_Z), errs(Rr, Zr, own_R, own_Z), per * 1e3,
                         fixed, fdiff))
            Rl, Zl = np.asarray(lr["R"])[:, 0], np.asarray(lr["Z"])[:, 0]
        floor, d_common, tr, d = _drift(Rl, Zl, fit_tr, common_at)
        _, d_end, _, _ = _drift(Rl, Zl, fit_tr, tr[-1])
        slope = np.polyfit(tr[fit_tr * NFP:], d[fit_tr * NFP:], 1)[0] if len(tr) > fit_tr * NFP + 2 else np.nan
        long_rows.append((name, rows[-1 if tool != "vpforms" else -2][1], tr[-1], floor, d_common, d_end,
                          slope * 1000))
        curves[name] = (tr, d)

    png_note = ""
    if curves and not smoke:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
        for name, (tr, d) in curves.items():
            ax[0].plot(tr, d * 1e6, ".", ms=1.5, label=name)
            ax[1].semilogy(tr, np.abs(d) + 1e-12, ".", ms=1.5, label=name)
        ax[0].set(xlabel="transit", ylabel="ρ − ρ_fit(θ)  (µm)",
                  title="Distance from the own surface (fit to the first 20 transits)")
        ax[1].set(xlabel="transit", ylabel="|ρ − ρ_fit(θ)|  (m)", title="same, log scale")
        for a in ax:
            a.legend(markerscale=6)
        fig.suptitle(f"l = 2 stellarator coils, line from R = {R0[1]:.4f} m, section φ = 2πk/5")
        fig.tight_layout()
        fig.savefig(args.png, dpi=110)
        png_note = f"![drift]({os.path.relpath(args.png, os.path.dirname(os.path.abspath(args.out)))})"

    import vpforms

    total = time.perf_counter() - t_start
    L = [
        "# vpforms against DESC and ESSOS: field lines of one coil set",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPU cores **shared with other work** (load averages "
        f"below), {platform.system()}; vpforms {vpforms.__version__} (JAX {jax.__version__}); "
        + ", ".join(f"{r['tool']} {r['version']} (JAX {r['jax']})" for t, r in results.items() if t != "vpforms")
        + f". Generated by `python benchmarks/peers/bench_peers.py{' --smoke' if smoke else ''}` in {total:.0f} s"
        + (" (**smoke mode: tiny sizes, numbers meaningless**)" if smoke else "") + ". One tool at a time, "
        "each in its own process and virtual environment (`benchmarks/peers/README.md`).",
        "",
        "**Problem.** vpforms' l = 2, m = 5 stellarator coils (`l2_stellarator()`: 20 TF coils + 2 helical "
        "windings, 22 polylines, 1760 segments) written as a MAKEGRID coils file that every tool reads; "
        f"lines from (R, Z) = ({', '.join(f'{r:.4f}' for r in R0)}; 0) m on φ = 0 (good surfaces, ι ≈ 0.31–0.34); "
        "section points at φ = 2πk/5. Reference: scipy DOP853 in φ, rtol 1e-12, on the polylines' "
        f"Biot–Savart B (vpforms' closed form; {t_ref:.0f} s). Error = max distance in (R, Z) over the first "
        f"{acc} transits ({n_acc} section points per line, 3 lines). \"Own field\" = DOP853 on the field the "
        "tool traces (vpforms: the spline of A; ESSOS: its Fourier-fitted coils; DESC traces the polylines "
        "themselves, so its own field is the reference).",
        "",
        "## 1. Accuracy and cost (3 lines)",
        "",
        "| tool | settings | error vs coils' B (m) | error vs own field (m) | ms / transit / line | "
        "compile / fixed cost per call (s) | field: max\\|B − B_coils\\| / max\\|B\\| |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for name, lab, e1, e2, ms, comp, fd in rows:
        cost = f"{ms:.1f}" if ms > 0 else "not resolved (†)"
        L.append(f"| {name} | {lab} | {e1:.1e} | {e2:.1e} | {cost} | {comp:.1f} | {fd:.1e} |")
    if any(r[4] <= 0 for r in rows):
        L += ["", "(†) The 20-transit call took no longer than the 2-transit call: the fixed cost per call "
              "(compilation, rebuilt every call) dominates and the marginal cost per transit is below the timing "
              "noise of this loaded machine; the raw call times are listed under Runs."]
    L += [
        "",
        "Time per transit: vpforms — the best of two identical calls divided by the transits the lines "
        "made (compile = first call − second); DESC, ESSOS — (t(20 transits) − t(2 transits)) / (18 · 3): "
        "their trace functions are rebuilt and re-jitted per call, so the marginal cost is the cost after "
        "compilation and the rest is the fixed cost per call. With 3 lines vpforms' step is dominated by "
        "per-step overhead (its cost per particle-step falls ~25× with 2000 lines: "
        "`results_real_fields.md`); the peers' Biot–Savart cost grows with lines × segments.",
        "",
        "## 2. Long run: does the line stay on its surface?",
        "",
        f"The middle line (R = {R0[1]:.4f} m). ρ(θ) about the axis ({R_AXIS}, 0) is fitted by a 24-harmonic "
        f"Fourier series to the tool's own first {fit_tr} transits; the residual ρ − ρ_fit of the later "
        "points measures how far the line has left that curve (a secular drift = a spurious flux change; "
        "on a good surface of an exactly volume-preserving map it stays at the fit's level).",
        "",
        f"| tool | settings | transits | RMS residual, transits 1–{fit_tr} (m) | mean residual near "
        f"transit {common_at} (m) | mean residual near the end (m) | drift per 1000 transits (m) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for name, lab, n, floor, dc, de, sl in long_rows:
        L.append(f"| {name} | {lab} | {n:.0f} | {floor:.1e} | {dc:.1e} | {de:.1e} | {sl:.1e} |")
    if png_note:
        L += ["", png_note]
    L += ["", "## 3. What each pipeline requires", ""]
    for name, text in PIPELINES.items():
        L.append(f"* **{name}**: {text}")
    L += ["", "## Runs", ""] + [f"* {s}" for s in log]
    for tool, res in results.items():
        if tool != "vpforms":
            a, b = res["runs"]
            L.append(f"* {res['tool']} call times: {a['short_transits']} transits × 3 lines {a['t_short']:.1f} s; "
                     f"{a['transits']} transits × 3 lines {a['t_acc']:.1f} s; {b['transits']} transits × 1 line "
                     f"{b['t']:.1f} s")
        else:
            L.append(f"* vpforms: spline of A built in {res['spline_build_s']:.1f} s (spline error "
                     f"{res['spline_error']:.1e}); DOP853 reference on the spline {res['own_ref_s']:.0f} s; "
                     + "; ".join(f"{r['label']}: {r['n_steps']} steps, first call {r['first_s']:.1f} s, second "
                                 f"{r['best_s']:.1f} s" for r in res["runs"]))
    for tool, why in failures.items():
        L.append(f"* **{tool} did not run**: {why}")
    L.append(f"* Work folder (coils file, problem.json, raw JSON results): `{work}`")
    return write_results(args.out, "\n".join(L) + "\n")


if __name__ == "__main__":
    sys.exit(main())

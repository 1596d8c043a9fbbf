"""ι and surface thickness of vpforms, DESC and ESSOS on one coil set (issue #21, item 6) — never in CI.

The coil set and tools of ``bench_peers.py`` (each peer in its own environment, ``peers/run_<tool>.py``):

1. **ι at the same points**: 10 lines from (R, Z) = (R_axis + 0.02 … 0.12 m, 0) on φ = 0, ``--iota-transits``
   (200) transits each. Every tool's section points (φ = 2πk/5) go through one estimator, here:
   the poloidal angle θ about the axis (R_axis, 0) of each section point, its increments Δθ ∈ (−π, π]
   over 1/5 transit, ι = 5·⟨Δθ⟩/2π (negative here: θ decreases as φ grows) with the weighted Birkhoff average of
   :func:`vpforms.fieldlines.birkhoff_weight` (super-polynomial on invariant circles); its error is
   estimated by the same average over the first half of the transits.
2. **Surface thickness over 10⁴ transits**: one line (R = R_axis + 0.076 m) for ``--long-transits``
   (10 000) transits; the distance ρ − ρ_fit(θ) of its section points from the Fourier curve fitted
   to its first 20 transits (``bench_peers._fit_residual``): RMS over the fit window, RMS over the
   last 1000 transits, and the linear trend per 1000 transits. An exactly volume-preserving map
   keeps a line on an invariant circle of its own field; a non-preserving one drifts.

These are accuracy measures, not timings: the wall times printed are only for orientation.
vpforms: native, SE+SE ∘ order 4, h = 0.025 on the 96×64×96 spline of A (``bench_peers_issue_size``).

    PYTHONPATH=src python benchmarks/peers/bench_peers_surfaces.py [--tools vpforms,desc,essos] [--smoke]
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
from bench_peers import R_AXIS, RK_TOL, _fit_residual  # noqa: E402
from bench_peers_issue_size import BOX_R, BOX_Z, NFP, _per_line, run_peers  # noqa: E402


def iota(R, Z):
    """(ι, error estimate) per line from section points (n, lines) at φ = 2πk/5, k = 1 … n, of lines
    that start on (R_axis + ·, 0): weighted Birkhoff average of the increments of θ about the axis."""
    from vpforms.fieldlines import birkhoff_weight

    th = np.arctan2(np.asarray(Z), np.asarray(R) - R_AXIS)
    th = np.vstack([np.zeros((1, th.shape[1])), th])  # the start: θ = 0 on the outboard midplane
    d = np.angle(np.exp(1j * np.diff(th, axis=0)))  # Δθ over 1/5 transit, in (−π, π]

    def avg(dd):
        n = dd.shape[0]
        w = np.asarray(birkhoff_weight((np.arange(n) + 0.5) / n))[:, None]
        return NFP * np.sum(w * dd, axis=0) / np.sum(w) / (2 * np.pi)

    full = avg(d)
    return full, np.abs(full - avg(d[: d.shape[0] // 2]))


def thickness(R, Z, fit_transits=20):
    """(RMS over the fit window, RMS over the last 1000 transits, trend per 1000 transits, transits)."""
    tr, d = _fit_residual(np.asarray(R), np.asarray(Z), fit_transits)
    floor = float(np.sqrt(np.mean(d[: fit_transits * NFP] ** 2)))
    last = tr > tr[-1] - 1000
    tail = float(np.sqrt(np.mean(d[last] ** 2)))
    after = tr > fit_transits
    slope = float(np.polyfit(tr[after], d[after], 1)[0]) * 1000 if after.sum() > 2 else float("nan")
    return floor, tail, slope, float(tr[-1])


def run_vpforms(x_R, long_i, iota_tr, long_tr, grid, order, h):
    """Section points (R, Z) of the ι run and of the long run, natively."""
    import vpforms
    from vpforms.coils import l2_stellarator
    from vpforms.fieldlines import toroidal_section
    from vpforms.problems.coil_fields import spline_coil_field
    from vpforms.toroidal import to_toroidal

    field, _ = spline_coil_field(l2_stellarator(), BOX_R, BOX_Z, n_R=grid[0], n_phi=grid[1], n_Z=grid[2],
                                 name="peers")
    m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=order)
    x0 = np.asarray(to_toroidal(np.c_[x_R, np.zeros_like(x_R), np.zeros_like(x_R)]))
    t_transit = 2 * np.pi * 1.2**2  # generous (φ̇ ≈ 1/R²)
    out = {}
    for key, x, tr in (("iota", x0, iota_tr), ("long", x0[long_i:long_i + 1], long_tr)):
        t = time.perf_counter()
        s = toroidal_section(m, x, h, int(np.ceil(tr * t_transit / h)), phi=0.0, nfp=NFP, direction=1,
                             progress=False)
        R, Z, _ = _per_line(s, x.shape[0], tr * NFP)
        out[key] = (R, Z, time.perf_counter() - t)
    return out, f"{grid[0]}×{grid[1]}×{grid[2]} spline, SE+SE ∘ order {order}, h = {h:g} (native)"


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_peers_surfaces.md"), rounds=1)
    ap.add_argument("--venvs", default=os.environ.get("VPFORMS_PEER_VENVS", "/work/peers"))
    ap.add_argument("--work", default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--tools", default="vpforms,desc,essos", help="comma-separated subset to run")
    ap.add_argument("--iota-transits", type=int, default=200)
    ap.add_argument("--long-transits", type=int, default=10000)
    ap.add_argument("--reuse", default="", help="comma-separated tools not re-run: their <work>/<tool>.json "
                    "of an earlier run (same --work) is re-analysed, and the table says so")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    from vpforms.coils import l2_stellarator, write_makegrid

    smoke = args.smoke
    n_lines, iota_tr, long_tr = (3, 4, 30) if smoke else (10, args.iota_transits, args.long_transits)
    grid, order, h = ((12, 8, 12), 2, 0.05) if smoke else ((96, 64, 96), 4, 0.025)
    x_R = R_AXIS + np.linspace(0.02, 0.12, n_lines)
    long_i = int(np.argmin(np.abs(x_R - (R_AXIS + 0.08))))
    work = args.work or tempfile.mkdtemp(prefix="vpforms-peers-surf-")
    os.makedirs(work, exist_ok=True)
    write_makegrid(l2_stellarator(), os.path.join(work, "coils.l2_stellarator"))
    rng = np.random.default_rng(0)
    Rc, ph, Zc = rng.uniform(0.9, 1.1, 5), rng.uniform(0, 2 * np.pi, 5), rng.uniform(-0.08, 0.08, 5)
    with open(os.path.join(work, "problem.json"), "w") as fh:
        json.dump({"coils_file": "coils.l2_stellarator", "nfp": NFP, "R0": x_R.tolist(), "Z0": [0.0] * n_lines,
                   "accuracy_transits": iota_tr, "short_transits": 1, "long_line": long_i,
                   "long_transits": {"desc": long_tr, "essos": long_tr}, "rk_tol": RK_TOL,
                   "check_points": np.c_[Rc * np.cos(ph), Rc * np.sin(ph), Zc].tolist(), "own_reference": False}, fh)

    tools = args.tools.split(",")
    reuse = [t for t in args.reuse.split(",") if t and t not in tools]
    got, reused = {}, []
    if "vpforms" in tools:
        out, label = run_vpforms(x_R, long_i, iota_tr, long_tr, grid, order, h)
        got["vpforms"] = (label, out["iota"][:2], out["long"][:2], out["iota"][2] + out["long"][2])
        with open(os.path.join(work, "vpforms.json"), "w") as fh:  # for a later --reuse vpforms
            json.dump({"label": label, **{k: [np.asarray(v[0]).tolist(), np.asarray(v[1]).tolist(), v[2]]
                                          for k, v in out.items()}}, fh)
    if "vpforms" in reuse:
        with open(os.path.join(work, "vpforms.json")) as fh:
            v = json.load(fh)
        got["vpforms"] = (v["label"], tuple(v["iota"][:2]), tuple(v["long"][:2]), v["iota"][2] + v["long"][2])
        reused.append("vpforms")
    results, failures = run_peers(tools, args.venvs, work)
    for tool in reuse:
        path = os.path.join(work, f"{tool}.json")
        if tool != "vpforms" and os.path.exists(path):
            with open(path) as fh:
                results[tool] = json.load(fh)
            reused.append(tool)
    for res in results.values():
        run, lr = res["runs"]
        got[res["tool"]] = (f"{res['version']}: {run['label']}", (run["R"], run["Z"]), (lr["R"], lr["Z"]),
                            run["t_acc"] + lr["t"])

    ref = got.get("vpforms")
    t1 = ["| tool | settings | ι range over the lines | max ι error estimate | max \\|ι − ι_vpforms\\| |",
          "|---|---|---|---:|---:|"]
    t2 = ["| tool | transits | RMS residual, fit window (m) | RMS residual, last 1000 transits (m) | "
          "trend per 1000 transits (m) |", "|---|---:|---:|---:|---:|"]
    iv = iota(*ref[1]) if ref else None
    for name, (label, (R, Z), (RL, ZL), _) in got.items():
        n = min(np.asarray(R).shape[0], iota_tr * NFP)
        io, er = iota(np.asarray(R)[:n], np.asarray(Z)[:n])
        diff = "—" if iv is None or name == "vpforms" else f"{np.max(np.abs(io - iv[0])):.1e}"
        t1.append(f"| {name} | {label} | {io.min():.6f} … {io.max():.6f} | {er.max():.1e} | {diff} |")
        fl, tail, slope, tr = thickness(np.asarray(RL)[:, 0], np.asarray(ZL)[:, 0])
        t2.append(f"| {name} | {tr:.0f} | {fl:.1e} | {tail:.1e} | {slope:+.1e} |")
    text = "\n".join([
        "# ι and surface thickness: vpforms, DESC and ESSOS on one coil set", "",
        (f"The l = 2 stellarator coils of `results_peers.md` (one MAKEGRID file). ι: {n_lines} lines from "
         f"R = R_axis + 0.02 … 0.12 m, {iota_tr} transits, one estimator for all tools (weighted Birkhoff "
         "average of the poloidal increments about the axis between the sections φ = 2πk/5; error estimate "
         "= its change from the first half of the transits). Thickness: the line from "
         f"R = {x_R[long_i]:.4f} m over its transits, residual from the Fourier curve fitted to its first 20. "
         "ESSOS traces its Fourier fit of the coils (7.9e-4 from the polylines' B), so its ι differs by its "
         "field, not only its integrator."), "",
        "## ι at the same points", "", *t1, "",
        "## Surface thickness", "", *t2, "",
        *([f"* {t}: {why}" for t, why in failures.items()] + [""] if failures else []),
        *([f"* Re-analysed from an earlier run of this script (same work folder, not re-run): "
           f"{', '.join(reused)}.", ""] if reused else []),
        machine("bench_peers_surfaces.py", time.perf_counter() - t0, smoke), ""])
    return write_results(args.out, text)


if __name__ == "__main__":
    sys.exit(main())

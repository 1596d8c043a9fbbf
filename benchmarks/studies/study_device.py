"""Real stellarators end to end (issue #38 item 4): sections on two planes, the axis, ι of every line; W7-X's 5/5 chain.

    PYTHONPATH=$PWD/src python benchmarks/studies/study_device.py [--device w7x] [--grid 48x96x48] [--transits 200]

The device's coils as simsopt integrates them (``device(name, rule="quadrature")``) splined on a grid
that follows its default domain (:func:`vpforms.problems.devices.grid_field`), SE+SE composed to
order 2, fixed h, natively. Lines start on the outboard midplane of φ = 0 from the axis out to 1.3×
the distance to the last closed surface (W7-X: 0.32 m, past the last closed surface at ≈ 0.25 m,
through the 5/5 island chain at R ∈ [6.20, 6.25] m) and are stopped at the domain. The script writes
``docs/figures/<device>_sections.png`` (φ = 0 and half a period side by side — W7-X's bean and
triangle —, the domain's boundary, the axis, the chain's O- and X-points with ``--islands``) and
``benchmarks/studies/results_study_device_<device>.md`` (timings, the axis and its ι, ι of each
line by the weighted Birkhoff average of its crossings, failed lines).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def iota_of_crossings(R, Z, R_axis, Z_axis, nfp):
    """ι of one line from its successive crossings of the planes φ ≡ φ₀ (mod 2π/nfp): the poloidal
    angle θ about the axis point advances by ι·2π/nfp per period (unwrapped into (−π, π]: valid for
    |ι| < nfp/2); ι = Σ w_k Δθ_k / Σ w_k (2π/nfp) with the weighted Birkhoff weights w_k."""
    th = np.unwrap(np.arctan2(np.asarray(Z) - Z_axis, np.asarray(R) - R_axis))
    d = np.diff(th)
    n = d.size
    s = (np.arange(n) + 0.5) / n
    w = np.exp(-1.0 / (s * (1 - s)))
    return float(np.sum(w * d) / np.sum(w) / (2 * np.pi / nfp))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="w7x")
    ap.add_argument("--grid", default="48x96x48")
    ap.add_argument("--transits", type=int, default=200)
    ap.add_argument("--lines", type=int, default=24)
    ap.add_argument("--h", type=float, default=0.05)
    ap.add_argument("--order", type=int, default=2)
    ap.add_argument("--figure", default=None, help="default docs/figures/<device>_sections.png")
    ap.add_argument("--results", default=None, help="default benchmarks/studies/results_study_device_<device>.md")
    ap.add_argument("--islands", action="store_true", help="also search the 5/5 chain's O- and X-points")
    args = ap.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import vpforms
    from vpforms.coils import device_axis
    from vpforms.fieldlines import island_chain, magnetic_axis, toroidal_section, trace_to_wall
    from vpforms.coils import device_data
    from vpforms.problems.devices import EDGE, grid_field
    from vpforms.toroidal import to_toroidal

    name = device_data(args.device)["name"]
    figure = args.figure or str(ROOT / "docs" / "figures" / f"{name}_sections.png")
    results = args.results or str(Path(__file__).with_name(f"results_study_device_{name}.md"))
    times = {}
    nfp = int(device_data(name)["nfp"])
    grid = tuple(int(v) for v in args.grid.split("x"))
    t = time.perf_counter()
    field, err = grid_field(name, grid)
    times["grid (sample A, fit)"] = time.perf_counter() - t
    t = time.perf_counter()
    m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=args.order)
    times["method"] = time.perf_counter() - t
    R0, Z0 = (float(v) for v in device_axis(name)(0.0))
    t = time.perf_counter()
    axis = magnetic_axis(m, (R0, Z0), args.h, 0.0, nfp)
    times["axis (Newton on the return map)"] = time.perf_counter() - t
    offsets = np.linspace(0.05, 1.28, args.lines) * EDGE[name]
    x0 = np.asarray(to_toroidal(np.c_[axis.R + offsets, np.zeros_like(offsets), np.full_like(offsets, axis.Z)]))
    x1 = np.asarray(m.step_with_status(x0[0], args.h)[0])
    steps = int(np.ceil(args.transits * 2 * np.pi / abs(float(x1[1] - x0[0][1]))))
    dom = field.domain
    secs = {}
    for phi in (0.0, np.pi / nfp):
        t = time.perf_counter()
        secs[phi] = toroidal_section(m, x0, args.h, steps, phi=phi, nfp=nfp, progress=False)
        times[f"section φ = {np.degrees(phi):.0f}° ({args.lines} lines × {args.transits} transits)"] = \
            time.perf_counter() - t
    t = time.perf_counter()
    hits = trace_to_wall(m, x0, args.h, steps, dom, progress=False)
    times["the same lines to the domain's boundary"] = time.perf_counter() - t
    chains = []
    if args.islands and name == "w7x":
        t = time.perf_counter()
        chains = island_chain(m, 5, args.h, np.linspace(axis.R + 0.24, axis.R + 0.31, 15), axis.Z, 0.0, nfp)  # W7-X
        times["5/5 chain (fixed points of P⁵)"] = time.perf_counter() - t
    iotas = []
    sec0 = secs[0.0].before(hits.t_exit)
    for i in range(args.lines):
        k = (sec0.line == i) & (sec0.t > 1e-12)  # the start on φ = 0 is not a crossing
        R, Z = sec0.R[k][np.argsort(sec0.t[k])], sec0.Z[k][np.argsort(sec0.t[k])]
        iotas.append(iota_of_crossings(R, Z, axis.R, axis.Z, nfp) if R.size > 20 and not hits.hit[i] else np.nan)

    fig, axes = plt.subplots(1, 2, figsize=(11, 6.2), constrained_layout=True)
    for ax, (phi, sec) in zip(axes, secs.items()):
        sec = sec.before(hits.t_exit)
        w = dom.wall_at(phi)
        ax.plot(w.R, w.Z, "k-", lw=1, label="domain boundary")
        sc = ax.scatter(sec.R, sec.Z, s=0.6, c=offsets[sec.line], cmap="viridis")
        if phi == 0.0:
            ax.plot(axis.R, axis.Z, "r+", ms=12, mew=2, label=f"magnetic axis, ι = {abs(axis.iota):.4f}")
            for fp in chains:
                ax.plot(fp.R, fp.Z, "o" if fp.kind == "O" else "x", color="C3" if fp.kind == "O" else "C1", ms=8,
                        mfc="none", label=f"5/5 {fp.kind}-point")
        ax.set_aspect("equal")
        ax.set_xlabel("R (m)")
        ax.set_ylabel("Z (m)")
        ax.set_title(f"φ = {np.degrees(phi):.0f}°" + (f" ({'bean' if phi == 0 else 'triangle'})" if name == "w7x" else ""))
        ax.legend(fontsize=8, loc="lower left")
    fig.colorbar(sc, ax=axes, label="start offset from the axis (m)", shrink=0.8)
    fig.suptitle(f"{name} (simsopt's coils by quadrature), {args.grid} grid on the domain, SE+SE order {args.order}, "
                 f"h = {args.h:g}, {args.transits} transits")
    os.makedirs(os.path.dirname(figure), exist_ok=True)
    fig.savefig(figure, dpi=110)

    out = [f"# {name} study (issue #38 item 4)", "",
           f"Generated by `benchmarks/studies/study_device.py --device {name} --grid {args.grid} --transits {args.transits} --lines "
           f"{args.lines}{' --islands' if args.islands else ''}`; {os.cpu_count()} cores, load average "
           f"{os.getloadavg()[0]:.1f} at the end.", "",
           "| phase | s |", "|---|---|", *[f"| {k} | {v:.1f} |" for k, v in times.items()], "",
           f"* grid {args.grid}: B error on the domain {err:.2e} (max over 400 points; the worst at its edge)",
           f"* axis (φ = 0): R = {axis.R:.8f} m, Z = {axis.Z:.2e} m, |ι| = {abs(axis.iota):.6f}, residual {axis.residual:.1e}",
           f"* lines: {args.lines}, failed {int(np.count_nonzero(secs[0.0].status != 0))}, "
           f"stopped at the domain {int(hits.hit.sum())}", "",
           "| offset (m) | start R (m) | ι (Birkhoff, crossings of φ = 0) | left the domain |", "|---|---|---|---|",
           *[f"| {o:.4f} | {axis.R + o:.5f} | {io:.6f} | {bool(hit)} |" for o, io, hit in zip(offsets, iotas, hits.hit)]]
    for fp in chains:
        out.append(f"* 5/5 {fp.kind}-point: R = {fp.R:.6f} m, Z = {fp.Z:.5f} m, residue {fp.residue:.4g}")
    Path(results).write_text("\n".join(out) + "\n")
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

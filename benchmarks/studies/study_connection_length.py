"""W7-X connection-length map (issue #38 item 4): ≥ 10⁴ lines near the 5/5 islands traced both ways to a divertor-like wall.

    PYTHONPATH=$PWD/src nice -n 5 python benchmarks/studies/study_connection_length.py [--lines 10000]
        [--depth 0.12] [--transits 20] [--h 0.1] [--order 2] [--dask-lines 200] [--check-lines 300]

The field and the method are those of ``vpforms fieldlines --device w7x`` (the command's own code path,
:func:`vpforms.cli.fieldlines.build_method`: the quadrature coils splined on the 48×96×48 grid that
follows the default domain, SE+SE composed to ``--order``); the wall is
:func:`vpforms.problems.devices.divertor_wall` (the default domain 0.24 m inward, through the 5/5
chain); the lines start on an (R, Z) grid of φ = 0 within ``--depth`` of the wall
(:func:`vpforms.fieldlines.start_grid`) and run at most ``--transits`` toroidal transits each way
(the command's ``--connection-length`` phase, ``_connection_map``). Then:

* the same map natively in this process (timed, load given);
* a subset of ``--dask-lines`` lines on a Dask ``LocalCluster`` of 2 worker processes × 1 thread
  (each worker rebuilds the field and the method with the command's builder), compared bit for bit;
* the step's effect on L_c: ``--check-lines`` lines again at h/2;
* stellarator symmetry, a check of the physics: (R, φ, Z) → (R, −φ, −Z) maps a line onto a line
  run backwards, so on φ = 0 L_bwd(R, Z) = L_fwd(R, −Z) (the grid's Z nodes are symmetric);
* ``docs/figures/w7x_connection_length.png`` and ``results_study_connection_length.md``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def load() -> str:
    return "{:.1f} {:.1f} {:.1f}".format(*os.getloadavg())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lines", type=int, default=10000)
    ap.add_argument("--depth", type=float, default=0.12)
    ap.add_argument("--transits", type=float, default=20.0)
    ap.add_argument("--h", type=float, default=0.1)
    ap.add_argument("--order", type=int, default=2)
    ap.add_argument("--dask-lines", type=int, default=200)
    ap.add_argument("--check-lines", type=int, default=300)
    ap.add_argument("--section-lines", type=int, default=24)
    ap.add_argument("--figure", default=str(ROOT / "docs" / "figures" / "w7x_connection_length.png"))
    ap.add_argument("--results", default=str(Path(__file__).with_name("results_study_connection_length.md")))
    ap.add_argument("--csv", default=None, help="also write every line's lengths (ConnectionLengths.to_csv)")
    a = ap.parse_args(argv)

    from dask.distributed import Client, LocalCluster

    from vpforms import plots
    from vpforms._phases import Phases
    from vpforms.cli import build_parser
    from vpforms.cli import fieldlines as fl
    from vpforms.coils import device_axis
    from vpforms.fieldlines import connection_length, return_map, toroidal_section, trace_to_wall
    from vpforms.problems.devices import DIVERTOR_INSET

    start_load = load()
    cli = ["fieldlines", "--device", "w7x", "--wall", "divertor", "--h", str(a.h), "--order", str(a.order),
           "--connection-length", str(a.lines), "--lc-depth", str(a.depth), "--lc-transits", str(a.transits)]
    args = build_parser().parse_args(cli)
    times, loads = {}, {}

    def timed(what, fn):
        t = time.perf_counter()
        out = fn()
        times[what] = time.perf_counter() - t
        loads[what] = load()
        print(f"{what}: {times[what]:.1f} s (load {loads[what]})", flush=True)
        return out

    method = timed("field and method (the command's builder)", lambda: fl.method_builder(args)())
    field = method.field
    nfp = fl.field_nfp(field)
    wall = fl._divertor_wall(args)
    P = return_map(method, a.h, 0.0, nfp)
    native = f"connection lengths, {a.lines} lines both ways, in process (native)"
    with Phases(quiet=True) as log:
        lc, grid, steps = timed(native, lambda: fl._connection_map(args, log, method, P, wall, nfp))
    taken = sum(int(np.where(d.hit, d.step + 1, steps).sum()) for d in (lc.forward, lc.backward))
    N = len(grid.x0)
    if a.csv:
        lc.to_csv(a.csv)
    print(lc.summary(), flush=True)

    # the same lines on Dask workers: every k-th line, compared bit for bit
    sub = np.linspace(0, N - 1, min(a.dask_lines, N)).astype(int)
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    try:
        dk = timed(f"the same {sub.size} lines on Dask (2 workers × 1 thread; each worker builds field, method)",
                   lambda: connection_length(method, grid.x0[sub], a.h, steps, wall, client=client,
                                             builder=fl.method_builder(args), progress=False))
        dk2 = timed(f"again on the warm workers ({sub.size} lines)",
                    lambda: connection_length(method, grid.x0[sub], a.h, steps, wall, client=client,
                                              builder=fl.method_builder(args), progress=False))
    finally:
        client.close()
        cluster.close()
    same = all(np.array_equal(getattr(dk, f), getattr(lc, f)[sub], equal_nan=True) and
               np.array_equal(getattr(dk2, f), getattr(lc, f)[sub], equal_nan=True)
               for f in ("status_fwd", "status_bwd", "length_fwd", "length_bwd"))
    same &= all(np.array_equal(d.exit(w)["point"], lc.exit(w)["point"][sub], equal_nan=True)
                for d in (dk, dk2) for w in ("forward", "backward"))
    print("Dask == in process, bit for bit:", same, flush=True)

    # the step: a subset again at h/2 and h/4 (the same transits)
    chk = np.linspace(0, N - 1, min(a.check_lines, N)).astype(int)
    half = timed(f"{chk.size} lines at h/2", lambda: connection_length(method, grid.x0[chk], a.h / 2, 2 * steps,
                                                                        wall, progress=False))
    quarter = timed(f"{chk.size} lines at h/4", lambda: connection_length(method, grid.x0[chk], a.h / 4, 4 * steps,
                                                                           wall, progress=False))
    both = half.reached & lc.reached[chk]
    rel = np.abs(half.L[both] - lc.L[chk][both]) / half.L[both]
    agree_status = float(np.mean(half.status == lc.status[chk]))
    all3 = both & quarter.reached
    d1 = np.abs(lc.L[chk][all3] - quarter.L[all3]) / quarter.L[all3]  # h against h/4
    d2 = np.abs(half.L[all3] - quarter.L[all3]) / quarter.L[all3]     # h/2 against h/4

    # stellarator symmetry on φ = 0: L_bwd(R, Z) against L_fwd(R, −Z)
    key = {(i, j): k for k, (i, j) in enumerate(grid.index)}
    nZ = grid.Z.size
    pairs = np.array([(k, key[(nZ - 1 - i, j)]) for k, (i, j) in enumerate(grid.index) if (nZ - 1 - i, j) in key])
    np.testing.assert_allclose(grid.Z[grid.index[pairs[:, 0], 0]], -grid.Z[grid.index[pairs[:, 1], 0]], atol=1e-12)
    sb, sf = lc.status_bwd[pairs[:, 0]], lc.status_fwd[pairs[:, 1]]
    sym_status = float(np.mean(sb == sf))
    ok = (sb == 0) & (sf == 0)
    sym_rel = np.abs(lc.length_bwd[pairs[ok, 0]] - lc.length_fwd[pairs[ok, 1]]) / lc.length_fwd[pairs[ok, 1]]

    # a section for the islands (lines through the band on the outboard midplane), cut at the wall
    R_ax = float(device_axis("w7x")(0.0)[0])
    rs = np.linspace(R_ax + 0.15, float(wall.wall_at(0.0).bounds[1]) - 0.005, a.section_lines)
    xs = np.stack([rs**2 / 2, 0 * rs, 0 * rs], 1)
    n_sec = int(np.ceil(100 * nfp * fl._steps_per_period(P, xs[0])))
    sec = timed(f"section for the figure ({a.section_lines} lines × 100 transits)",
                lambda: toroidal_section(method, xs, a.h, n_sec, phi=0.0, nfp=nfp, progress=False))
    sec = sec.before(trace_to_wall(method, xs, a.h, n_sec, wall, progress=False).t_exit)
    plots.connection_length_figure(
        lc, grid, wall.wall_at(0.0), section=sec, path=a.figure,
        title=f"W7-X connection length to a divertor-like wall (the default domain {DIVERTOR_INSET['w7x']} m "
              f"inward): {N} lines on φ = 0 within {a.depth} m of it, traced both ways, SE+SE order {a.order}, "
              f"h = {a.h}, ≤ {steps} steps (≈ {a.transits:g} transits) each way")

    r = lc.reached
    sf_, sb_ = lc.status_fwd, lc.status_bwd
    Lr = lc.L[r]
    lines = [
        "# W7-X connection-length map (issue #38 item 4)",
        "",
        f"Generated by `benchmarks/studies/study_connection_length.py --lines {a.lines} --depth {a.depth} "
        f"--transits {a.transits:g} --h {a.h} --order {a.order} --dask-lines {a.dask_lines} "
        f"--check-lines {a.check_lines}` (run with `nice -n 5`).",
        "",
        f"Load averages (1, 5, 15 min): {start_load} at the start, after each phase in the table (2 cores shared "
        "with other agents' runs).",
        "",
        "Field and method: `vpforms fieldlines --device w7x` (the command's builder, "
        "`vpforms.cli.fieldlines.build_method`): simsopt's W7-X coils by quadrature splined on the 48×96×48 grid "
        f"that follows the default domain, SE+SE composed to order {a.order}, h = {a.h} "
        f"(≈ {steps / a.transits:.0f} steps per transit). Wall: `vpforms.problems.devices.divertor_wall('w7x')` — "
        f"the default domain moved {DIVERTOR_INSET['w7x']} m inward, through the 5/5 island chain (a model, "
        "not the real divertor). Starts: `start_grid(wall, "
        f"{a.lines}, depth={a.depth})` on φ = 0: {N} lines on a square grid of spacing {grid.spacing * 1e3:.1f} mm "
        f"within {a.depth} m of the wall; at most {steps} steps (≈ {a.transits:g} transits) each way.",
        "",
        "| phase | s | load after |",
        "|---|---|---|",
        *[f"| {k} | {v:.1f} | {loads[k]} |" for k, v in times.items()],
        "",
        f"* lines: {N}; reached the wall both ways: **{int(r.sum())} ({100 * r.mean():.1f} %)**; forwards "
        f"{int((sf_ == 0).sum())}, backwards {int((sb_ == 0).sum())}; not within {steps} steps (lower bounds): "
        f"{int(lc.unreached.sum())}; failed or left the field's domain: {int((~r & ~lc.unreached).sum())}",
        (f"* L_c = L_fwd + L_bwd of the lines that reached the wall: median {np.median(Lr):.4g} m, "
         f"10 % / 90 % {np.percentile(Lr, 10):.4g} / {np.percentile(Lr, 90):.4g} m, min {Lr.min():.4g} m, "
         f"max {Lr.max():.4g} m" if r.any() else "* no line reached the wall both ways"),
        (f"* lower bounds: the lines that did not reach the wall were traced ≥ {lc.traced[lc.unreached].min():.4g} m "
         f"(both ways together): L_c is larger" if lc.unreached.any() else "* every line reached the wall or failed"),
        f"* steps taken, both ways: {taken:,} ({taken / times[native] * 1e-6:.2f} M steps/s of the whole phase, "
        "exits and checks included; a line that stopped counts to its exit step)",
        f"* Dask: {sub.size} of the lines (every {max(1, N // sub.size)}-th) on a `LocalCluster` of 2 worker processes × "
        f"1 thread, the method rebuilt in each worker by the command's builder: **{'equal bit for bit' if same else 'NOT equal'}** "
        "to the in-process run (statuses, lengths, exit points, both ways), cold (first call: workers build the grid "
        "and the method) and warm",
        f"* the step: {chk.size} lines again at h/2 = {a.h / 2}: the same status for {100 * agree_status:.1f} %; of the "
        f"{int(both.sum())} that reached the wall at both steps, |ΔL_c|/L_c median {np.median(rel):.2e}, "
        f"{100 * np.mean(rel < 1e-2):.1f} % within 1 %, {100 * np.mean(rel < 0.1):.1f} % within 10 %, max {rel.max():.2e}; "
        f"median L_c of the subset's reached lines at h, h/2, h/4: {np.median(lc.L[chk][lc.reached[chk]]):.4g}, "
        f"{np.median(half.L[half.reached]):.4g}, {np.median(quarter.L[quarter.reached]):.4g} m "
        f"({int(lc.reached[chk].sum())}, {int(half.reached.sum())}, {int(quarter.reached.sum())} lines)"
        if both.any() else f"* the step: {chk.size} lines at h/2, none reached the wall at both",
        (f"* against h/4 = {a.h / 4} ({int(all3.sum())} lines that reached the wall at all three steps): |ΔL_c|/L_c "
         f"of h median {np.median(d1):.2e}, of h/2 median {np.median(d2):.2e} (ratio {np.median(d1) / max(np.median(d2), 1e-300):.1f}; "
         f"4 for an O(h²) error); 90th percentiles {np.percentile(d1, 90):.2e} and {np.percentile(d2, 90):.2e}"
         if all3.any() else "* no line reached the wall at h, h/2 and h/4"),
        f"* stellarator symmetry on φ = 0, L_bwd(R, Z) = L_fwd(R, −Z): {pairs.shape[0]} mirror pairs, the same "
        f"status for {100 * sym_status:.1f} %; of the {int(ok.sum())} that reached the wall, |ΔL|/L median "
        f"{np.median(sym_rel):.2e}, max {sym_rel.max():.2e}, {100 * np.mean(sym_rel < 1e-2):.1f} % within 1 %"
        if ok.any() else "* symmetry: no mirror pair reached the wall",
        "",
        "![W7-X connection length](../../docs/figures/w7x_connection_length.png)",
        "",
        "Reproduce: `PYTHONPATH=$PWD/src nice -n 5 .venv/bin/python benchmarks/studies/study_connection_length.py` "
        "(or the same map from the command line: `vpforms fieldlines --device w7x --wall divertor "
        f"--connection-length {a.lines} --lc-depth {a.depth} --lc-transits {a.transits:g} --h {a.h}`).",
        "",
    ]
    Path(a.results).write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

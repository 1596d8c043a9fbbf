"""vpforms, DESC and ESSOS at the size of issue #21 (100 lines × 1000 transits of one coil set) — never in CI.

The problem of ``bench_peers.py`` (vpforms' l = 2, m = 5 stellarator coils written as a MAKEGRID file
that every tool reads; sections at φ = 2πk/5), at the issue's size: 100 field lines from
(R, Z) = (R_axis + 0.02 … 0.12 m, 0) on φ = 0, 1000 toroidal transits. For every tool and setting:

* **error**: the max over all 100 lines of the distance in (R, Z) of the first 500 section points
  (100 transits, the issue's horizon) from scipy DOP853 (rtol 1e-12) on the coils' own Biot–Savart B;
* **wall time** of 100 lines × 1000 transits, with the compile / fixed cost per call apart.

How each tool runs (one at a time, each in its own process and virtual environment for the peers,
``benchmarks/peers/README.md``):

* vpforms (this process, native backend): the coils' A splined on an (R, φ, Z) grid (several grids:
  the spline's error is what limits the accuracy), B = ∇×A, SE+SE ∘ order 4, ``toroidal_section``.
  A 2-line call of one transit gives the fixed cost (the first call of a method: the kernel's compilation
  or its load from the cache); a 100-transit call of the 100 lines gives the error and each line's time
  per transit; the 1000-transit call then takes ceil(1000 · T_max · 1.02 / h) steps
  (T_max: the slowest line's time per transit), so every line makes ≥ 1000 transits.
* vpforms with **φ as the time** (native, ``run_vpforms_phi_time``): the φ-time field of the same
  spline of A with K splined on a (v, φ, Z) grid, the φ-exact SE+SE composed, n steps per field
  period: the section points are step boundaries (``save_every=n``), mapped back to (R, Z) by U.
* DESC (``peers/run_desc.py``): Biot–Savart of the polylines at every stage, Tsit5 in φ, rtol = atol
  = 1e-8; one 2-transit call (its fixed cost: DESC recompiles per call) and the 1000-transit call.
* ESSOS (``peers/run_essos.py``): Fourier-fitted coils, Dopri8, rtol = atol = 1e-8; at its measured
  cost 1000 transits of 100 lines take hours on 2 cores, so it runs 2 and ``--essos-transits``
  (default 100) transits and its 1000-transit time is **extrapolated** linearly from the marginal
  cost (said so in the table).

    PYTHONPATH=src python benchmarks/peers/bench_peers_issue_size.py [--tools vpforms,desc,essos] [--smoke]
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
from bench_peers import R_AXIS, RK_TOL, _run_peer  # noqa: E402

NFP = 5
BOX_R, BOX_Z = (0.80, 1.18), (-0.18, 0.18)


def _error(R, Z, rR, rZ, n):
    """max over lines of the (R, Z) distance of the first n section points; R, Z (n', lines)."""
    R, Z = np.asarray(R, float), np.asarray(Z, float)
    k = min(n, R.shape[0])
    return float(np.max(np.hypot(R[:k] - rR[:k], Z[:k] - rZ[:k]))), k


def _per_line(s, n_lines, n_points):
    """(R, Z) of shape (n_points, n_lines) and each line's time per transit, from a section result
    (crossings of φ = 0 mod 2π/5 after t = 0)."""
    R, Z, T = np.full((n_points, n_lines), np.nan), np.full((n_points, n_lines), np.nan), np.zeros(n_lines)
    for i in range(n_lines):
        k = (s.line == i) & (s.t > 1e-9)  # the start on φ = 0 is not a crossing
        r, z, t = s.R[k][:n_points], s.Z[k][:n_points], s.t[k][:n_points]
        R[: r.size, i], Z[: z.size, i] = r, z
        T[i] = t[-1] / (t.size / NFP) if t.size else np.inf
    return R, Z, T


def run_vpforms(x_R, ref, settings, n_acc_tr, transits, coils):
    """The vpforms rows, one per setting (grid, order, h)."""
    import vpforms
    from vpforms.fieldlines import toroidal_section
    from vpforms.problems.coil_fields import spline_coil_field
    from vpforms.toroidal import to_toroidal

    x0 = np.asarray(to_toroidal(np.c_[x_R, np.zeros_like(x_R), np.zeros_like(x_R)]))
    t_guess = 2 * np.pi * 1.2**2  # φ̇ = B_φ/R ≈ 1/R²: a generous time per transit
    rows, compiled = [], set()
    for grid in dict.fromkeys(g for g, _, _ in settings):
        t = time.perf_counter()
        field, spline_err = spline_coil_field(coils, BOX_R, BOX_Z, n_R=grid[0], n_phi=grid[1], n_Z=grid[2],
                                              name="peers")
        t_spline = time.perf_counter() - t
        for order, h in [(o, h) for g, o, h in settings if g == grid]:
            m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=order)
            n20 = int(np.ceil(n_acc_tr * t_guess / h))
            # the fixed cost: a 2-line call of one transit, the first of each method (the kernel's
            # compilation, or its load from the on-disk cache)
            t = time.perf_counter()
            toroidal_section(m, x0[:2], h, int(t_guess / h), phi=0.0, nfp=NFP, direction=1, progress=False)
            t_fixed = time.perf_counter() - t
            first = (order not in compiled)
            compiled.add(order)
            s = toroidal_section(m, x0, h, n20, phi=0.0, nfp=NFP, direction=1, progress=False)
            R, Z, T = _per_line(s, x_R.size, n_acc_tr * NFP)
            err, k = _error(R, Z, *ref, n_acc_tr * NFP)
            n = int(np.ceil(transits * float(np.max(T)) * 1.02 / h))
            t = time.perf_counter()
            big = toroidal_section(m, x0, h, n, phi=0.0, nfp=NFP, direction=1, progress=False)
            wall = time.perf_counter() - t
            sec = big.section
            least = float(np.min(np.asarray(sec.counts)) / NFP)
            rows.append(dict(tool="vpforms", setting=f"{grid[0]}×{grid[1]}×{grid[2]} spline (B error "
                             f"{spline_err:.1e}, built in {t_spline:.0f} s), SE+SE ∘ order {order}, h = {h:g}",
                             error=err, points=k, wall=wall, fixed=(t_fixed if first else None),
                             size=f"{x_R.size} × {transits} ({n:,} steps; ≥ {least:.0f} transits each)",
                             backend=sec.backend, load=os.getloadavg()[0], extrapolated=False))
            print(rows[-1], flush=True)
    return rows


def run_vpforms_phi_time(x_R, ref, settings, n_acc_tr, transits, coils):
    """The vpforms rows with φ as the time, one per setting (A grid, K grid, order, n steps per field
    period): the φ-time field of the spline of A with K splined on the K grid
    (``phi_time_field(..., grid=)``), the φ-exact SE+SE composed to the order; the section points are
    every n-th step (``save_every=n``), mapped back to (R, Z) by U (Newton, vectorised; timed)."""
    import vpforms
    from vpforms.phitime import (
        from_phi_time,
        phi_time_field,
        phi_time_scheme,
        to_phi_time,
    )
    from vpforms.problems.coil_fields import spline_coil_field

    x0 = np.c_[x_R**2 / 2, np.zeros_like(x_R), np.zeros_like(x_R)]
    rows, compiled, fields = [], set(), {}
    for grid, kgrid, order, n in settings:
        t = time.perf_counter()
        if (grid, kgrid) not in fields:  # the φ-time field, built once per (A grid, K grid)
            field, spline_err = spline_coil_field(coils, BOX_R, BOX_Z, n_R=grid[0], n_phi=grid[1], n_Z=grid[2],
                                                  name="peers")
            pf = phi_time_field(field, grid=kgrid, name="peers φ-time")  # the box: the spline's grid
            fields[grid, kgrid] = (pf, spline_err, time.perf_counter() - t)
        pf, spline_err, t_build = fields[grid, kgrid]
        m = phi_time_scheme(pf, "SE+SE", order=order)
        y0 = np.asarray(to_phi_time(pf, x0))
        h = 2 * np.pi / NFP / n

        def sections(n_tr):
            sol = vpforms.integrate(m, y0, h, n * NFP * n_tr, save_every=n, backend="native", progress=False)
            x = np.asarray(from_phi_time(pf, sol.xs[:, 1:]))  # (lines, sections, 3) → (R, Z) (sections, lines)
            return np.sqrt(2 * x[..., 0]).T, x[..., 2].T, sol

        t = time.perf_counter()  # the fixed cost, as run_vpforms's
        vpforms.integrate(m, y0[:2], h, n * NFP, save_every=n, backend="native", progress=False)
        t_fixed = time.perf_counter() - t
        first = (order, kgrid) not in compiled
        compiled.add((order, kgrid))
        R, Z, _ = sections(n_acc_tr)
        err, k = _error(R, Z, *ref, n_acc_tr * NFP)
        t = time.perf_counter()
        R, Z, sol = sections(transits)
        wall = time.perf_counter() - t
        rows.append(dict(tool="vpforms", setting=f"φ as the time: {grid[0]}×{grid[1]}×{grid[2]} spline of A (B error "
                         f"{spline_err:.1e}), K on a {kgrid[0]}×{kgrid[1]}×{kgrid[2]} (v, φ, Z) grid (b error "
                         f"{pf.phi_time_spline_error:.1e}; built in {t_build:.0f} s), φ-exact SE+SE ∘ order {order}, "
                         f"{n} steps per field period ({n * NFP} per transit)",
                         error=err, points=k, wall=wall, fixed=(t_fixed if first else None),
                         size=f"{x_R.size} × {transits} ({n * NFP * transits:,} steps; {sol.n_failed} failed)",
                         backend="native", load=os.getloadavg()[0], extrapolated=False))
        print(rows[-1], flush=True)
    return rows


def run_peers(tools, venvs, work):
    """({tool: its JSON result} of the peers in ``tools`` that ran, {tool: why not} of the others):
    each in its own environment ``<venvs>/<tool>`` (``bench_peers._run_peer``), one after the other."""
    results, failures, log = {}, {}, []
    for tool in ("desc", "essos"):
        if tool not in tools:
            continue
        py = os.path.join(venvs, tool, "bin", "python")
        if not os.path.exists(py):
            failures[tool] = f"no virtual environment at {os.path.dirname(os.path.dirname(py))} (skipped)"
            continue
        res, err = _run_peer(tool, py, work, log)
        print(log[-1], flush=True)
        if res is None:
            failures[tool] = f"the run failed: {err.splitlines()[-1] if err else '?'}"
        else:
            results[tool] = res
    return results, failures


def peer_row(res, ref, n_acc_tr, transits):
    """A peer's table row: its error, and its wall time for ``transits`` (extrapolated from the
    marginal cost where it ran fewer)."""
    run = res["runs"][0]
    e, k = _error(run["R"], run["Z"], *ref, n_acc_tr * NFP)
    lines = run["lines"]
    if run["transits"] >= transits:
        wall, extra = run["t_acc"], False
    else:  # marginal cost per line-transit after the fixed cost, times the size
        per = (run["t_acc"] - run["t_short"]) / (run["transits"] - run["short_transits"])
        wall, extra = run["t_short"] + per * (transits - run["short_transits"]), True
    size = f"{lines} × {transits}" + (f" (measured: {lines} × {run['transits']} in {run['t_acc']:.0f} s)"
                                      if extra else "")
    return dict(tool=res["tool"], setting=f"{res['version']}: {run['label']}", error=e, points=k, wall=wall,
                fixed=run["t_short"], size=size, backend="CPU", load=res["loadavg_end"][0], extrapolated=extra)


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_peers_issue_size.md"), rounds=1)
    ap.add_argument("--venvs", default=os.environ.get("VPFORMS_PEER_VENVS", "/work/peers"),
                    help="folder holding the peers' virtual environments <venvs>/desc, <venvs>/essos")
    ap.add_argument("--work", default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--tools", default="vpforms,desc,essos", help="comma-separated subset to run")
    ap.add_argument("--rows", default="time,phi", help="which vpforms rows: time (time stepping), phi (φ as the time)")
    ap.add_argument("--reuse", default="", help="comma-separated peers not re-run: their <work>/<tool>.json "
                    "of an earlier run (same --work) is re-analysed, and the table says so")
    ap.add_argument("--essos-transits", type=int, default=100, help="transits ESSOS runs (then extrapolated)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    import jax

    from vpforms.coils import l2_stellarator, write_makegrid

    smoke = args.smoke
    n_lines, transits, n_acc_tr = (4, 4, 2) if smoke else (100, 1000, 100)
    # (grid, order, h): the spline's error limits the accuracy (order 4 gains nothing below h = 0.025
    # on the 40×32×40 grid), so the finer grid gets the smaller steps and order 6
    fine = (96, 64, 96)
    settings = ([((12, 8, 12), 2, 0.05)] if smoke else [(fine, 4, 0.025), (fine, 6, 0.025)])
    # φ as the time: (A grid, K grid, order, steps per field period); K's error is set by its φ
    # resolution (K has more φ structure than A: 32 → 64 → 128 nodes per period gave b errors
    # 9.4e-4, 1.1e-4, 6.3e-5 on the 40×32×40 A) and at the Z edges, so the K grid is fine in φ and Z
    kfine = (48, 256, 96)  # (v, φ, Z), uniform nodes
    phi_settings = ([((12, 8, 12), (8, 16, 8), 2, 4)] if smoke else
                    [(fine, kfine, 4, 20), (fine, kfine, 4, 32), (fine, kfine, 6, 16), (fine, kfine, 6, 24)])
    work = args.work or tempfile.mkdtemp(prefix="vpforms-peers-size-")
    os.makedirs(work, exist_ok=True)
    coils = l2_stellarator()
    write_makegrid(coils, os.path.join(work, "coils.l2_stellarator"))
    x_R = R_AXIS + np.linspace(0.02, 0.12, n_lines)
    rng = np.random.default_rng(0)
    R, ph, Z = rng.uniform(0.9, 1.1, 50), rng.uniform(0, 2 * np.pi, 50), rng.uniform(-0.08, 0.08, 50)
    problem = {
        "coils_file": "coils.l2_stellarator", "nfp": NFP, "R0": x_R.tolist(), "Z0": [0.0] * n_lines,
        "accuracy_transits": transits, "short_transits": 2 if not smoke else 1, "long_line": 0,
        "long_transits": {"desc": 1, "essos": 1}, "rk_tol": RK_TOL,
        "check_points": np.c_[R * np.cos(ph), R * np.sin(ph), Z].tolist(),
        # ESSOS at the full size would take hours: fewer transits, extrapolated (module docstring)
        "accuracy_transits_by_tool": {"essos": min(args.essos_transits, transits)}, "own_reference": False,
    }
    with open(os.path.join(work, "problem.json"), "w") as fh:
        json.dump(problem, fh)

    B = jax.jit(coils.B)
    t = time.perf_counter()
    ref = dop853_section(lambda x: np.asarray(B(x)), x_R, np.zeros(n_lines), NFP, n_acc_tr * NFP)
    t_ref = time.perf_counter() - t
    print(f"reference {t_ref:.0f} s", flush=True)

    tools = args.tools.split(",")
    which = args.rows.split(",")
    rows = run_vpforms(x_R, ref, settings, n_acc_tr, transits, coils) if "vpforms" in tools and "time" in which else []
    if "vpforms" in tools and "phi" in which:
        rows += run_vpforms_phi_time(x_R, ref, phi_settings, n_acc_tr, transits, coils)
    results, failures = run_peers(tools, args.venvs, work)
    reused = []
    for tool in (t for t in args.reuse.split(",") if t and t not in tools):
        path = os.path.join(work, f"{tool}.json")
        if os.path.exists(path):
            with open(path) as fh:
                results[tool] = json.load(fh)
            reused.append(tool)
    rows += [peer_row(res, ref, n_acc_tr, transits) for res in results.values()]

    table = [f"| tool | settings | error at {n_acc_tr} transits, {n_lines} lines (m) | size (lines × transits) | wall time (s) | "
             "compile / fixed cost per call (s) | load |", "|---|---|---:|---|---:|---:|---:|"]
    for r in rows:
        wall = f"{r['wall']:.0f} (extrapolated)" if r["extrapolated"] else f"{r['wall']:.1f}"
        fixed = "—" if r["fixed"] is None else f"{r['fixed']:.1f}"
        table.append(f"| {r['tool']} | {r['setting']} | {r['error']:.1e} | {r['size']} | {wall} | {fixed} | "
                     f"{r['load']:.1f} |")
    text = "\n".join([
        "# vpforms, DESC and ESSOS at the size of issue #21: 100 lines × 1000 transits", "",
        (f"The coil set of `results_peers.md` (l = 2 stellarator, 22 polylines, 1760 segments, one MAKEGRID "
         f"file); {n_lines} lines from R = R_axis + 0.02 … 0.12 m, Z = 0. Error = max over all {n_lines} lines of "
         f"the (R, Z) distance of the first {n_acc_tr * NFP} section points (φ = 2πk/5) from scipy DOP853 "
         f"(rtol 1e-12) on the coils' Biot–Savart B ({t_ref:.0f} s). vpforms: native, its own fixed-step "
         "methods on the exactly divergence-free curl of a spline of A; the compile column is its first "
         "(2-line, 1-transit) call of each method, with the kernel's gcc compilation or, when an earlier run "
         "built it, its load from the on-disk cache; '—' where this run had already loaded it. DESC: Biot–Savart of the polylines at every Tsit5 stage, one call per size (it recompiles "
         "per call: the fixed cost is its 2-transit call). ESSOS: its Fourier-fitted coils (7.9e-4 from the "
         "polylines' B, `results_peers.md`), Dopri8; 1000 transits are extrapolated from its marginal cost. "
         "One tool at a time, each on the same 2 cores (load average at the end of each run)."), "",
        *table, "",
        *([f"* {t}: {why}" for t, why in failures.items()] + [""] if failures else []),
        *([f"* Re-analysed from an earlier run of this script (same work folder and problem, not re-run): "
           f"{', '.join(reused)}.", ""] if reused else []),
        machine("bench_peers_issue_size.py", time.perf_counter() - t0, smoke), ""])
    return write_results(args.out, text)


if __name__ == "__main__":
    sys.exit(main())

"""DESC on the common problem (runs in DESC's environment): ``python benchmarks/peers/run_desc.py WORKDIR``.

Pipeline: MAKEGRID coils → ``desc.coils.MixedCoilSet.from_makegrid_coilfile`` (SplineXYZCoils) →
B by Biot–Savart (Hanson–Hirshman straight segments) evaluated directly at every stage →
``desc.magnetic_fields.field_line_integrate`` (diffrax Tsit5, φ as the time, PID step control,
rtol = atol = 1e-8: DESC's defaults; ``rk_tols`` in the problem: one accuracy run per tolerance, for
an accuracy–wall-time curve), output at φ = 2πk/nfp. The coils are read with
``method="linear"`` and a source grid at the knots, so that DESC's segments are exactly the file's
polylines (its default, ``method="cubic"`` on 2N+5 points, re-interpolates them: the difference in
B is reported). Writes ``desc.json``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _peer_common import accuracy_transits, load_problem, timed, write_result  # noqa: E402


def main() -> int:
    P, work = load_problem()
    t0 = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    from importlib.metadata import version
    from desc.coils import MixedCoilSet
    from desc.grid import Grid
    from desc.magnetic_fields import field_line_integrate

    path = os.path.join(work, P["coils_file"])
    cs = MixedCoilSet.from_makegrid_coilfile(path, method="linear", ignore_groups=True)
    grids = [Grid(np.c_[0 * np.asarray(c.knots), 0 * np.asarray(c.knots), np.asarray(c.knots)], jitable=True)
             for c in cs]
    pts = np.asarray(P["check_points"])
    B_lin = np.asarray(cs.compute_magnetic_field(pts, basis="xyz", source_grid=grids))
    B_def = np.asarray(MixedCoilSet.from_makegrid_coilfile(path, ignore_groups=True)
                       .compute_magnetic_field(pts, basis="xyz"))
    nfp, tol = P["nfp"], P["rk_tol"]
    period = 2 * np.pi / nfp
    R0, Z0 = np.asarray(P["R0"]), np.asarray(P["Z0"])

    def trace(r0, z0, transits, tol=tol):
        phis = period * np.arange(transits * nfp + 1)
        r, z = field_line_integrate(r0, z0, phis, cs, source_grid=grids, rtol=tol, atol=tol)
        return np.asarray(r)[1:], np.asarray(z)[1:]

    n_short, n_acc = P["short_transits"], accuracy_transits(P, "desc")
    runs = []
    for tl in P.get("rk_tols", [tol]):  # each: its fixed cost (DESC recompiles per call), then the run
        t_short, _ = timed(lambda: trace(R0, Z0, n_short, tl))
        t_acc, (R, Z) = timed(lambda: trace(R0, Z0, n_acc, tl))
        print("desc accuracy", tl, t_short, t_acc, flush=True)
        runs.append({"label": f"Tsit5 rtol=atol={tl:g}", "rtol": tl, "R": R, "Z": Z, "t_short": t_short,
                     "t_acc": t_acc, "short_transits": n_short, "transits": n_acc, "lines": len(R0)})
    line = P["long_line"]
    L = P["long_transits"]["desc"]
    t_long, (RL, ZL) = timed(lambda: trace(R0[line:line + 1], Z0[line:line + 1], L))
    print("desc long", t_long, flush=True)
    write_result(work, "desc", {
        "tool": "DESC", "version": version("desc-opt"), "jax": jax.__version__,
        "pipeline": "MAKEGRID → SplineXYZCoil (linear, source grid at the knots = the polylines) → "
                    "Biot–Savart (Hanson–Hirshman) at every stage; diffrax Tsit5 in φ, PID rtol=atol="
                    f"{tol:g}",
        "field_check_B": B_lin, "field_check_B_default_cubic": B_def,
        "runs": [*runs, {"label": "long", "R": RL, "Z": ZL, "t": t_long, "transits": L, "lines": 1, "rtol": tol}],
        "total_s": time.perf_counter() - t0,
    })
    return 0


if __name__ == "__main__":
    sys.exit(main())

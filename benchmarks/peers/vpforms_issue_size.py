"""vpforms alone on the peer problem at the size issue #21 names (100 lines × 1000 transits), natively.

The coil set and spline of ``bench_peers.py`` (l = 2 stellarator coils, MAKEGRID file → A on a
40×32×40 grid → C² spline; B = ∇×A), SE+SE compositions, sections φ = 0 (mod 2π/5) by
``toroidal_section`` on the native backend. Per setting:

* the section error after 20 transits, max over the lines at R_axis + (0.04, 0.08, 0.12) m and the
  first 100 section points, against scipy DOP853 (rtol 1e-12) on the coils' own Biot–Savart B —
  the same reference and lines as ``results_peers.md``;
* the wall time of 100 lines (R_axis + 0.02 … 0.12 m) × at least 1000 transits (one call, after a
  call that compiled or loaded the kernel).

The peers are not run here (ESSOS' measured 45–120 ms per transit per line would take 1.3–3.3 h
at this size on 2 shared cores; DESC pays ~50 s per call): compare with ``results_peers.md``.

    PYTHONPATH=src python benchmarks/peers/vpforms_issue_size.py [--coils FILE] [--smoke]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
from _bench import machine, write_results  # noqa: E402
from _peer_common import dop853_section  # noqa: E402

R_AXIS, NFP = 0.983112, 5


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--coils", default=None, help="MAKEGRID coils file (default: written from l2_stellarator())")
    ap.add_argument("--smoke", action="store_true", help="tiny sizes (checks the script runs)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "results_peers_issue_size.md"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    import jax

    import vpforms
    from vpforms.coils import l2_stellarator, read_makegrid, write_makegrid
    from vpforms.fieldlines import toroidal_section
    from vpforms.problems.coil_fields import spline_coil_field
    from vpforms.toroidal import to_toroidal

    path = args.coils
    if path is None:
        path = os.path.join(tempfile.mkdtemp(prefix="vpforms-peers-"), "coils.l2_stellarator")
        write_makegrid(l2_stellarator(), path)
    coils = read_makegrid(path)
    field, spline_err = spline_coil_field(coils, (0.80, 1.18), (-0.18, 0.18), n_R=40, n_phi=32, n_Z=40, name="peers")
    n_acc, transits, n_lines = (10, 20, 10) if args.smoke else (100, 1000, 100)
    R3 = R_AXIS + np.array([0.04, 0.08, 0.12])
    B = jax.jit(coils.B)
    rR, rZ = dop853_section(lambda x: np.asarray(B(x)), R3, np.zeros(3), NFP, n_acc)
    t_transit = 2 * np.pi * 1.2**2  # φ̇ = B_φ/R ≈ 1/R²: a generous time per transit

    def points(x0):
        return np.asarray(to_toroidal(np.c_[x0, np.zeros_like(x0), np.zeros_like(x0)]))

    def section(m, h, x0, tr):
        n = int(np.ceil(tr * t_transit / h))
        return toroidal_section(m, x0, h, n, phi=0.0, nfp=NFP, direction=1, progress=False), n

    rows = []
    settings = [(2, 0.05), (2, 0.0125), (4, 0.05), (4, 0.025)] if not args.smoke else [(2, 0.05)]
    for order, h in settings:
        m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=order)
        t = time.perf_counter()
        s, _ = section(m, h, points(R3), n_acc // NFP)
        t_first = time.perf_counter() - t
        err = 0.0
        for i in range(3):
            k = (s.line == i) & (s.t > 1e-9)  # the start point on φ = 0 is not a crossing
            R, Z = s.R[k][:n_acc], s.Z[k][:n_acc]
            err = max(err, float(np.max(np.hypot(R - rR[: R.size, i], Z - rZ[: R.size, i]))))
        x100 = points(R_AXIS + np.linspace(0.02, 0.12, n_lines))
        t = time.perf_counter()
        big, n = section(m, h, x100, transits)
        wall = time.perf_counter() - t
        assert big.section.backend == "native", big.section.backend_reason
        least = float(np.min(np.asarray(big.section.counts)) / NFP)
        rows.append(f"| SE+SE ∘ order {order} | {h:g} | {err:.1e} | {n_lines} × {transits} ({n:,} steps; "
                    f"≥ {least:.0f} transits each) | {wall:.1f} | {t_first:.1f} | {os.getloadavg()[0]:.1f} |")
        print(rows[-1], flush=True)
    text = "\n".join([
        "# vpforms on the peer problem at the size of issue #21 (native)", "",
        (f"The coil set, spline (40×32×40, max|B − B_coils|/max|B| = {spline_err:.1e} at 400 seeded points of the grid box, "
         "`spline_coil_field`) and reference of `results_peers.md`; error = max distance in (R, Z) of the "
         f"first {n_acc} section points of 3 lines from DOP853 on the coils' Biot–Savart B; wall time of "
         f"{n_lines} lines × ≥ {transits} transits, one call, native, 2 OpenMP threads. First call = the "
         "3-line accuracy call, with the kernel's compilation when it is not cached. The peers are not "
         "run at this size (see the script's docstring); `results_peers.md` has them at 3 lines."), "",
        "| method | h | error at 20 transits (m) | size | wall time (s) | first call (s) | load |",
        "|---|---:|---:|---|---:|---:|---:|", *rows, "",
        machine("peers/vpforms_issue_size.py", time.perf_counter() - t0, args.smoke), ""])
    return write_results(args.out, text)


if __name__ == "__main__":
    sys.exit(main())

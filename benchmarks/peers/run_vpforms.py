"""vpforms on the common problem (runs in vpforms' own environment): ``python benchmarks/peers/run_vpforms.py WORKDIR``.

Pipeline: MAKEGRID coils → ``vpforms.coils.read_makegrid`` → the coils' vector potential A
(Hanson–Hirshman, closed form) sampled on a 40 × 32 × 40 (R, φ, Z) grid over one field period →
C² cubic spline of A in (u = R²/2, φ, Z) → B = ∇×A of the spline (exactly divergence free) →
SE+SE composed to order 2 (``recover=False``), fixed step h, crossings of φ = 2πk/nfp located on the
method's own step family (``vpforms.fieldlines.toroidal_section``). Writes ``vpforms.json``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _peer_common import dop853_section, load_problem, timed, write_result  # noqa: E402


def main() -> int:
    P, work = load_problem()
    t0 = time.perf_counter()
    import jax

    import vpforms
    from vpforms.coils import read_makegrid
    from vpforms.fieldlines import toroidal_section
    from vpforms.problems.coil_fields import spline_coil_field
    from vpforms.toroidal import cartesian_field, to_toroidal

    coils = read_makegrid(os.path.join(work, P["coils_file"]))
    nfp = coils.nfp
    t = time.perf_counter()
    field, spline_err = spline_coil_field(coils, (0.80, 1.18), (-0.18, 0.18), n_R=40, n_phi=32, n_Z=40,
                                          name="peers")
    t_spline = time.perf_counter() - t
    R0, Z0 = np.asarray(P["R0"]), np.asarray(P["Z0"])
    x0 = np.asarray(to_toroidal(np.c_[R0, np.zeros_like(R0), Z0]))
    m = vpforms.compose(vpforms.scheme(field, "SE+SE", recover=False), order=2)
    t_transit = 2 * np.pi * (R0.max() + 0.05) ** 2  # φ̇ = B_φ/R ≈ 1/R² (B0 R0 = 1 T m): time of one transit, generous

    def section(h, transits):
        n = max(int(np.ceil(transits * t_transit / h)), 20480)  # ≥ 20480 steps: the same compiled segment scan
        sec = toroidal_section(m, x0, h, n, phi=0.0, nfp=nfp, direction=1, progress=False)
        Rs, Zs, ts = [], [], []
        for i in range(len(R0)):
            k = sec.line == i
            R, Z, tt = sec.R[k], sec.Z[k], sec.t[k]
            keep = tt > 1e-9  # the start point on φ = 0 is not a crossing
            Rs.append(R[keep][: transits * nfp]), Zs.append(Z[keep][: transits * nfp]), ts.append(tt[keep][: transits * nfp])
        n_min = min(len(r) for r in Rs)
        traced = np.asarray(sec.section.counts) / nfp  # transits each line made in the n steps
        return (np.stack([r[:n_min] for r in Rs], 1), np.stack([z[:n_min] for z in Zs], 1), n,
                int(sec.section.n_fallback), traced)

    runs = []
    for label, h, transits in P["vpforms_runs"]:
        t1, (R, Z, n, fb, traced) = timed(lambda: section(h, transits))
        t2, (R, Z, n, fb, traced) = timed(lambda: section(h, transits))
        runs.append({"label": label, "h": h, "n_steps": n, "transits": R.shape[0] // nfp, "R": R, "Z": Z,
                     "first_s": t1, "best_s": min(t1, t2), "compile_s": max(t1 - t2, 0.0),
                     "traced_transits": traced, "n_fallback": fb})
        print(label, h, n, R.shape, t1, t2, flush=True)

    # reference on vpforms' own field (the spline): separates the integrator's error from the spline's
    curl = jax.jit(field)

    def B_xyz(xyz):
        p = to_toroidal(xyz)
        return np.asarray(cartesian_field(curl(p), p))

    n_acc = P["accuracy_transits"] * nfp
    t_ref, (Rr, Zr) = timed(lambda: dop853_section(B_xyz, R0, Z0, nfp, n_acc))
    pts = np.asarray(P["check_points"])
    write_result(work, "vpforms", {
        "tool": "vpforms", "version": vpforms.__version__, "jax": jax.__version__,
        "pipeline": "coils → A (closed form) on a 40×32×40 grid → C² spline of A → B = ∇×A (exact div-free); "
                    "SE+SE order 2, fixed h, crossings on the step family",
        "field_check_B": np.asarray(B_xyz(pts)), "spline_error": spline_err, "spline_build_s": t_spline,
        "runs": runs, "own_ref_R": Rr, "own_ref_Z": Zr, "own_ref_s": t_ref,
        "total_s": time.perf_counter() - t0,
    })
    return 0


if __name__ == "__main__":
    sys.exit(main())

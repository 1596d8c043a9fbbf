"""Spline fields on the native backend (issue #20 item 4), written to results_native_splines.md.

One process, SE+SE (recover=False), ns per particle-step (best of ``--rounds`` after a warm-up
that compiles and loads):

* the closed-form tokamak (``problems.get("tokamak")``, Cartesian SymPy), native — the reference;
* a spline of the same tokamak's vector potential on an (R, φ, Z) grid, in (u = R²/2, φ, Z)
  (``grids.cylindrical_potential``: A_u = 0, A_φ = ψ + εR²χ, A_Z = −(B₀/R₀)u, the covariant
  components of the model's A), native, from the same initial conditions;
* the coil stellarator (``problems.get("coil_stellarator")``: the coils' A splined), native;
* both spline fields on JAX (fewer particles: it is that much slower).

Per particle-step: (runs of 2n steps − runs of n steps) / (N·n), so that a run's fixed costs
(the check of the initial conditions by JAX, ~0.5 s on a spline field) cancel.

Ratios: native spline ÷ native closed form (issue: ≤ 5×), JAX ÷ native on the same field
(issue: ≥ 20×). All rows of one run: same process, same load.

    PYTHONPATH=src python benchmarks/native/bench_native_splines.py [--smoke]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import fresh_native_cache, machine, native_missing, parser, per_step, write_results

import vpforms
from vpforms import problems
from vpforms.grids import cylindrical_potential
from vpforms.toroidal import to_toroidal, toroidal_field

R0, B0, EPS = 1.0, 1.8, 0.01  # the tokamak problem's defaults (m, n) = (2, 1)


def tokamak_A(R, phi, Z):
    """Physical cylindrical (A_R, A_φ, A_Z) of the tokamak model (problems/tokamak.py):
    A = (ψ/R² + εχ)(−x₂, x₁, 0) − (B₀/R₀)(R²/2) e_z, ψ = (R² − R₀²)²/8 + R²Z²/2,
    χ = Re[w²(x₁ − ix₂)]/R₀, w = (R² − R₀²)/(2R₀) + iZ."""
    psi = (R**2 - R0**2) ** 2 / 8 + R**2 * Z**2 / 2
    w = (R**2 - R0**2) / (2 * R0) + 1j * Z
    chi = np.real(w**2 * R * np.exp(-1j * phi)) / R0
    return np.stack([np.zeros_like(R), psi / R + EPS * R * chi, -(B0 / R0) * R**2 / 2])


def tokamak_spline(n_R: int, n_phi: int, n_Z: int):
    R = np.linspace(0.45, 1.55, n_R)
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    Z = np.linspace(-0.6, 0.6, n_Z)
    A = tokamak_A(*np.meshgrid(R, phi, Z, indexing="ij"))
    pot, _ = cylindrical_potential(R, phi, Z, nfp=1, A=A, source="tokamak model")
    field = toroidal_field(pot, pot.grid_box, nfp=1, name="tokamak (spline of A)", origin=pot.center)
    field.inside = pot.inside  # a line that leaves the grid stops with left_domain
    return field


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_native_splines.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    smoke = args.smoke
    rounds = 1 if smoke else args.rounds
    fresh_native_cache()
    N, NJ, n, h = (200, 20, 5, 0.01) if smoke else (20_000, 1_000, 100, 0.01)
    tok = problems.get("tokamak")
    x_cart = tok.initial_conditions(N, seed=0)
    spl = tokamak_spline(*((12, 8, 12) if smoke else (48, 32, 48)))
    x_tor = np.asarray(to_toroidal(x_cart))
    # the spline against the model: max |a_spline − a| / max |a| at the initial conditions, a in
    # (u, φ, Z): (R B_R, B_φ/R, B_Z) of the closed form
    B = np.asarray(tok.field(x_cart))
    c, s = np.cos(x_tor[:, 1]), np.sin(x_tor[:, 1])
    Rr = np.sqrt(2 * x_tor[:, 0])
    a = np.stack([Rr * (B[:, 0] * c + B[:, 1] * s), (-B[:, 0] * s + B[:, 1] * c) / Rr, B[:, 2]], -1)
    spline_err = float(np.max(np.abs(np.asarray(spl(x_tor)) - a)) / np.max(np.abs(a)))
    stel = problems.get("coil_stellarator")
    x_st = stel.initial_conditions(N, seed=0)
    runs = [  # (field label, backend, method, x0)
        ("tokamak (closed form)", "native", vpforms.scheme(tok.field, "SE+SE", recover=False), x_cart),
        ("tokamak (spline of A)", "native", vpforms.scheme(spl, "SE+SE", recover=False), x_tor),
        ("coil_stellarator (spline of A)", "native", vpforms.scheme(stel.field, "SE+SE", recover=False), x_st),
    ]
    runs += [(f, "jax", m, x[:NJ]) for f, b, m, x in runs[1:]]
    rows, per = [], {}
    for label, backend, m, x0 in runs:
        def go(steps, m=m, x0=x0, backend=backend):
            return vpforms.integrate(m, x0, h, steps, progress=False, backend=backend)

        per[label, backend], compile_s, sol = per_step(go, n, len(x0), rounds, strict=not smoke)
        assert sol.stats["backend"] == backend, sol.stats
        failed = int(np.sum(np.asarray(sol.status) != 0))
        rows.append((label, backend, len(x0), per[label, backend], compile_s, failed))
    ref = per["tokamak (closed form)", "native"]
    lines = ["# Spline fields on the native backend (issue #20 item 4)", "",
             (f"SE+SE (recover=False), h = {h}, `vpforms.integrate`, one process; ns per "
              f"particle-step = (best of {rounds} runs of {2 * n} steps − best of {rounds} runs of {n} "
              "steps) / (N·n): the cost of stepping, without a run's fixed costs (the check of the "
              "initial conditions, ~0.5 s for a spline field); compile = first call − best call. "
              "The spline's knots and coefficients are passed to the generated kernel at run time. "
              f"Tokamak spline: {'12×8×12' if smoke else '48×32×48'} (R, φ, Z) nodes of "
              f"R ∈ [0.45, 1.55], Z ∈ [−0.6, 0.6]; max|a_spline − a|/max|a| at the initial "
              f"conditions = {spline_err:.2g}."), "",
             ("| field | backend | N | ns / particle-step | × native closed-form tokamak | "
              "JAX ÷ native (same field) | compile (s) | failed |"),
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, backend, Np, t, comp, failed in rows:
        jn = per[label, "jax"] / per[label, "native"] if (label, "jax") in per and backend == "native" else None
        lines.append(f"| {label} | {backend} | {Np:,} | {t:,.0f} | {t / ref:.2f} | "
                     f"{'' if jn is None else f'{jn:.1f}×'} | {comp:.1f} | {failed} |")
    lines += ["", f"Load average at the end: {os.getloadavg()[0]:.1f}.", "",
              machine("bench_native_splines.py", time.perf_counter() - t0, smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

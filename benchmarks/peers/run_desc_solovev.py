"""DESC on the Solov'ev study of issue #24 (runs in DESC's environment): ``python benchmarks/peers/run_desc_solovev.py WORKDIR``.

The field, in (R, φ, Z): ψ = c/2·(R²Z² + κ²/4·(R² − 1)²), c = 1/(κ q₀), B_R = −(1/R)∂ψ/∂Z = −cRZ,
B_Z = (1/R)∂ψ/∂R = c(Z² + κ²/2·(R² − 1)), B_φ = g/R — given to DESC as
``desc.magnetic_fields.MagneticFieldFromUser`` (a JAX function of (R, φ, Z)), traced by
``field_line_integrate`` (diffrax Tsit5 in φ, PID step control) with output at φ = 2πk.
``field_line_integrate`` re-traces and re-compiles on every call (and cannot be wrapped in one
``jax.jit``: it converts traced values with ``int``), so its run time is the marginal cost: the
best of ``rounds`` calls over ``timing_transits`` minus the best over ``short_transits``, scaled to
``timing_transits``; the rest of a call is its fixed cost (compilation), reported separately. Reads ``problem.json`` (κ, q₀, g, the lines,
the transits, the tolerances), writes ``desc_solovev.json``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _peer_common import load_problem, write_result


def main() -> int:
    P, work = load_problem()
    t_start = time.perf_counter()
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    from importlib.metadata import version

    from desc.magnetic_fields import MagneticFieldFromUser, field_line_integrate

    kap, q0, g = P["kappa"], P["q0"], P["g"]
    c = 1.0 / (kap * q0)

    def B_rpz(coords, params):
        R, Z = coords[:, 0], coords[:, 2]
        return jnp.stack([-c * R * Z, g / R, c * (Z * Z + kap**2 / 2 * (R * R - 1.0))], axis=1)

    field = MagneticFieldFromUser(B_rpz)
    R0, Z0 = np.asarray(P["R0"]), np.asarray(P["Z0"])
    runs = []

    def trace(transits, rtol, r0, z0):
        phis = 2 * np.pi * np.arange(transits + 1)
        max_steps = int(P["max_steps_per_transit"] * transits)
        r, z = field_line_integrate(r0, z0, phis, field, rtol=rtol, atol=rtol, max_steps=max_steps)
        return np.asarray(r), np.asarray(z)  # (transits + 1, lines)

    def best(transits, rtol):
        ts = []
        for _ in range(P["rounds"]):
            t = time.perf_counter()
            trace(transits, rtol, R0, Z0)
            ts.append(time.perf_counter() - t)
        return min(ts), ts

    for rtol in P["rtols"]:
        row = {"rtol": rtol}
        t = time.perf_counter()
        row["R_acc"], row["Z_acc"] = trace(P["accuracy_transits"], rtol, R0, Z0)
        row["acc_call_s"] = time.perf_counter() - t
        n_short, n_long = P["short_transits"], P["timing_transits"]
        t_short, row["short_calls_s"] = best(n_short, rtol)
        t_long, row["long_calls_s"] = best(n_long, rtol)
        run = max(t_long - t_short, 0.0) * n_long / (n_long - n_short)
        row["time_s"], row["fixed_s"] = run, t_long - run
        L = P["long_line"]
        t = time.perf_counter()
        r, z = trace(P["long_transits"], rtol, R0[L:L + 1], Z0[L:L + 1])
        row["thick_call_s"] = time.perf_counter() - t
        row["R_long"], row["Z_long"] = r[:, 0], z[:, 0]
        runs.append(row)
        print(f"desc rtol={rtol:g}: {n_long} transits {t_long:.2f} s per call, {n_short} transits "
              f"{t_short:.2f} s → run {run:.2f} s, fixed {row['fixed_s']:.2f} s", flush=True)

    write_result(work, "desc_solovev", {
        "tool": "DESC", "version": version("desc-opt"), "jax": jax.__version__,
        "pipeline": "MagneticFieldFromUser (B of the Solov'ev ψ, B_φ = g/R) → field_line_integrate "
                    "(diffrax Tsit5 in φ, PID rtol = atol)",
        "runs": runs, "total_s": time.perf_counter() - t_start,
    })
    return 0


if __name__ == "__main__":
    sys.exit(main())

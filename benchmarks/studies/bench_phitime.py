"""Cost of a Poincaré section with φ as the time vs time stepping (issue #24 item 1), written to
results_phitime.md.

The field: the Solov'ev tokamak of tests/test_toroidal.py (B_φ = g/R, 3-periodic perturbation
ε = 0.02, Cartesian A), three lines from (R, Z) = (1.1, 0), (1.2, 0.05), (0.9, −0.1) at φ = 0. The
section is φ = 2πk/3; its reference is DOP853 in φ (rtol 1e-12) of dR/dφ = R B_R/B_φ,
dZ/dφ = R B_Z/B_φ. The error of a run is the largest |(R, Z) − reference| over its first 20 section
points (all three lines).

* φ-time: ``vpforms.phitime.phi_time_scheme(field, "SE+SE", order=2 | 4)`` (a φ-exact case: the
  section points are the step boundaries φ = kh·n), n steps per field period, ``vpforms.integrate``
  with ``save_every=n``;
* time stepping: SE+SE composed to order 2 | 4 on the (u, φ, Z) field,
  ``vpforms.diagnostics.poincare_section`` (crossings located on the method's own step family,
  order p), h = T/n with T = 2π/3·1.1² the transit time of the line at R = 1.1; two versions:
  "representative" — ``vpforms.scheme(toroidal_field(A_cart), "SE+SE")``, whose pair integrates
  A_φ along φ by Gauss–Legendre quadrature (the general case of a Cartesian A); "gauge along u" — the
  case (σ, Σ) = ((2,1,3), (3,1,2)) on the same A given as (0, A_φ, A_Z) (its A_u = A_R/R is
  identically 0), whose pair is read off A with no quadrature (the cheapest time stepping here).

Run time per transit and line: best of rounds after compilation (one process; a time-stepping run
has a fixed number of steps, so the number of transits it covers varies with h). Compile = first
call − best call.

    python benchmarks/studies/bench_phitime.py [--smoke] [--rounds R] [--out benchmarks/studies/results_phitime.md]
"""

from __future__ import annotations

import itertools
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from scipy.integrate import solve_ivp

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import best_of, machine, parser, write_results

import vpforms
from vpforms import Case
from vpforms._vecpot import CallablePotential, curl_of
from vpforms.diagnostics import poincare_section
from vpforms.phitime import from_phi_time, phi_time_field, phi_time_scheme, to_phi_time
from vpforms.toroidal import ToroidalPotential, box_from_cylindrical, toroidal_field

KAP, Q0, G, EPS, NFP = 1.5, 1.2, 1.0, 0.02, 3
C = 1 / (KAP * Q0)
PERIOD = 2 * np.pi / NFP
RZ0 = np.array([[1.1, 0.0], [1.2, 0.05], [0.9, -0.1]])
BOX = box_from_cylindrical((0.7, 1.3), (0, PERIOD), (-0.4, 0.4))
KINDS = ("φ-time", "time stepping (representative)", "time stepping (gauge along u)")


def A_cart(x):  # tests/test_toroidal.py
    X, Y, Z = x[0], x[1], x[2]
    R2 = X * X + Y * Y
    psi = C / 2 * (R2 * Z * Z + KAP**2 / 4 * (R2 - 1) ** 2)
    return jnp.stack([-psi * Y / R2, psi * X / R2, -0.5 * G * jnp.log(R2) + EPS * Z * (X**3 - 3 * X * Y * Y)])


def reference(transits):
    B = jax.jit(jax.vmap(curl_of([lambda x, y, z, i=i: A_cart(jnp.stack([x, y, z]))[i] for i in range(3)])))

    def rhs(phi, s):
        R, Z = s.reshape(-1, 2).T
        c, sn = np.cos(phi), np.sin(phi)
        b = np.asarray(B(np.stack([R * c, R * sn, Z], -1)))
        BR, Bp = b[:, 0] * c + b[:, 1] * sn, -b[:, 0] * sn + b[:, 1] * c
        return np.stack([R * BR / Bp, R * b[:, 2] / Bp], -1).ravel()

    phis = PERIOD * np.arange(transits + 1)
    sol = solve_ivp(rhs, (0, phis[-1]), RZ0.ravel(), method="DOP853", rtol=1e-12, atol=1e-14, t_eval=phis)
    return sol.y.T.reshape(transits + 1, -1, 2)


def _cost_at(runs, tol):
    """The cost at section error ``tol`` by log–log interpolation over (error, cost) runs, or None."""
    runs = sorted(runs)
    for (e0, c0), (e1, c1) in itertools.pairwise(runs):
        if e0 <= tol <= e1:
            w = np.log(tol / e0) / np.log(e1 / e0)
            return float(np.exp((1 - w) * np.log(c0) + w * np.log(c1)))
    return None


def timed(fn, rounds):
    t = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t
    best, out = best_of(fn, rounds)
    return out, best, first - best


def main(argv=None) -> int:
    p = parser(__doc__, os.path.join(HERE, "results_phitime.md"), rounds=2)
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    transits = 2 if args.smoke else 20
    ns = (8, 16) if args.smoke else (8, 16, 32, 64)
    rounds = 1 if args.smoke else args.rounds
    ref = reference(transits)
    x0 = np.stack([0.5 * RZ0[:, 0] ** 2, 0 * RZ0[:, 0], RZ0[:, 1]], -1)
    rows = []

    # --- φ as the time ---------------------------------------------------------------------------
    t = time.perf_counter()
    pf = phi_time_field(ToroidalPotential(A_cart, NFP), BOX, name="solovev-3 phi-time")
    build = time.perf_counter() - t
    y0 = np.asarray(to_phi_time(pf, x0))
    for order in (2, 4):
        m = phi_time_scheme(pf, "SE+SE", order=order)
        for n in ns:
            def run(m=m, n=n):
                sol = vpforms.integrate(m, y0, PERIOD / n, n * transits, save_every=n, progress=False, backend="jax")
                return np.asarray(sol.xs), np.asarray(sol.status)

            (ys, status), best, comp = timed(run, rounds)
            x = np.asarray(from_phi_time(pf, np.moveaxis(ys, 0, 1)))  # (transits + 1, lines, 3)
            RZ = np.stack([np.sqrt(2 * x[..., 0]), x[..., 2]], -1)
            err = float(np.abs(RZ - ref).max())
            rows.append(("φ-time", order, n, err, best / (transits * len(x0)), comp, int(np.sum(status != 0))))
            print(rows[-1], flush=True)

    # --- time stepping of the (u, φ, Z) field ----------------------------------------------------
    tf = toroidal_field(A_cart, BOX, nfp=NFP, name="solovev-3")
    _, A_phi, A_Z = ToroidalPotential(A_cart, NFP).components()
    tf_u = toroidal_field(CallablePotential([0, A_phi, A_Z], (None, PERIOD, None)), BOX, name="solovev-3, A_u = 0")
    T = PERIOD * 1.1**2 / G  # the transit time (in t) at R = 1.1 (B^φ = g/R²)
    steps = int(1.6 * transits * max(ns) * (1.3 / 1.1) ** 2)  # enough for `transits` at the finest h
    for label, field, case in (("time stepping (representative)", tf, "SE+SE"),
                               ("time stepping (gauge along u)", tf_u, Case((2, 1, 3), (3, 1, 2)))):
        for order in (2, 4):
            m = vpforms.compose(vpforms.scheme(field, case, recover=False), order)
            for n in ns:
                h = T / n
                nsteps = int(steps * n / max(ns))  # the same number of transits for every h

                def run(m=m, h=h, nsteps=nsteps):
                    return poincare_section(m, x0, h, nsteps, axis=1, value=0.0, direction=1, period=PERIOD,
                                            progress=False)

                sec, best, comp = timed(run, rounds)
                k = np.rint(sec.points[:, 1] / PERIOD).astype(int)
                R, Z = np.sqrt(2 * sec.points[:, 0]), sec.points[:, 2]
                use = k <= transits
                err = float(np.max(np.abs(np.stack([R, Z], -1)[use] - ref[k[use], sec.particle[use]])))
                covered = sec.counts.sum() / len(x0)
                rows.append((label, order, n, err, best / (covered * len(x0)), comp, int(np.sum(sec.status != 0))))
                print(rows[-1], f"covered {covered:.1f} transits/line, missing {transits - use.sum() / len(x0):.1f}",
                      flush=True)

    lines = [
        "# φ as the time vs time stepping: cost of a Poincaré section (issue #24 item 1)",
        "",
        ("Solov'ev tokamak with a 3-periodic perturbation (tests/test_toroidal.py), 3 lines, section "
        "φ = 2πk/3, error = max |(R, Z) − DOP853| over the first "
        f"{transits} section points. φ-time: SE+SE on the (v, φ, Z) field (U by Newton), a φ-exact "
        "case, n steps per field period. Time stepping: SE+SE on the (u, φ, Z) field, `poincare_section`, "
        "h = T/n with T the transit time at R = 1.1; 'representative': the pair by quadrature of A_φ "
        "along φ; 'gauge along u': case ((2,1,3), (3,1,2)) on A = (0, A_φ, A_Z), pair read off A "
        "(see the script's docstring). μs per transit and line: "
        f"best of {rounds} after compilation. Building the φ-time field took {build:.1f} s."),
        "",
        "| tracing | order | n | section error | μs / transit / line | compile (s) | failed |",
        "|---|---|---|---|---|---|---|",
    ]
    for kind, order, n, err, cost, comp, fail in rows:
        lines.append(f"| {kind} | {order} | {n} | {err:.2e} | {1e6 * cost:,.0f} | {comp:.1f} | {fail} |")
    lines += ["", ("Cost at a section accuracy (μs / transit / line), interpolated log–log between the "
              "measured runs (— outside their range):"), "",
              "| accuracy | " + " | ".join(f"{k} order {o}" for k in KINDS for o in (2, 4)) + " |",
              "|---" * (1 + 2 * len(KINDS)) + "|"]
    for tol in (1e-3, 1e-5, 1e-7):
        cells = []
        for kind in KINDS:
            for order in (2, 4):
                got = [(r[3], r[4]) for r in rows if r[0] == kind and r[1] == order]
                cost = _cost_at(got, tol)
                cells.append("—" if cost is None else f"{1e6 * cost:,.0f}")
        lines.append(f"| {tol:.0e} | " + " | ".join(cells) + " |")
    lines += ["", machine("bench_phitime.py", time.perf_counter() - t_start, args.smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())

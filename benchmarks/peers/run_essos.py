"""ESSOS on the common problem (runs in ESSOS's environment): ``python benchmarks/peers/run_essos.py WORKDIR``.

Pipeline: ESSOS has no MAKEGRID coils reader: the file's polylines (read here) are fitted by
ESSOS's Fourier curves (``essos.coils.fit_dofs_from_coils``, uniform in the file's parameter; TF
coils order 1 — the circles through the 64-gon's vertices —, helical windings order 7 — exact for
the smooth helix through the vertices), ``Coils(Curves(…, n_segments=240))`` → ``BiotSavart``
(quadrature on the smooth curves) evaluated directly at every stage → ``essos.dynamics.Tracing``
with ``model="FieldLineAdaptative"`` (Cartesian x, dx/dt = B; ESSOS's default solver diffrax
Dopri8, PID rtol = atol = 1e-8, the tolerance of ESSOS's field-line examples), saved at 200
points per transit. Section points: ESSOS's ``poincare_plot`` interpolates the saved points
linearly; here the crossing of φ = 2πk/nfp is located on the cubic Hermite interpolant of the
saved points and B there (O(Δt⁴), far below the tolerance). Writes ``essos.json``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _peer_common import accuracy_transits, dop853_section, load_problem, read_makegrid, timed, write_result  # noqa: E402

os.environ.setdefault("ESSOS_PROGRESS", "0")
SAVES_PER_TRANSIT = 200


def crossings(ts, xyz, dxdt, nfp, n_max):
    """(R, Z) where the Hermite interpolant of (xyz, dxdt) crosses φ = 2πk/nfp (k ≥ 1, φ increasing)."""
    phi = np.unwrap(np.arctan2(xyz[:, 1], xyz[:, 0]))
    period = 2 * np.pi / nfp
    k = np.floor(phi / period + 1e-12)
    idx = np.flatnonzero(np.diff(k) > 0)[:n_max]
    target = (k[idx + 1]) * period
    dt = (ts[idx + 1] - ts[idx])[:, None]
    p0, p1, m0, m1 = xyz[idx], xyz[idx + 1], dxdt[idx] * dt, dxdt[idx + 1] * dt

    def herm(s):
        s = s[:, None]
        return ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * p1
                + (s**3 - s**2) * m1)

    lo, hi = np.zeros(len(idx)), np.ones(len(idx))
    base = phi[idx]
    for _ in range(60):  # bisection on the unwrapped angle
        mid = 0.5 * (lo + hi)
        x = herm(mid)
        ph = base + np.angle(np.exp(1j * (np.arctan2(x[:, 1], x[:, 0]) - base)))
        below = ph < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    x = herm(0.5 * (lo + hi))
    return np.hypot(x[:, 0], x[:, 1]), x[:, 2]


def main() -> int:
    P, work = load_problem()
    t0 = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    from importlib.metadata import version
    from essos.coils import Coils, Curves, fit_dofs_from_coils
    from essos.dynamics import Tracing
    from essos.fields import BiotSavart

    coils = read_makegrid(os.path.join(work, P["coils_file"]))
    order, nseg = 7, 240
    D, I = [], []
    for npts, o in sorted({len(c[0]): (1 if len(c[0]) == 64 else order) for c in coils}.items()):
        grp = [c for c in coils if len(c[0]) == npts]
        dofs, _ = fit_dofs_from_coils(jnp.array(np.stack([c[0] for c in grp])), o, npts, assume_uniform=True)
        d = np.zeros((len(grp), 3, 2 * order + 1))
        d[:, :, : dofs.shape[2]] = np.asarray(dofs)
        D.append(d)
        I += [c[1] for c in grp]
    field = BiotSavart(Coils(Curves(jnp.array(np.concatenate(D)), n_segments=nseg, nfp=1, stellsym=False),
                             jnp.array(I)))
    Bv = jax.jit(jax.vmap(field.B))
    pts = np.asarray(P["check_points"])
    nfp, tol = P["nfp"], P["rk_tol"]
    R0, Z0 = np.asarray(P["R0"]), np.asarray(P["Z0"])
    t_transit = 2 * np.pi * (R0.max() + 0.05) ** 2  # dx/dt = B: φ̇ = B_φ/R ≈ 1/R², generous

    def trace(r0, z0, transits):
        x0 = jnp.array(np.c_[r0, np.zeros_like(r0), z0])
        n_save = int(SAVES_PER_TRANSIT * transits)
        tr = Tracing(field=field, model="FieldLineAdaptative", initial_conditions=x0, maxtime=transits * t_transit,
                     times_to_trace=n_save, rtol=tol, atol=tol, timestep=1e-2, progress=False)
        return np.asarray(tr.times), np.asarray(tr.trajectories)[:, :, :3]

    def B_at(y, batch=4096):  # in batches: a long run's saved points at once would need ~10² GB
        return np.concatenate([np.asarray(Bv(jnp.asarray(y[i:i + batch]))) for i in range(0, len(y), batch)])

    def sections(ts, Y, transits):
        out = [crossings(ts, y, B_at(y), nfp, transits * nfp) for y in Y]
        n = min(len(r) for r, _ in out)
        return np.stack([r[:n] for r, _ in out], 1), np.stack([z[:n] for _, z in out], 1)

    n_short, n_acc = P["short_transits"], accuracy_transits(P, "essos")
    t_short, _ = timed(lambda: trace(R0, Z0, n_short))
    t_acc, (ts, Y) = timed(lambda: trace(R0, Z0, n_acc))
    R, Z = sections(ts, Y, n_acc)
    print("essos accuracy", t_short, t_acc, R.shape, flush=True)
    line = P["long_line"]
    L = P["long_transits"]["essos"]
    t_long, (ts, Y) = timed(lambda: trace(R0[line:line + 1], Z0[line:line + 1], L))
    RL, ZL = sections(ts, Y, L)
    print("essos long", t_long, RL.shape, flush=True)
    t_ref, (Rr, Zr) = (0.0, (None, None)) if not P.get("own_reference", True) else timed(
        lambda: dop853_section(lambda x: np.asarray(Bv(jnp.asarray(x))), R0, Z0, nfp, n_acc * nfp))
    write_result(work, "essos", {
        "tool": "ESSOS", "version": version("essos"), "jax": jax.__version__,
        "pipeline": "MAKEGRID polylines → Fourier curves (order 1 TF, 7 helical; 240 quadrature points) → "
                    f"Biot–Savart at every stage; Tracing FieldLineAdaptative, Dopri8, PID rtol=atol={tol:g}",
        "field_check_B": np.asarray(Bv(jnp.asarray(pts))),
        "runs": [{"label": f"Dopri8 rtol=atol={tol:g}", "R": R, "Z": Z, "t_short": t_short, "t_acc": t_acc,
                  "short_transits": n_short, "transits": n_acc, "lines": len(R0)},
                 {"label": "long", "R": RL, "Z": ZL, "t": t_long, "transits": L, "lines": 1}],
        "own_ref_R": Rr, "own_ref_Z": Zr, "own_ref_s": t_ref,
        "total_s": time.perf_counter() - t0,
    })
    return 0


if __name__ == "__main__":
    sys.exit(main())

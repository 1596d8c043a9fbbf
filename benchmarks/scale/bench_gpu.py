"""Millions of particles on one accelerator: vpforms' JAX path on a GPU against the same code on the
CPU cores of the same machine, written to results_gpu.md (issue: the mission's "fast for millions").

Never part of CI (CI has no GPU). On a machine with a CUDA JAX, run it twice — once per platform —
and the second call merges the rows:

    JAX_PLATFORMS=cuda PYTHONPATH=src python benchmarks/scale/bench_gpu.py --out results_gpu.json
    JAX_PLATFORMS=cpu  PYTHONPATH=src python benchmarks/scale/bench_gpu.py --out results_gpu.json --md results_gpu.md

Per platform and N (ABC flow, h = 0.1, ``--steps`` steps, one compiled call per method and N):
ns per particle-step (best of ``--rounds`` after compilation, ``jax.block_until_ready``) of

* vpforms SE+SE (the closed-form fast path), its Blanes–Moan order-4 composition, and SE+SE by the
  generic engine (two scalar Newton solves per step), through ``vpforms.integrate`` (no saves, one
  chunk: the whole N on the device);
* the hand-written JAX three-shear kernel of ``bench_abc.py`` (the same map as SE+SE on ABC) and a
  hand-written JAX RK4, as the baselines of the same run.

Plus, per platform, |det J − 1| of one order-4 step at 1000 particles (``jax.jacfwd``): volume
preservation on that hardware's float64.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE), os.path.join(os.path.dirname(HERE), "methods")]  # _bench.py, methods/bench_abc.py


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,100000,1000000,4000000")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(HERE, "results_gpu.json"), help="JSON rows (merged)")
    ap.add_argument("--md", default=None, help="also write the Markdown table here")
    args = ap.parse_args(argv)
    import jax
    import jax.numpy as jnp
    from bench_abc import _jax_kernels

    import vpforms
    from vpforms import problems
    from vpforms.diagnostics import log_det

    dev = jax.devices()[0]
    where = f"{dev.platform}: {getattr(dev, 'device_kind', dev.platform)}"
    if dev.platform == "cpu":
        where += f" ({os.cpu_count()} cores)"
    abc = problems.get("abc")
    fast = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
    methods = {
        "vpforms SE+SE (closed form)": fast,
        "vpforms SE+SE ∘ order 4 (Blanes–Moan)": vpforms.compose(fast, 4, "blanes_moan"),
        "vpforms SE+SE (generic engine, 2 Newton solves)": vpforms.scheme(abc.field, "SE+SE", recover=False),
    }
    _, rk4, shear = _jax_kernels()
    h, n = 0.1, args.steps
    rows = []
    for N in (int(s) for s in args.sizes.split(",")):
        x0 = abc.initial_conditions(N, seed=0)
        runs = {name: (lambda m=m, x0=x0, N=N: vpforms.integrate(m, x0, h, n, chunk_size=N, progress=False,
                                                                 backend="jax").xs) for name, m in methods.items()}
        xj = jnp.asarray(x0)
        runs["hand-written JAX three shears"] = lambda xj=xj: shear(xj, h, n)
        runs["hand-written JAX RK4"] = lambda xj=xj: rk4(xj, h, n)
        for name, fn in runs.items():
            t = time.perf_counter()
            jax.block_until_ready(fn())
            first = time.perf_counter() - t
            best = np.inf
            for _ in range(args.rounds):
                t = time.perf_counter()
                jax.block_until_ready(fn())
                best = min(best, time.perf_counter() - t)
            rows.append({"where": where, "N": N, "method": name, "ns": best / (N * n) * 1e9,
                         "compile_s": first - best})
            print(rows[-1], flush=True)
    ld = log_det(methods["vpforms SE+SE ∘ order 4 (Blanes–Moan)"], abc.initial_conditions(1000, seed=1), h, 1)
    rows.append({"where": where, "det_max_abs": float(ld.max_abs), "jax": jax.__version__,
                 "python": platform.python_version()})
    old = []
    if os.path.exists(args.out):
        with open(args.out) as fh:
            old = [r for r in json.load(fh) if r["where"] != where]
    with open(args.out, "w") as fh:
        json.dump(old + rows, fh, indent=1)
    if args.md:
        with open(args.md, "w") as fh:
            fh.write(markdown(old + rows))
    return 0


def markdown(rows) -> str:
    wheres = sorted({r["where"] for r in rows}, key=lambda w: not w.startswith("cuda")
                    and not w.startswith("gpu"))
    timing = [r for r in rows if "ns" in r]
    meta = {r["where"]: r for r in rows if "det_max_abs" in r}
    sizes = sorted({r["N"] for r in timing})
    methods = list(dict.fromkeys(r["method"] for r in timing))
    out = ["# vpforms on a GPU: millions of particles", "",
           ("ns per particle-step (ABC flow, h = 0.1, 100 steps, all N particles in one compiled call; "
            "best of 2 after compilation). Written by `benchmarks/scale/bench_gpu.py` (see its docstring: one "
            "run per platform on the same machine)."), ""]
    for w in wheres:
        m = meta.get(w, {})
        det = m.get("det_max_abs", float("nan"))
        det = "not measured (the run stopped before it)" if math.isnan(det) else f"{det:.1e}"
        out += [f"## {w}", "", (f"JAX {m.get('jax', '?')}, Python {m.get('python', '?')}; one order-4 step, "
                                f"1000 particles: max |det J − 1| = {det}."), "",
                "| method | " + " | ".join(f"N = {N:,}" for N in sizes) + " |",
                "|---|" + "---:|" * len(sizes)]
        for meth in methods:
            cells = []
            for N in sizes:
                r = [x for x in timing if x["where"] == w and x["N"] == N and x["method"] == meth]
                cells.append(f"{r[0]['ns']:.2f}" if r else "—")
            out.append(f"| {meth} | " + " | ".join(cells) + " |")
        out.append("")
    gpu = [w for w in wheres if not w.startswith("cpu")]
    cpu = [w for w in wheres if w.startswith("cpu")]
    if gpu and cpu:
        out += [f"## GPU speed-up ({gpu[0]} over {cpu[0]}), per particle-step", "",
                "| method | " + " | ".join(f"N = {N:,}" for N in sizes) + " |", "|---|" + "---:|" * len(sizes)]
        for meth in methods:
            cells = []
            for N in sizes:
                g = [x["ns"] for x in timing if x["where"] == gpu[0] and x["N"] == N and x["method"] == meth]
                c = [x["ns"] for x in timing if x["where"] == cpu[0] and x["N"] == N and x["method"] == meth]
                cells.append(f"{c[0] / g[0]:.1f}×" if g and c else "—")
            out.append(f"| {meth} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())

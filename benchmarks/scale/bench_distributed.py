"""Distributed store runs (issues #10, #22): which backend the Dask workers run, what the store
path costs against plain ``vpforms.integrate``, and 1 vs 2 local Dask workers.

1. the same store run of N particles (SE+SE on ABC, native where a compiler exists) three ways:
   in one process on the native backend (OpenMP over the cores), on a LocalCluster of 2
   single-threaded workers with ``backend="native"`` (each worker compiles or loads the kernel
   once), and on the same cluster with ``backend="jax"`` (what a Dask run could fall back to before
   issue #22 made the store honour --backend); each cold (the first run: workers build the method and
   compile) and warm (a second run into a fresh store), one run each; the stores are compared
   bitwise; the final verification pass is timed on its own;
2. the store path's own cost on one chunk, in process, against plain ``integrate``;
3. 1 vs 2 workers, native, warm.

    PYTHONPATH=src python benchmarks/scale/bench_distributed.py              # N = 10⁶ → results_distributed.md
    PYTHONPATH=src python benchmarks/scale/bench_distributed.py --n 200000   # a smaller N
    PYTHONPATH=src python benchmarks/scale/bench_distributed.py --smoke      # seconds, N = 2·10³
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser, write_results

import vpforms as V
from vpforms import distributed as D
from vpforms import io as VIO
from vpforms import problems as P


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def _files(store: str) -> dict:
    out = {}
    for root, _dirs, files in os.walk(store):
        for f in files:
            with open(os.path.join(root, f), "rb") as fh:
                out[os.path.relpath(os.path.join(root, f), store)] = fh.read()
    return out


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_distributed.md"), rounds=3)
    ap.add_argument("--n", type=int, default=1_000_000, help="particles (default 10⁶)")
    ap.add_argument("--steps", type=int, default=100, help="steps (default 100)")
    ap.add_argument("--save-every", type=int, default=50, help="saved every k steps (default 50)")
    ap.add_argument("--chunk", type=int, default=125_000, help="particles per task (default 125000)")
    a = ap.parse_args(argv)
    if a.smoke:
        a.n, a.chunk, a.steps, a.save_every, a.rounds = 2000, 500, 4, 2, 1
    from dask.distributed import Client, LocalCluster

    from vpforms.backends import select_backend

    t_script = time.perf_counter()
    prob = P.get("abc")
    method = V.scheme(prob.field, "SE+SE")
    x0 = prob.initial_conditions(a.n, seed=0)
    h = 0.05
    native, why = select_backend(method, "auto")
    tmp = tempfile.mkdtemp()
    kw = {"save_every": a.save_every, "chunk_particles": a.chunk, "progress": False}

    def store(name):
        return os.path.join(tmp, name + ".zarr")

    try:
        # 1. one process native vs Dask native vs Dask JAX, cold then warm
        walls = {}
        walls["in process", "cold"], _ = _timed(lambda: D.run(method, x0, h, a.steps, store=store("p0"),
                                                              backend=native, **kw))
        walls["in process", "warm"], _ = _timed(lambda: D.run(method, x0, h, a.steps, store=store("p1"),
                                                              backend=native, **kw))
        verify_s, check = _timed(lambda: VIO.verify_store(store("p1")))
        assert not check["bad"], check["bad"]
        for backend in (native, "jax") if native == "native" else ("jax",):
            cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
            try:
                for k, when in enumerate(("cold", "warm")):
                    name = f"d{backend}{k}"
                    walls[f"Dask 2 workers, {backend}", when], _ = _timed(
                        lambda n=name, c=client, b=backend: D.run(method, x0, h, a.steps, store=store(n), client=c,
                                                                  backend=b, **kw))
            finally:
                client.close()
                cluster.close()
        same = _files(store(f"d{native}1")) == _files(store("p1"))
        jax_close = float(np.max(np.abs(VIO.open_store(store("djax1")).x.values
                                        - VIO.open_store(store("p1")).x.values)))
        # 2. the store path's own cost on one chunk (warm: compile and the method cache excluded)
        over = []
        for steps in sorted({a.steps // 10 or 1, a.steps}):
            V.integrate(method, x0[: a.chunk], h, steps, progress=False, chunk_size=a.chunk)
            plain, path = [], []
            for rep in range(a.rounds):  # alternate, keep the minimum: the machine is shared
                t, _ = _timed(lambda s=steps: V.integrate(method, x0[: a.chunk], h, s, progress=False,
                                                          chunk_size=a.chunk))
                plain.append(t)
                t, _ = _timed(lambda s=steps, r=rep: D.run(method, x0[: a.chunk], h, s, store=store(f"c{s}_{r}"),
                                                           chunk_particles=a.chunk, progress=False))
                path.append(t)
            over.append((steps, min(plain), min(path)))
        # 3. 1 vs 2 workers, native, warm (a tiny run per cluster first: workers build and load)
        scale = {}
        for w in (1, 2):
            cluster = LocalCluster(n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
            try:
                D.run(method, x0[: 2 * w], h, a.steps, store=store(f"warm{w}"), chunk_particles=1,
                      client=client, progress=False)
                scale[w], _ = _timed(lambda w=w, c=client: D.run(method, x0, h, a.steps, store=store(f"s{w}"),
                                                                 client=c, **kw))
            finally:
                client.close()
                cluster.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    ps = a.n * a.steps
    ref = walls["in process", "warm"]
    rows = []
    for (who, when), t in walls.items():
        rows.append(f"| {who}, {when} | {t:.2f} s | {1e9 * t / ps:.1f} | {t / ref:.2f}× |")
    rows.append(f"| final verification pass alone (`vpforms verify`), {a.n} particles | {verify_s:.2f} s | | |")
    jx = walls.get(("Dask 2 workers, jax", "warm"))
    nt = walls.get((f"Dask 2 workers, {native}", "warm"))
    text = "\n".join([
        "# Distributed store runs (issues #10, #22)", "",
        machine("bench_distributed.py" + ("" if a.smoke else f" --n {a.n}"), time.perf_counter() - t_script, a.smoke),
        (f"ABC flow, SE+SE, h = {h}, {a.steps} steps saved every {a.save_every}, chunks of {a.chunk} particles; "
        f"backend auto → {native} ({why})."), "",
        f"## One store run of {a.n} particles × {a.steps} steps: which backend the workers run", "",
        "| run (one each) | wall | ns per particle-step | vs in process, warm |", "|---|---|---|---|", *rows, "",
        f"Dask JAX takes **{jx / nt:.1f}×** the wall time of Dask native (warm); Dask native (2 single-threaded workers) vs "
        f"one process native (OpenMP on all cores), warm: **{nt / ref:.2f}×** the wall time."
        if jx and nt and native == "native" else "The native backend is unavailable here: JAX only.",
        (f"The Dask native store is bitwise the in-process store (every file): {same}; the JAX store agrees to "
        f"{jax_close:.1e} (another backend: last bits differ, which is why a store records its backend)."), "",
        ("Wall times are whole `distributed.run` calls: store creation, the chunks, the final verification pass "
        "(every chunk read back and hashed). Cold = the first run on fresh workers (each builds the method from "
        "its spec and loads the native kernel from the on-disk cache, or compiles the JAX kernel); the cluster's "
        "own start is excluded."), "",
        "## The store path's own cost (one chunk, in process)", "",
        "| measurement | value |", "|---|---|",
        *[r for steps, plain, path in over for r in (
            f"| plain integrate, one chunk of {a.chunk} particles × {steps} steps | {plain:.3f} s |",
            f"| store path (distributed.run in process), same chunk | {path:.3f} s |",
            f"| store path − plain (creation, writes, checksums, verification) | {path - plain:.3f} s |")],
        "",
        "## 1 vs 2 workers (native, warm)", "",
        "| measurement | value |", "|---|---|",
        f"| LocalCluster, 1 worker, N = {a.n}, {a.steps} steps | {scale[1]:.2f} s |",
        f"| LocalCluster, 2 workers, same | {scale[2]:.2f} s |",
        f"| scaling 1 → 2 workers (wall₁ / wall₂) | {scale[1] / scale[2]:.2f}× |", "",
        ("Timings are single runs (best of " f"{a.rounds} for the one-chunk rows) on a shared machine: only ratios "
        "within this file mean anything."), ""])
    return write_results(a.out, text)


if __name__ == "__main__":
    raise SystemExit(main())

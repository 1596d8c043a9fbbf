"""GPU probe (results_gpu.md, 'Where the time goes'): the fixed cost of an integrate() call: 1, 100, 256, 400 steps, with and without saves.

    PYTHONPATH=src python3 benchmarks/scale/gpu_probes/probe_fixed_cost.py N
"""

import sys
import time

import vpforms
from vpforms import problems

N = int(sys.argv[1]); abc = problems.get("abc"); x0 = abc.initial_conditions(N, seed=0)
m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
def t_of(n, se):
    f = lambda: vpforms.integrate(m, x0, 0.1, n, save_every=se, chunk_size=N, progress=False, backend="jax").xs
    f(); best = 1e9
    for _ in range(2):
        t = time.perf_counter(); f(); best = min(best, time.perf_counter() - t)
    return best
for n, se in [(1, None), (100, None), (256, None), (100, 100), (400, 400), (400, None)]:
    t = t_of(n, se); print(f"n={n} save_every={se}: {t:.4f} s = {t / (N * n) * 1e9:.3f} ns/particle-step", flush=True)

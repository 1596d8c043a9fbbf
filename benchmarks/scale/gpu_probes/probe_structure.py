"""GPU probe (results_gpu.md, 'Where the time goes'): integrate() with the consistency guard on/off and lax.cond replaced by where, against the hand-written kernel and vmap(step) in a fori_loop.

    PYTHONPATH=src python3 benchmarks/scale/gpu_probes/probe_structure.py N
"""
# ruff: noqa: B023  (each closure is called inside the loop iteration that defines it)
import os
import sys
import time
import types

import jax
import jax.numpy as jnp
from jax import lax

import vpforms
import vpforms._integrate as I
from vpforms import problems

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "methods"))  # bench_abc.py
from bench_abc import _jax_kernels

N = int(sys.argv[1]) if len(sys.argv) > 1 else 4_000_000
abc = problems.get("abc"); x0 = abc.initial_conditions(N, seed=0); h, n = 0.1, 100
def timed(fn):
    jax.block_until_ready(fn()); best = 1e9
    for _ in range(2):
        t = time.perf_counter(); jax.block_until_ready(fn()); best = min(best, time.perf_counter() - t)
    return best / (N * n) * 1e9
def where_cond(p, t, f, c):
    return jax.tree.map(lambda a, b: jnp.where(p, a, b), t(c), f(c))
shim = types.SimpleNamespace(scan=lax.scan, cond=where_cond, while_loop=lax.while_loop, fori_loop=lax.fori_loop)
for label, guard, nocond in [("base", True, False), ("no guard", False, False), ("no cond", True, True), ("no guard, no cond", False, True)]:
    m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
    if not guard:
        object.__setattr__(m, "guard_kappa", None)
    I.lax = shim if nocond else lax
    ns = timed(lambda: vpforms.integrate(m, x0, h, n, chunk_size=N, progress=False, backend="jax").xs)
    print(f"{label}: {ns:.3f} ns/particle-step", flush=True)
I.lax = lax
_, rk4, shear = _jax_kernels(); xj = jnp.asarray(x0)
print(f"hand-written shears: {timed(lambda: shear(xj, h, n)):.3f}", flush=True)
m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
step = jax.jit(jax.vmap(lambda x: m.step_with_status(x, h)[0]) if False else (lambda X: jax.vmap(lambda x: m.step(x, h))(X)))
def loop():
    return lax.fori_loop(0, n, lambda i, y: step(y), xj)
print(f"vmap(step) in fori_loop (no statuses): {timed(jax.jit(loop)):.3f}", flush=True)
def loop2():
    return jax.vmap(lambda x: lax.fori_loop(0, n, lambda i, y: m.step(y, h), x))(xj)
print(f"vmap(fori_loop(step)) like the hand-written: {timed(jax.jit(loop2)):.3f}", flush=True)

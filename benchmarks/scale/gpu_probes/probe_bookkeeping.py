"""GPU probe (results_gpu.md, 'Where the time goes'): the batched step_with_status in a fori_loop, alone and with integrate's status bookkeeping, guard on/off.

    PYTHONPATH=src python3 benchmarks/scale/gpu_probes/probe_bookkeeping.py N
"""
# ruff: noqa: B023  (each closure is called inside the loop iteration that defines it)
import sys
import time

import jax
import jax.numpy as jnp
from jax import lax

import vpforms
from vpforms import RESULTS, problems

N = int(sys.argv[1]) if len(sys.argv) > 1 else 4_000_000
abc = problems.get("abc"); x0 = jnp.asarray(abc.initial_conditions(N, seed=0)); h, n = 0.1, 100
def timed(fn):
    jax.block_until_ready(fn()); best = 1e9
    for _ in range(2):
        t = time.perf_counter(); jax.block_until_ready(fn()); best = min(best, time.perf_counter() - t)
    return best / (N * n) * 1e9
for guard in (True, False):
    m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
    if not guard:
        object.__setattr__(m, "guard_kappa", None)
    sws = m.step_with_status
    def a():
        def body(i, c):
            x, _s = c
            X, st = sws(x, h) if hasattr(sws, "with_recovery") else jax.vmap(sws, in_axes=(0, None))(x, h)
            return X, st
        return lax.fori_loop(0, n, body, (x0, jnp.zeros(N, jnp.int32)))
    def b():
        def body(i, c):
            x, status = c
            X, st = sws(x, h) if hasattr(sws, "with_recovery") else jax.vmap(sws, in_axes=(0, None))(x, h)
            st = jnp.asarray(st, jnp.int32)
            st = jnp.where((st == 0) & ~jnp.all(jnp.isfinite(X), axis=-1), RESULTS.nonfinite, st)
            alive = status == 0
            good = alive & (st == 0)
            return jnp.where(good[:, None], X, x), jnp.where(alive & (st != 0), st, status)
        return lax.fori_loop(0, n, body, (x0, jnp.zeros(N, jnp.int32)))
    def c():  # b on SoA columns
        def body(i, cc):
            x1, x2, x3, status = cc
            X, _st = jax.vmap(lambda p: m.step_with_status(p, h) if False else (m.step(p, h), jnp.int32(0)))(jnp.stack([x1, x2, x3], -1))
            ok = jnp.isfinite(X[:, 0]) & jnp.isfinite(X[:, 1]) & jnp.isfinite(X[:, 2])
            good = (status == 0) & ok
            return (jnp.where(good, X[:, 0], x1), jnp.where(good, X[:, 1], x2), jnp.where(good, X[:, 2], x3),
                    jnp.where((status == 0) & ~ok, 5, status))
        return lax.fori_loop(0, n, body, (x0[:, 0], x0[:, 1], x0[:, 2], jnp.zeros(N, jnp.int32)))
    print(f"guard={guard}: step_with_status only {timed(jax.jit(a)):.3f}; + bookkeeping {timed(jax.jit(b)):.3f}; plain step + bookkeeping SoA {timed(jax.jit(c)):.3f}", flush=True)

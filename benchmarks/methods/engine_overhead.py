"""The bare generic engine against the hand-written kernel, and the cost of the case as data.

The same SE+SE step on the ABC flow (MATH.md §3/§4), 8192 particles × 100 steps, `jit` + `vmap` +
`fori_loop`, three ways:

* ``shear``        — the hand-written three-shear kernel;
* ``generic``      — ``GeneratingMap.solve`` as shipped: the case (σ, Σ, Σ⁻¹ gather indices and the
  sign) is *data*, so the 36 cases share one compilation;
* ``static-case``  — the very same solve (``_map._solve_generic``, same potentials, same Newton)
  with the permutations applied by Python indices and the sign a constant, i.e. compiled per case.

Prints ns per particle-step (best of 5 interleaved rounds), ratios to ``shear``, and checks that
``static-case`` equals ``generic`` bitwise.  Measured on the 2-core CI-like machine (loaded):
generic 1.02–1.30× shear, static-case the same within noise — the engine itself is within the
1.5× target and passing the case as data costs nothing measurable.  (A method built by
``vpforms.scheme`` additionally evaluates the field for its Euler-predictor guess; see
``bench_abc.py``.)  A diagnostic for issues #2/#5; it reaches into the private ``vpforms._map``
and is not part of the test suite.

    python benchmarks/methods/engine_overhead.py
"""

from __future__ import annotations

import math
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

import vpforms._map as M
from vpforms import Case, GeneratingMap

A, B, C = 1.0, math.sqrt(2 / 3), math.sqrt(1 / 3)
H = 0.1


def F1(x1, x2, x3):
    return C * jnp.cos(x2) - B * x2 * jnp.cos(x1) + A * jnp.sin(x3)


def F3(x1, x2, x3):
    return A * x2 * jnp.sin(x3) + C * jnp.sin(x2) + B * jnp.cos(x1)


def shear(x):
    x1, x2, x3 = x[0], x[1], x[2]
    X3 = x3 + H * (C * jnp.sin(x2) + B * jnp.cos(x1))
    X2 = x2 + H * (A * jnp.cos(X3) + B * jnp.sin(x1))
    X1 = x1 + H * (A * jnp.sin(X3) + C * jnp.cos(X2))
    return jnp.stack([X1, X2, X3])


def main() -> None:
    case = Case((3, 2, 1), (1, 2, 3))
    m = GeneratingMap(lambda X3, x2, x1: x2 * X3 + H * F1(x1, x2, X3),
                      lambda X3, X2, x1: x1 * X2 + H * F3(x1, X2, X3), case)
    idx = np.asarray(m._perm_indices)
    sign = float(m.sign)

    def static_case(x):
        y = jnp.stack([x[int(i)] for i in idx[0]])  # y = x·σ
        guess = jnp.stack([x[int(i)] for i in idx[1]])  # the guess X = x, as Y = X·Σ (as solve)
        Y, _, _ = M._solve_generic(m._static, y, guess, jnp.asarray(sign))
        return jnp.stack([Y[int(i)] for i in idx[2]])

    def run_of(step):
        return jax.jit(lambda x0: jax.vmap(lambda x: lax.fori_loop(0, 100, lambda i, y: step(y), x))(x0))

    runs = {"shear": run_of(shear), "generic": run_of(lambda y: m.solve(y)[0]),
            "static-case": run_of(static_case)}
    x0 = jnp.asarray(np.random.default_rng(0).uniform(0, 2 * np.pi, (8192, 3)))
    out = {k: np.asarray(r(x0)) for k, r in runs.items()}  # compiles
    best = {k: math.inf for k in runs}
    for _ in range(5):
        for k, r in runs.items():
            t = time.perf_counter()
            r(x0).block_until_ready()
            best[k] = min(best[k], time.perf_counter() - t)
    for k, v in best.items():
        print(f"{k:12s} {1e9 * v / (8192 * 100):8.1f} ns/particle-step  {v / best['shear']:.2f}× shear")
    print("static-case == generic bitwise:", np.array_equal(out["static-case"], out["generic"]),
          f"; max |generic − shear| = {np.max(np.abs(out['generic'] - out['shear'])):.1e}")


if __name__ == "__main__":
    main()

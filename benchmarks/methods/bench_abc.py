"""Particle-tracing benchmark on the ABC flow: vpforms against hand-written JAX kernels, SciPy, diffrax.

Measures, in one process, ns per particle-step and the median error at T on the ABC flow
(A, B, C) = (1, √(2/3), √(1/3)) with step h, for N particles (default N ∈ {10³, 10⁵, 10⁶},
T = 10, h = 0.1, i.e. 100 steps):

* vpforms SE+SE through the generic engine (``GeneratingMap``: two scalar Newton solves per step),
  both as ``scheme(field, "SE+SE")`` builds it (Newton started from the Euler predictor
  x + h·a(x)) and as the bare ``GeneratingMap.solve`` of that method's own map (started from x),
  and through the closed-form fast path (``scheme(field, "SE+SE", fast=True)``), all driven by
  ``vpforms.integrate``;
* vpforms compositions of order 2 and 4 (of the fast SE+SE step);
* a hand-written JAX RK4 and a hand-written JAX three-shear splitting — the same map as SE+SE on
  ABC written out explicitly (checked against vpforms to 1e-12 below);
* SciPy ``solve_ivp`` DOP853 on the stacked 3N system (adaptive, rtol = atol = 1e-8);
* diffrax Tsit5 with a constant step h (if diffrax is installed).

Every JAX method runs in chunks of ``--chunk`` particles (one compilation per method, excluded from
the timing by a warm-up chunk).  ns per particle-step = wall time / (N · T/h) (for the adaptive
SciPy run T/h is the nominal step count).  Errors are the median over the first ≤ 1000 particles
(the same particles for every N) of max_i |x_i(T) − x_i^ref(T)|, the reference from DOP853 at
rtol = atol = 1e-13.  Ratios are relative to the hand-written three-shear kernel.

Usage:  python benchmarks/methods/bench_abc.py [--sizes 1000,100000,1000000] [--out benchmarks/methods/results.md]
        python benchmarks/methods/bench_abc.py --smoke      # tiny N, for CI (no timing claims)
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from functools import partial

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine  # noqa: E402

A, B, C = 1.0, math.sqrt(2.0 / 3.0), math.sqrt(1.0 / 3.0)


# ---------------------------------------------------------------------------------------------
# Hand-written baselines (what a user would write today)
# ---------------------------------------------------------------------------------------------
def _jax_kernels():
    import jax
    import jax.numpy as jnp

    import vpforms  # noqa: F401  (float64)

    def abc(x):
        return jnp.stack([
            A * jnp.sin(x[2]) + C * jnp.cos(x[1]),
            B * jnp.sin(x[0]) + A * jnp.cos(x[2]),
            C * jnp.sin(x[1]) + B * jnp.cos(x[0]),
        ])

    def rk4_step(x, h):
        k1 = abc(x)
        k2 = abc(x + 0.5 * h * k1)
        k3 = abc(x + 0.5 * h * k2)
        k4 = abc(x + h * k3)
        return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def shear_step(x, h):
        # SE+SE on ABC (MATH.md §4 with F¹, F³ of §3) is three explicit shears:
        x1, x2, x3 = x[0], x[1], x[2]
        X3 = x3 + h * (C * jnp.sin(x2) + B * jnp.cos(x1))  # X₃ = x₃ − h ∂₂F¹
        X2 = x2 + h * (A * jnp.cos(X3) + B * jnp.sin(x1))  # X₂ = x₂ + h ∂₃F¹ − h ∂₁F³
        X1 = x1 + h * (A * jnp.sin(X3) + C * jnp.cos(X2))  # X₁ = x₁ + h ∂₂F³
        return jnp.stack([X1, X2, X3])

    def make_run(step):
        @partial(jax.jit, static_argnums=2)
        def run(x0, h, n):
            def one(x):
                return jax.lax.fori_loop(0, n, lambda i, y: step(y, h), x)

            return jax.vmap(one)(x0)

        return run

    return abc, make_run(rk4_step), make_run(shear_step)


def _abc_numpy(_t, y):
    x = y.reshape(-1, 3)
    out = np.empty_like(x)
    out[:, 0] = A * np.sin(x[:, 2]) + C * np.cos(x[:, 1])
    out[:, 1] = B * np.sin(x[:, 0]) + A * np.cos(x[:, 2])
    out[:, 2] = C * np.sin(x[:, 1]) + B * np.cos(x[:, 0])
    return out.reshape(-1)


def _diffrax_run():
    try:
        import diffrax
    except ImportError:
        return None
    import jax
    import jax.numpy as jnp

    def vf(t, x, args):
        return jnp.stack([
            A * jnp.sin(x[2]) + C * jnp.cos(x[1]),
            B * jnp.sin(x[0]) + A * jnp.cos(x[2]),
            C * jnp.sin(x[1]) + B * jnp.cos(x[0]),
        ])

    term = diffrax.ODETerm(vf)
    solver = diffrax.Tsit5()

    @partial(jax.jit, static_argnums=2)
    def run(x0, h, n):
        def one(x):
            sol = diffrax.diffeqsolve(term, solver, 0.0, n * h, h, x,
                                      stepsize_controller=diffrax.ConstantStepSize(),
                                      saveat=diffrax.SaveAt(t1=True), max_steps=n + 1)
            return sol.ys[-1]

        return jax.vmap(one)(x0)

    return run


# ---------------------------------------------------------------------------------------------
# Timing helpers
# ---------------------------------------------------------------------------------------------
def _chunked(run, x0, h, n, chunk):
    """Run a hand-written kernel over x0 in chunks of `chunk` (last chunk padded)."""
    import jax.numpy as jnp

    N = x0.shape[0]
    out = np.empty_like(x0)
    for lo in range(0, N, chunk):
        hi = min(lo + chunk, N)
        blk = x0[lo:hi]
        if hi - lo < chunk:
            blk = np.concatenate([blk, np.repeat(blk[-1:], chunk - (hi - lo), axis=0)])
        out[lo:hi] = np.asarray(run(jnp.asarray(blk), h, n))[: hi - lo]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1000,100000,1000000")
    ap.add_argument("--T", type=float, default=10.0)
    ap.add_argument("--h", type=float, default=0.1)
    ap.add_argument("--chunk", type=int, default=8192, help="particles per compiled call")
    ap.add_argument("--repeats", type=int, default=3, help="best of R runs for N ≤ 10⁴ (2 up to 10⁵)")
    ap.add_argument("--large", type=int, default=10**6,
                    help="for N ≥ LARGE time only the first --large-steps steps (default 10⁶)")
    ap.add_argument("--large-steps", type=int, default=20)
    ap.add_argument("--scipy-max-n", type=int, default=10**6, help="skip SciPy above this N")
    ap.add_argument("--out", default=os.path.join(HERE, "results.md"))
    ap.add_argument("--smoke", action="store_true", help="tiny sizes for CI; no timing claims")
    ap.add_argument("--readme", default=None,
                    help="then regenerate the quote blocks of this file (e.g. README.md) from the "
                         "results files (benchmarks/quote.py; README.md quotes benchmarks/methods/results.md)")
    args = ap.parse_args(argv)
    if args.smoke:
        args.sizes, args.T, args.repeats, args.chunk = "16,40", 1.0, 1, 16

    from vpforms import problems

    try:
        from vpforms import compose, scheme
    except ImportError:  # before the methods are re-exported at the top level
        from vpforms._methods import compose, scheme
    from vpforms.diagnostics import reference_solution
    from vpforms import integrate

    sizes = [int(s) for s in args.sizes.split(",")]
    h, T = args.h, args.T
    n = int(round(T / h))
    prob = problems.get("abc", A=A, B="sqrt(2/3)", C="sqrt(1/3)")
    abc, rk4_run, shear_run = _jax_kernels()
    dfx = _diffrax_run()

    rng = np.random.default_rng(0)
    X0 = rng.uniform(0.0, 2 * math.pi, size=(max(sizes), 3))  # prefix-consistent across N
    n_ref = min(1000, max(sizes))
    t_ref = time.perf_counter()
    ref = reference_solution(abc, X0[:n_ref], T)
    print(f"reference (DOP853, rtol 1e-13) for {n_ref} particles: {time.perf_counter() - t_ref:.1f} s",
          flush=True)

    se_generic = scheme(prob.field, "SE+SE")
    se_fast = scheme(prob.field, "SE+SE", fast=True)
    vp2 = compose(se_fast, order=2)
    vp4 = compose(se_fast, order=4)

    def vp(method):
        def run(x0, chunk, n=n):
            sol = integrate(method, x0, h, n, chunk_size=chunk, progress=False)
            if not sol.ok:
                sol.raise_for_status()
            return sol.x_final

        return run

    def hand(kernel):
        return lambda x0, chunk, n=n: _chunked(kernel, x0, h, n, chunk)

    def scipy_dop853(x0, chunk, n=n):
        from scipy.integrate import solve_ivp

        sol = solve_ivp(_abc_numpy, (0.0, n * h), x0.reshape(-1), method="DOP853", rtol=1e-8, atol=1e-8)
        return sol.y[:, -1].reshape(-1, 3)

    class EngineDirect:
        """The method's own GeneratingMap (same potentials), solved from the guess X = x."""

        description = "GeneratingMap of vpforms SE+SE, guess X = x"

        def step_with_status(self, x, h):
            return se_generic.generating_map(h, x).solve(x)

    rows = [
        ("vpforms SE+SE, generic engine via scheme() (Euler-predictor guess)", vp(se_generic), True),
        ("vpforms SE+SE, generic engine, GeneratingMap.solve (guess X = x)", vp(EngineDirect()), True),
        ("vpforms SE+SE, fast path (closed-form shears)", vp(se_fast), True),
        ("vpforms order 2 (SE+SE* ∘ SE+SE, fast)", vp(vp2), True),
        ("vpforms order 4 (Suzuki 5-stage of order 2, fast)", vp(vp4), True),
        ("hand-written JAX three-shear (= SE+SE on ABC)", hand(shear_run), True),
        ("hand-written JAX RK4", hand(rk4_run), True),
        ("SciPy solve_ivp DOP853 (stacked, rtol=atol=1e-8)", scipy_dop853, False),
    ]
    if dfx is not None:
        rows.append(("diffrax Tsit5 (constant step h)", hand(dfx), True))

    # the hand-written three-shear kernel must be the same map as vpforms SE+SE on ABC
    xs = X0[:16]
    d_shear = float(np.max(np.abs(hand(shear_run)(xs, 16) - vp(se_generic)(xs, 16))))
    d_fast = float(np.max(np.abs(vp(se_fast)(xs, 16) - vp(se_generic)(xs, 16))))
    d_direct = float(np.max(np.abs(vp(EngineDirect())(xs, 16) - vp(se_generic)(xs, 16))))
    print(f"max |three-shear − SE+SE generic| after {n} steps = {d_shear:.2e}; "
          f"|fast − generic| = {d_fast:.2e}; |GeneratingMap.solve − scheme| = {d_direct:.2e}", flush=True)

    results = {}  # (label, N) -> (ns, err or nan)
    t_all = time.perf_counter()
    for N in sizes:
        x0 = X0[:N]
        chunk = min(N, args.chunk)
        large = N >= args.large
        steps = min(n, args.large_steps) if large else n
        active = [r for r in rows if not (r[0].startswith("SciPy") and N > args.scipy_max_n)]
        for label, run, jitted in rows:
            if (label, run, jitted) not in active:
                results[(label, N)] = (math.nan, math.nan)
            elif jitted:  # compile outside the timing: one warm-up chunk of the same shape
                run(X0[:chunk], chunk, steps)
        # rounds interleave the methods, so that a change of machine load hits all of them alike;
        # each method keeps its best round
        reps = 1 if large else (args.repeats if N <= 10**4 else min(2, args.repeats))
        best = {}
        for _ in range(reps):
            for label, run, _j in active:
                t = time.perf_counter()
                xT = run(x0, chunk, steps)
                wall = time.perf_counter() - t
                if label not in best or wall < best[label][0]:
                    best[label] = (wall, xT)
        for label, _run, _j in active:
            wall, xT = best[label]
            err = math.nan
            if steps == n:
                m = min(N, n_ref)
                err = float(np.median(np.max(np.abs(xT[:m] - ref[:m]), axis=1)))
            ns = 1e9 * wall / (N * steps)
            results[(label, N)] = (ns, err)
            print(f"N={N:>8d}  {label:<52s} {ns:10.1f} ns/particle-step  median err {err:.2e}  "
                  f"({wall:.2f} s, {steps} steps)", flush=True)
    total = time.perf_counter() - t_all

    base = "hand-written JAX three-shear (= SE+SE on ABC)"
    lines = [
        f"# Particle-tracing benchmark: ABC flow (A, B, C) = (1, √(2/3), √(1/3)), h = {h:g}, T = {T:g} "
        f"({n} steps)",
        "",
        machine("bench_abc.py", total, args.smoke),
        "",
        "ns per particle-step (wall time / (N · T/h), compile excluded; best of interleaved rounds) and, in "
        "brackets, the ratio to "
        "the hand-written JAX three-shear kernel; error = median over the first "
        f"{n_ref} particles of max-norm |x(T) − x_ref(T)| (reference: DOP853, rtol = atol = 1e-13).",
        "",
        *([(f"For N ≥ {args.large:,} ".replace(",", " ") + f"each method is timed over its first "
           f"{args.large_steps} steps only (the cost per particle-step does not depend on the number "
           "of steps; it keeps the whole benchmark under 10 minutes); the error column comes from the "
           f"runs to T = {T:g}."), ""] if any(N >= args.large for N in sizes) else []),
        "| method | " + " | ".join(f"N = {N:,}".replace(",", " ") for N in sizes) + f" | median error at T = {T:g} |",
        "|---|" + "---:|" * len(sizes) + "---:|",
    ]
    for label, _, _ in rows:
        cells = []
        for N in sizes:
            ns, _ = results[(label, N)]
            b, _ = results[(base, N)]
            cells.append("skipped" if math.isnan(ns) else f"{ns:,.0f} ({ns / b:.2f}×)".replace(",", " "))
        errs = [results[(label, N)][1] for N in sizes if not math.isnan(results[(label, N)][1])]
        lines.append(f"| {label} | " + " | ".join(cells) + (f" | {errs[-1]:.2e} |" if errs else " | – |"))
    lines += [
        "",
        f"Check: max |three-shear − vpforms SE+SE generic| after {n} steps on 16 particles = {d_shear:.1e} "
        f"(the same map); |fast path − generic| = {d_fast:.1e}; |GeneratingMap.solve from x − scheme()| = "
        f"{d_direct:.1e} (same map, other Newton start).",
        "",
        "All JAX methods run in chunks of "
        f"{min(max(sizes), args.chunk)} particles (`jit` + `vmap`, a scan/loop over steps); the vpforms "
        "rows go through `vpforms.integrate` (per-particle status, frozen failures, host transfer of "
        "the final state included). SciPy integrates the stacked 3N system with a NumPy right-hand "
        "side (adaptive steps; its ns/particle-step uses the nominal T/h steps). diffrax uses Tsit5 "
        "with `ConstantStepSize` h.",
    ]
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\nwritten: {args.out}")
    if args.readme:
        import quote  # benchmarks/quote.py: the one mechanism that quotes results files in documents

        with open(args.readme, encoding="utf-8") as f:
            text = f.read()
        with open(args.readme, "w", encoding="utf-8") as f:
            f.write(quote.render(text, where=args.readme))
        print(f"quote blocks regenerated in: {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

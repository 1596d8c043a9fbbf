"""B of the W7-X coils at many points: simsopt's C++ ``BiotSavart`` against vpforms' native evaluator
(``CoilSet.evaluate``, generated C) and its JAX ``CoilSet.B``, in one process, one thread, written to
results_biot_savart.md beside this script (issue #38 item 2: native within 2× of simsopt per pair).

Run it in simsopt's venv with vpforms installed there too, pinned to one core:

    /work/peers/simsopt/bin/pip install -e .
    OMP_NUM_THREADS=1 XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1" \\
        taskset -c 0 /work/peers/simsopt/bin/python benchmarks/peers/bench_biot_savart.py [--points N]

The coils: W7-X's 50 coils with current (simsopt: ``coils_via_symmetries`` of the five non-planar
base curves and currents of ``get_data("w7x")``, 96 quadrature points each; vpforms:
``device("w7x")``, the polylines through the same 96 points, 4 800 segments). The points: N seeded
points within 0.3 m of the axis. Cost = best of R timed calls / (N × 4 800) — ns per point-segment
pair (simsopt's B alone: ``set_points`` then ``B()``; vpforms: one jitted call on chunks of 500
points, compile apart; vpforms native: ``CoilSet.evaluate(x, "B"|"A", backend="native")``, the C
compiled before timing). Their largest relative difference is printed too (the polyline's O(1/n²)).
simsopt's cost per pair is per quadrature point of its curves (a point-source sum), vpforms' per
straight segment (Hanson–Hirshman's closed form: two square roots and three divisions; A adds a
logarithm): the table gives both per pair and per point, same number of pairs.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import jax
import numpy as np
import simsopt
from simsopt.configs import get_data
from simsopt.field import BiotSavart
from simsopt.field.coil import coils_via_symmetries

from vpforms.coils import device, device_axis

OUT = Path(__file__).with_name("results_biot_savart.md")
CHUNK = 500


def points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    axis = device_axis("w7x")
    phi = rng.uniform(0, 2 * np.pi, n)
    R, Z = axis(phi)
    r, al = 0.3 * np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    R, Z = R + r * np.cos(al), Z + r * np.sin(al)
    return np.c_[R * np.cos(phi), R * np.sin(phi), Z]


def best(f, rounds: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(rounds):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=5000)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    x = points(args.points)

    curves, currents, *_ = get_data("w7x")
    live = [k for k, c in enumerate(currents) if c.get_value() != 0]
    bs = BiotSavart(coils_via_symmetries([curves[k] for k in live], [currents[k] for k in live], 5, True))
    n_seg_simsopt = sum(len(c.curve.quadpoints) for c in bs.coils)

    def simsopt_B():
        bs.set_points(x)
        return np.array(bs.B())

    t_simsopt, B_simsopt = best(simsopt_B, args.rounds)

    def simsopt_A():
        bs.set_points(x)
        return np.array(bs.A())

    t_simsopt_A, _ = best(simsopt_A, args.rounds)

    coils = device("w7x")
    n_seg = int(coils.segments()[0].shape[0])
    B_jit = jax.jit(coils.B)

    def vpforms_B():
        return np.concatenate([np.asarray(B_jit(x[i:i + CHUNK]).block_until_ready())
                               for i in range(0, len(x), CHUNK)])

    t = time.perf_counter()
    vpforms_B()
    t_first = time.perf_counter() - t
    t_vpforms, B_vpforms = best(vpforms_B, args.rounds)
    diff = float(np.max(np.linalg.norm(B_vpforms - B_simsopt, axis=1)) / np.max(np.linalg.norm(B_simsopt, axis=1)))
    coils.evaluate(x[:10], "B", backend="native")  # the C compiled (or loaded from the cache) before timing
    t_native, B_native = best(lambda: coils.evaluate(x, "B", backend="native"), args.rounds)
    t_native_A, _ = best(lambda: coils.evaluate(x, "A", backend="native"), args.rounds)
    diff_native = float(np.max(np.abs(B_native - B_vpforms)) / np.max(np.abs(B_vpforms)))
    # simsopt's own rule (current elements at its quadrature points): the same pairs, term by term
    quad = device("w7x", rule="quadrature")
    n_el = int(quad.elements()[0].shape[0])
    quad.evaluate(x[:10], "B", backend="native")
    t_el, B_el = best(lambda: quad.evaluate(x, "B", backend="native"), args.rounds)
    t_el_A, _ = best(lambda: quad.evaluate(x, "A", backend="native"), args.rounds)
    diff_el = float(np.max(np.abs(B_el - B_simsopt)) / np.max(np.abs(B_simsopt)))

    pairs = args.points * n_seg
    ns_s, ns_v = 1e9 * t_simsopt / (args.points * n_seg_simsopt), 1e9 * t_vpforms / pairs
    ns_n, ns_nA = 1e9 * t_native / pairs, 1e9 * t_native_A / pairs
    ns_sA = 1e9 * t_simsopt_A / (args.points * n_seg_simsopt)
    ns_el, ns_elA = 1e9 * t_el / (args.points * n_el), 1e9 * t_el_A / (args.points * n_el)
    lines = [
        "# B and A of the W7-X coils: simsopt BiotSavart vs vpforms (native and JAX)",
        "",
        f"`benchmarks/peers/bench_biot_savart.py --points {args.points} --rounds {args.rounds}`, one process, "
        f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, "
        f"XLA_FLAGS={os.environ.get('XLA_FLAGS', 'unset')!r}, CPU affinity {sorted(os.sched_getaffinity(0))}; "
        f"{platform.processor() or platform.machine()}, simsopt {simsopt.__version__}, jax {jax.__version__}.",
        "",
        f"W7-X, 50 coils with current, {n_seg} segments (vpforms) / {n_seg_simsopt} quadrature points "
        f"(simsopt); {args.points} points within 0.3 m of the axis; best of {args.rounds}.",
        "",
        "| evaluator | time (s) | ns per point-segment pair | µs per point |",
        "|---|---|---|---|",
        f"| simsopt `BiotSavart` (C++, `set_points` + `B()`) | {t_simsopt:.3f} | {ns_s:.2f} | "
        f"{1e6 * t_simsopt / args.points:.1f} |",
        f"| simsopt `BiotSavart` (C++, `set_points` + `A()`) | {t_simsopt_A:.3f} | {ns_sA:.2f} | "
        f"{1e6 * t_simsopt_A / args.points:.1f} |",
        f"| vpforms `CoilSet.evaluate(x, \"B\")` (native C, OpenMP) | {t_native:.3f} | {ns_n:.2f} | "
        f"{1e6 * t_native / args.points:.1f} |",
        f"| vpforms `CoilSet.evaluate(x, \"A\")` (native C, OpenMP) | {t_native_A:.3f} | {ns_nA:.2f} | "
        f"{1e6 * t_native_A / args.points:.1f} |",
        f"| vpforms `QuadratureCoils.evaluate(x, \"B\")` (simsopt's elements; native C, OpenMP) | {t_el:.3f} | "
        f"{ns_el:.2f} | {1e6 * t_el / args.points:.1f} |",
        f"| vpforms `QuadratureCoils.evaluate(x, \"A\")` (simsopt's elements; native C, OpenMP) | {t_el_A:.3f} | "
        f"{ns_elA:.2f} | {1e6 * t_el_A / args.points:.1f} |",
        f"| vpforms `CoilSet.B` (JAX, jit, chunks of {CHUNK} points) | {t_vpforms:.3f} | {ns_v:.2f} | "
        f"{1e6 * t_vpforms / args.points:.1f} |",
        "",
        f"simsopt's own elements ({n_el} of them), natively: B **{ns_el / ns_s:.2f}×** simsopt's time, A "
        f"{ns_elA / ns_sA:.2f}×, max |B_vpforms − B_simsopt| / max |B| = {diff_el:.1e} (the same sum). "
        f"Segments, per pair, vpforms native B / simsopt: **{ns_n / ns_s:.2f}×** (A against simsopt's A: {ns_nA / ns_sA:.2f}×); per point "
        f"{t_native / t_simsopt:.2f}×. vpforms JAX / simsopt: {t_vpforms / t_simsopt:.1f}× per point; its first "
        f"call (compile included) {t_first:.2f} s. max |B_native − B_JAX| / max |B| = {diff_native:.1e}; "
        f"max |B_vpforms − B_simsopt| / max |B| = {diff:.1e} (the polyline's O(1/n²) at 96 points per coil; "
        "tests/test_devices.py).",
    ]
    OUT.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

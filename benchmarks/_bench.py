"""What the benchmark scripts share: the command line, best-of timing and the machine line.

The scripts live in topic folders (``benchmarks/<topic>/<script>.py``, the results file beside each);
each puts its own folder and this one (``benchmarks/``) on ``sys.path`` at its top and imports from
here, so that it runs from the repository root as its docstring says
(``python benchmarks/<topic>/<script>.py``) and loads by path in the tests. Ratios are only compared
between rows of one run (same process, same machine load). ``benchmarks/index.py`` writes the table
of every script and its last result (``docs/benchmarks.md``)."""

from __future__ import annotations

import argparse
import math
import os
import platform
import tempfile
import time
from typing import Any, Callable


def parser(doc: str, results: str, rounds: int) -> argparse.ArgumentParser:
    """``--smoke`` (tiny sizes, one round), ``--out`` (default ``results``: the results file's path, a
    relative one taken from ``benchmarks/``; the scripts pass the absolute path beside themselves), ``--rounds``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="tiny sizes, one round (checks the script runs)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), results))
    ap.add_argument("--rounds", type=int, default=rounds, help=f"interleaved rounds, best of each (default {rounds})")
    return ap


def native_missing() -> bool:
    """True (after saying why) where the native backend cannot run: the script then exits with 1."""
    import vpforms

    ok, why = vpforms.native.available()
    if not ok:
        print(f"native backend unavailable: {why}")
    return not ok


def fresh_native_cache() -> None:
    """A native-kernel cache of the run's own (unless ``VPFORMS_NATIVE_CACHE`` is set), so that a
    "compile" column times a compilation, not a load of an earlier run's kernel."""
    os.environ.setdefault("VPFORMS_NATIVE_CACHE", tempfile.mkdtemp(prefix="vpforms-bench-"))


def best_of(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """The shortest wall time of ``repeats`` calls of ``fn`` and the last call's result."""
    best, out = math.inf, None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def per_step(go: Callable[[int], Any], n: int, N: int, rounds: int,
             strict: bool = True) -> tuple[float, float, Any]:
    """(ns per particle-step, compile s, the last run of 2n steps) of ``go(steps)`` on N particles:
    the cost of n more steps, (best of 2n − best of n)/(N·n), so that a run's fixed costs (the
    check of the initial conditions, the kernel call's set-up) cancel; compile = first call − best
    call of n steps. ``strict`` (off in smoke mode only): an error, never a number, where the 2n
    steps do not take measurably longer than the n (fixed costs and noise dominate)."""
    t = time.perf_counter()
    go(n)
    first = time.perf_counter() - t
    best, _ = best_of(lambda: go(n), rounds)
    best2, sol = best_of(lambda: go(2 * n), rounds)
    if strict and not best2 > 1.2 * best:  # n more steps must cost something measurable next to the fixed costs
        raise RuntimeError(f"{n} more steps took {best2 - best:+.3f} s next to {best:.3f} s for {n}: the "
                           "run's fixed costs and the machine's noise dominate; take more steps")
    return (best2 - best) * 1e9 / (N * n), first - best, sol


def interleaved(fns: dict[str, Callable[[], Any]], rounds: int) -> tuple[dict[str, float], dict[str, Any]]:
    """The best wall time of each of ``fns`` over ``rounds`` interleaved rounds (one call of each per
    round, so that a change of machine load touches all of them alike) and each one's last result."""
    times, out = dict.fromkeys(fns, math.inf), {}
    for _ in range(rounds):
        for k, fn in fns.items():
            t, out[k] = best_of(fn, 1)
            times[k] = min(times[k], t)
    return times, out


def jax_cell(fn: Callable[[], Any], per: int, native_s: float) -> tuple[str, Any]:
    """The JAX reference of a native timing: compile (one call), then one timed call; the table
    cell "ns per unit (× native)" and its result."""
    fn()
    t, ref = best_of(fn, 1)
    return f"{t * 1e9 / per:.0f} ({t / native_s:.1f}× native)", ref


def results_tail(script: str, seconds: float, smoke: bool) -> list[str]:
    """The closing lines of a results file: the load average at the end, then :func:`machine`."""
    load = os.getloadavg()
    return [f"Load average (1, 5, 15 min) at the end: {load[0]:.1f}, {load[1]:.1f}, {load[2]:.1f}.", "",
            machine(script, seconds, smoke), ""]


def script_path(name: str) -> str:
    """The path from the repository root of the benchmark script ``name`` (``bench_x.py``), found in
    the topic folders of ``benchmarks/`` (script names are unique there: ``benchmarks/index.py``)."""
    here = os.path.dirname(os.path.abspath(__file__))
    for folder, _, files in sorted(os.walk(here)):
        if name in files:
            return os.path.relpath(os.path.join(folder, name), os.path.dirname(here)).replace(os.sep, "/")
    raise FileNotFoundError(f"no benchmark script {name!r} under {here}")


def machine(script: str, seconds: float, smoke: bool) -> str:
    """One line: the machine, the JAX and vpforms versions, the command and how long it ran
    (``script``: the script's file name, then its arguments if any)."""
    import jax

    import vpforms

    name, _, args = script.partition(" ")
    command = " ".join([script_path(name), *([args] if args else [])])
    return (f"Machine: {platform.machine()}, {os.cpu_count()} CPU cores (shared), {platform.system()}; "
            f"JAX {jax.__version__} ({jax.default_backend()}), float64; vpforms {vpforms.__version__}. "
            f"Generated by `python {command}{' --smoke' if smoke else ''}` in {seconds:.0f} s"
            + (" (**smoke mode: tiny sizes, timings meaningless**)" if smoke else "") + ".")


def write_results(path: str, text: str) -> int:
    """Write the results text to ``path``, print it, and return 0 (the scripts' exit code)."""
    with open(path, "w") as fh:
        fh.write(text)
    print(text)
    return 0

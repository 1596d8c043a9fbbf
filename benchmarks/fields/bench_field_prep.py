"""Preparation time of a user's field (issue #22): the Fourier series sin(y) + sin(2y) + … + sin(ny),
0, 0 from text to the first step, written to results_field_prep.md.

Per n and method, a fresh Python process (no SymPy cache shared between rows) does what
``vpforms run --field …`` does: ``field_from_text`` (parse, real-field check, divergence check,
linearity detection), then the method (SE+SE with recovery: the relabelled fields and the closed-form
potentials; rk4: none), then one step through ``vpforms.integrate`` (compilation included).
``--src`` points the child processes at another source tree (e.g. an export of the main branch) to
compare; a row that runs past ``--timeout`` seconds is reported as such.

    python benchmarks/fields/bench_field_prep.py [--smoke] [--src DIR] [--timeout 150] [--out benchmarks/fields/results_field_prep.md]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser, write_results  # noqa: E402

SRC = os.path.join(os.path.dirname(os.path.dirname(HERE)), "src")

CHILD = r"""
import json, sys, time
n, method = int(sys.argv[1]), sys.argv[2]
t0 = time.perf_counter()
import vpforms
from vpforms._parse import field_from_text
t1 = time.perf_counter()
f = field_from_text("+".join(f"sin({k}*y)" for k in range(1, n + 1)) + ", 0, 0", {})
t2 = time.perf_counter()
m = vpforms.RK4(f) if method == "rk4" else vpforms.scheme(f, method)
t3 = time.perf_counter()
sol = vpforms.integrate(m, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]], 0.1, 1, progress=False)
t4 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "field": t2 - t1, "method": t3 - t2, "step": t4 - t3,
                  "failed": int(sol.n_failed), "check": f.divergence_check}))
"""


def one(src: str, n: int, method: str, timeout: float) -> dict:
    env = {**os.environ, "PYTHONPATH": src}
    t = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, str(n), method], env=env, capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timeout": timeout}
    if p.returncode:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1][:120], "wall": time.perf_counter() - t}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_field_prep.md"), rounds=1)
    ap.add_argument("--src", default=SRC, help="source tree the child processes import vpforms from")
    ap.add_argument("--timeout", type=float, default=150.0, help="seconds per row")
    ap.add_argument("--ns", default="10,20,40,80")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    ns = [3] if args.smoke else [int(v) for v in args.ns.split(",")]
    rows = ["| n | method | field_from_text (s) | method (s) | ready to step (s) | first step (s) | divergence check |",
            "|---|---|---|---|---|---|---|"]
    for n in ns:
        for method in ("SE+SE", "rk4"):
            r = one(args.src, n, method, args.timeout)
            if "timeout" in r:
                rows.append(f"| {n} | {method} | > {args.timeout:.0f} (killed) | | | | |")
            elif "error" in r:
                rows.append(f"| {n} | {method} | error: {r['error']} | | | | |")
            else:
                rows.append(f"| {n} | {method} | {r['field']:.2f} | {r['method']:.2f} | "
                            f"{r['field'] + r['method']:.2f} | {r['step']:.2f} | {r['check'][:40]} |")
            print(rows[-1], flush=True)
    text = "\n".join(["# Preparation of a Fourier-series field (issue #22)", "",
                      f"Source tree: `{os.path.relpath(args.src)}`.  'ready to step' = field_from_text + the "
                      "method (what the command line does before its first step, imports excluded).", "",
                      *rows, "", machine("bench_field_prep.py", time.perf_counter() - t0, args.smoke), ""])
    return write_results(args.out, text)


if __name__ == "__main__":
    raise SystemExit(main())

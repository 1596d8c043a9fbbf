"""GPU probe (results_gpu.md, 'Where the time goes'): cProfile of a 1-step integrate() call: the host-side work of a call.

    PYTHONPATH=src python3 benchmarks/scale/gpu_probes/probe_host_profile.py N
"""

import cProfile
import pstats
import sys

import vpforms
from vpforms import problems

N = int(sys.argv[1]); abc = problems.get("abc"); x0 = abc.initial_conditions(N, seed=0)
m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
f = lambda: vpforms.integrate(m, x0, 0.1, 1, chunk_size=N, progress=False, backend="jax")
f(); f()
cProfile.run("f()", "/tmp/p4")
pstats.Stats("/tmp/p4").sort_stats("tottime").print_stats(14)

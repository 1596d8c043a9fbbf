import sys, cProfile, pstats, time
import vpforms
from vpforms import problems
N = int(sys.argv[1]); abc = problems.get("abc"); x0 = abc.initial_conditions(N, seed=0)
m = vpforms.scheme(abc.field, "SE+SE", fast=True, recover=False)
f = lambda: vpforms.integrate(m, x0, 0.1, 1, chunk_size=N, progress=False, backend="jax")
f(); f()
cProfile.run("f()", "/tmp/p4")
pstats.Stats("/tmp/p4").sort_stats("tottime").print_stats(14)

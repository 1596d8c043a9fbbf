"""Bounded memory for coil sets of real size (issues #38 item 2, #40 item 2).

A child process builds a synthetic coil set of 10⁵ segments (the l = 2 stellarator's coils with
their polylines refined) and runs what evaluates coils: B and A at many points, the derivatives an
outer vmap over a potential check's worth of points takes (reverse mode through the gauge
integral's χ, then forward), a grid of A sampled on the domain's nodes, a method on that grid and a
few steps. Its peak resident memory (the kernel's VmHWM of the child's own memory map) must stay ≤ 2 GB, where
holding the (points × segments) intermediates at once would take ~10–100 GB.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

_CHILD = r"""
import json, resource, time
import numpy as np, jax, jax.numpy as jnp
import vpforms
from vpforms.coils import l2_stellarator
from vpforms.coils._segments import segment_chunk
from vpforms.domains import ToroidalDomain
from vpforms.problems.coil_fields import spline_coil_field

coils = l2_stellarator(points_per_tf=5000, points_per_period=300, vf_points=120)
S = int(coils.segments()[0].shape[0])
out = {"segments": S, "chunk": segment_chunk()}
t = time.perf_counter()
rng = np.random.default_rng(0)
x = np.c_[rng.uniform(0.85, 1.1, 4000), rng.uniform(-0.1, 0.1, 4000), rng.uniform(-0.1, 0.1, 4000)]
B = np.asarray(coils.B(x))
out["B_finite"] = bool(np.isfinite(B).all())
# an outer vmap of 1024 evaluations of ∂/∂x (reverse) then ∂/∂x (forward) of A: the potential check's pattern
J = jax.vmap(jax.jacfwd(jax.jacrev(lambda p: coils.A(p)[1])))(jnp.asarray(x[:1024]))
out["J_finite"] = bool(np.isfinite(np.asarray(J)).all())
dom = ToroidalDomain.tube(lambda p: (0.983 + 0 * p, 0 * p), 0.1, nfp=coils.nfp, n_phi=4)
field, err = spline_coil_field(coils, (0.8, 1.18), (-0.18, 0.18), n_R=14, n_phi=8, n_Z=14, domain=dom)
out["spline_error"] = err
m = vpforms.scheme(field, "SE+SE")
sol = vpforms.integrate(m, np.array([[0.5 * 1.03**2, 0.0, 0.0]]), 0.01, 3, progress=False, backend="jax")
out["failed"] = int(sol.n_failed)
out["seconds"] = time.perf_counter() - t
# VmHWM: the peak of this process's own memory map. (ru_maxrss would also count the parent's
# resident set at the fork before exec: Linux keeps it across execve — a pytest worker's GBs.)
try:
    out["peak_MB"] = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")) / 1024
except OSError:
    out["peak_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print("@@" + json.dumps(out))
"""


@pytest.mark.slow  # a child process: 10⁵ segments evaluated at ~10⁴ points, a grid and a method (~1–2 min)
def test_1e5_segments_in_bounded_memory():
    r = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.split("@@")[-1])
    assert out["segments"] >= 100_000, out
    assert out["B_finite"] and out["J_finite"] and out["failed"] == 0, out
    assert out["peak_MB"] <= 2048, out
    print(out)

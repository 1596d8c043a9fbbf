"""What the native kernel-reuse tests of spline and coil fields share (data passed at run time)."""

from __future__ import annotations

import numpy as np

from vpforms.backends.native import build as nbuild
from vpforms.backends.native.runner import kernel_for, run_points


def assert_reuses_kernel(m1, m2, f1, f2, x0, h=1e-3):
    """m2 (on the field f2) runs on m1's compiled library with nothing compiled, and each kernel
    steps its own field: one step is x + h a(x) + O(h²), and the two steps differ by far more."""
    k1 = kernel_for(m1)
    before = dict(nbuild.COUNTERS)
    k2 = kernel_for(m2)
    assert nbuild.COUNTERS["compiled"] == before["compiled"] and k2.lib is k1.lib
    X1 = run_points(m1, x0, h, np.array([0, 1]))[0][:, -1]
    X2 = run_points(m2, x0, h, np.array([0, 1]))[0][:, -1]
    a1, a2 = np.asarray(f1(x0)), np.asarray(f2(x0))
    assert np.max(np.abs(X1 - x0 - h * a1)) <= 10 * h * h * np.max(np.abs(a1))
    assert np.max(np.abs(X2 - x0 - h * a2)) <= 10 * h * h * np.max(np.abs(a2))
    assert np.max(np.abs(X2 - X1)) > 100 * h * h * np.max(np.abs(a2))

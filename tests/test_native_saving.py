"""The native kernel writes the saved states itself (issue #19 item 2: save_every pays no call per
save): its saves equal those of one kernel call per saved step (``run_points``, the old runner)
bit for bit — frozen failures, the last step off the stride and recovered steps included — and a
run makes at most ``CALLS`` kernel calls however often it saves."""

from __future__ import annotations

import numpy as np
import pytest

import vpforms as vp
from vpforms import RESULTS, problems
from vpforms._solution import saved_steps
from vpforms.backends.native import runner
from vpforms.backends.native.runner import CALLS, NativeKernel, run_points, run_saving

from .test_native import _Fake, _overflow_field

_OK, _WHY = vp.native.available()
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


@pytest.mark.parametrize("n_steps,save_every", [(15, 1), (16, 5), (16, 4), (17, 10)])
def test_kernel_saves_equal_one_call_per_save(n_steps, save_every):
    """RK4 on a field that overflows: particle 0 fails mid-run (frozen, its later saves its frozen
    state), particle 1 runs through; n_steps off the stride saves the last step too."""
    m = vp.RK4(_overflow_field())
    x0 = np.array([[700.0, 0.0, 0.0], [0.0, 0.0, 0.0], [650.0, 0.1, 0.0]])
    steps = saved_steps(n_steps, save_every)
    a = run_saving(m, x0, 1.0, n_steps, save_every)
    b = run_points(m, x0, 1.0, steps)
    for got, want in zip(a, b):
        np.testing.assert_array_equal(got, want)
    assert a[1][0] == RESULTS.nonfinite and np.all(np.isfinite(a[0]))


def test_recovered_steps_are_saved():
    """The fake method's bare step fails from some step on; each later step is recovered through
    JAX and must appear in the saves (the kernel had filled them with the frozen state)."""
    m = _Fake()
    x0 = np.array([[700.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    a = run_saving(m, x0, 1.0, 15, 1)
    b = run_points(m, x0, 1.0, saved_steps(15, 1))
    for got, want in zip(a, b):
        np.testing.assert_array_equal(got, want)
    assert a[3][0] > 0  # recovered steps happened


def test_saving_every_step_makes_few_kernel_calls(monkeypatch):
    prob = problems.get("abc")
    m = vp.compose(vp.scheme(prob.field, "SE+SE", fast=True, recover=False), 2)
    calls = []
    orig = NativeKernel.advance

    def counting(self, *a, **k):
        calls.append(1)
        return orig(self, *a, **k)

    monkeypatch.setattr(NativeKernel, "advance", counting)
    x0 = prob.initial_conditions(100, seed=0)
    sol = vp.integrate(m, x0, 0.05, 1000, save_every=1, progress=False, backend="native")
    assert sol.xs.shape == (100, 1001, 3) and len(calls) <= CALLS
    ref = vp.integrate(m, x0, 0.05, 1000, save_every=1, progress=False, backend="jax")
    np.testing.assert_allclose(sol.xs, ref.xs, rtol=0, atol=1e-10)
    assert runner.CALLS == CALLS


def test_a_few_lanes_are_split_over_the_threads_and_each_lane_is_its_own():
    """A few lanes (field lines) run as one block per thread (``vp_block``: fewer than B lanes a
    block), and a lane's states do not depend on which lanes share its block: 7 lines run together
    equal each line run alone, bit for bit, saves included."""
    m = vp.scheme(problems.get("abc").field, "SE+SE")
    x0 = np.random.default_rng(3).uniform(0.0, 2 * np.pi, (7, 3))
    together = vp.integrate(m, x0, 0.05, 40, save_every=8, backend="native", progress=False)
    for i in range(len(x0)):
        alone = vp.integrate(m, x0[i:i + 1], 0.05, 40, save_every=8, backend="native", progress=False)
        np.testing.assert_array_equal(together.xs[i], alone.xs[0])
    src = NativeKernel(m).source
    assert "vp_block(N)" in src and "omp_get_max_threads" in src

"""All 36 cases of ``vpforms.scheme`` on the problem library's fields (issue #5, item 3).

For every case c (built from the five recipes by relabelling and adjunction only):
* the method's case is c, and its step solves the determining equations of c itself (residual of
  eq:volpot through the method's generating map), or — for the S1/S2 correction maps on nonlinear
  fields, which have no explicit potentials — the twist conditions of c hold with the leading terms
  the field predicts: ∂X₋/∂x₊ = δ + h ∂a_{X₋}/∂x_{x₊} + O(h²), ∂x₋/∂X₊ = δ − h ∂a_{x₋}/∂x_{X₊} + O(h²);
* |det J − 1| ≤ 1e-12 at random points and random step sizes;
* consistency: ‖(X − x)/h − a(x)‖ = O(h) (log–log slope ≈ 1 over three h);
* observed global order 1.00 ± 0.1 (least-squares fit over 4 step sizes against DOP853).
One compiled function per case computes X, J, the residual and the twist together.
"""

import os
import time

import numpy as np
import pytest

from vpforms import cases
from vpforms._methods import scheme

from .test_methods_helpers import field_and_points, fit_order, global_errors, kernel, reference_flow


def check_all_cases(field_name: str, T: float = 0.4, ns=(4, 8, 16, 32)):
    field, pts = field_and_points(field_name, n=6, seed=1)
    a = np.asarray(field(pts))
    Da = np.asarray(field.jacobian(pts))
    rng = np.random.default_rng(7)
    h_det = rng.uniform(0.01, 0.1, len(pts))
    h_cons = (0.04, 0.02, 0.01, 0.005)  # ≥ 4 step sizes for the log–log slope
    x0 = pts  # same shape as every other call: one compilation per case
    ref = reference_flow(field, x0, T)
    report = []
    for c in cases():
        t0 = time.perf_counter()
        m = scheme(field, c, recover=False)  # case c's own recipe (recovery would compile ~15 alternatives)
        assert m.case == c and m.cls == c.cls and m.order == 1
        F, has_map = kernel(m)
        out = F(pts, h_det)
        assert np.all(np.asarray(out["status"]) == 0), (c, out["status"])
        det_err = float(np.max(np.abs(np.linalg.det(np.asarray(out["J"])) - 1)))
        assert det_err <= 1e-12, (c, det_err)
        # consistency, with the residual of case c (or its twist) at every h
        cons = []
        for h in h_cons:
            o = F(pts, np.full(len(pts), h))
            X = np.asarray(o["X"])
            cons.append(float(np.max(np.abs((X - pts) / h - a))))
            if has_map:
                assert m.generating_map(h, pts[0]).case == c
                assert float(np.max(np.abs(np.asarray(o["res"])))) <= 1e-10, c
            tw = np.asarray(o["twist"])
            d1 = float(c.X_minus == c.x_plus)
            d2 = float(c.x_minus == c.X_plus)
            pred1 = d1 + h * Da[:, c.X_minus - 1, c.x_plus - 1]
            pred2 = d2 - h * Da[:, c.x_minus - 1, c.X_plus - 1]
            scale = 1 + np.max(np.abs(Da)) ** 2
            assert np.max(np.abs(tw[:, 0] - pred1)) <= 5 * scale * h**2, (c, "twist 1")
            assert np.max(np.abs(tw[:, 1] - pred2)) <= 5 * scale * h**2, (c, "twist 2")
        slope_c = fit_order(h_cons, cons)
        assert 0.85 <= slope_c <= 1.15, (c, cons)
        # global order
        errs = global_errors(lambda x, h: F(x, np.full(len(x), h))["X"], x0, T, ns, ref)
        p = fit_order([T / n for n in ns], errs)
        assert abs(p - 1.0) <= 0.1, (c, p, errs)
        report.append((c, det_err, p, time.perf_counter() - t0))
    if os.environ.get("VPFORMS_REPORT"):
        for r in report:
            print(field_name, r[0].cls, r[0], f"det-1={r[1]:.1e} order={r[2]:.3f} {r[3]:.1f}s")
    return report


@pytest.mark.slow  # ≈ 1–1.5 min: one compilation per case (runs in CI)
def test_all_36_cases_abc():
    # T = 0.1 keeps the trajectories inside (0, π/2)³, away from the fold planes of the DL classes
    # (sin or cos of one coordinate = 0, where their generating forms cease to exist)
    check_all_cases("abc", T=0.1)

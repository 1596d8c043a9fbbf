"""Diagnostics along trajectories: volume (log |det J|), invariants, observed order, Poincaré sections.

The trajectory diagnostics (:func:`log_det`, :func:`step_size_errors`, :func:`observed_order`,
:func:`poincare_section`) take a *method* — anything with ``step_with_status(x, h) -> (X, status)``
for x of shape (3,) — and run it in float64 under ``jit``/``vmap``; a particle whose step fails is
frozen and its code reported, never carried as NaN.

* :func:`log_det` — per-step and accumulated log |det DΨ_h| along trajectories, the Jacobian by
  forward-mode AD through the step (exact IFT derivatives through the Newton solves), never by
  finite differences.  log |det D(Ψ_h^n)| = Σ_k log |det DΨ_h(x_k)| by the chain rule.
* :func:`invariant_drift` — I(x(t)) − I(x(0)) for named invariants (a Problem's ``invariants``).
* :func:`step_size_errors`, :func:`fit_order`, :func:`observed_order` — errors at time T for a
  step-size sweep and a plateau-aware log–log fit of the slope.
* :func:`poincare_section` — *non-terminating* crossings of a plane x_axis = value (optionally
  modulo a period), detected on the fly inside the scan and then located on the method's own
  continuous step family θ ↦ Ψ_{θh}(x_n), θ ∈ [0, 1] (see its docstring for the order).
* :func:`twist_map` — for a field or a method and a set of points, the fraction of points where
  each class's (or case's) twist condition holds, from one bare step of each (issue #12).
* :func:`explain_failures` — failed particles by reason, the first failures and a hint computed
  from the failed steps (smaller h, another class whose twist holds there).

One module per responsibility: :mod:`.volume` (log_det), :mod:`.invariants`, :mod:`.order`,
:mod:`.poincare`, :mod:`.twist`, :mod:`.failures`; every public name (and the private helpers other
modules use) is re-exported here, so ``from vpforms.diagnostics import log_det`` keeps working.
"""

from __future__ import annotations

from ._common import _chunks, _pad, _points
from .failures import FailureReport, explain_failures, failure_breakdown
from .invariants import invariant_drift
from .order import (
    OrderFit,
    _step_sizes,
    fit_order,
    observed_order,
    reference_solution,
    step_size_errors,
)
from .poincare import (
    PoincareSection,
    _interp_order,
    _levels,
    _poincare_scan,
    _refine_kernel,
    poincare_section,
)
from .steps import StepChoice, steps_for_tol
from .twist import TwistMap, TwistRow, twist_map
from .volume import LogDet, _logdet_kernel, log_det

__all__ = [
    "StepChoice",
    "steps_for_tol",
    "LogDet",
    "log_det",
    "invariant_drift",
    "step_size_errors",
    "reference_solution",
    "OrderFit",
    "fit_order",
    "observed_order",
    "PoincareSection",
    "poincare_section",
    "TwistRow",
    "TwistMap",
    "twist_map",
    "FailureReport",
    "explain_failures",
    "failure_breakdown",
]

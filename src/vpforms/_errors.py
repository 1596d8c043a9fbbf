"""Errors and per-point status codes.

Inside jitted code nothing can raise, so every solve returns an integer status per point (like
diffrax's ``RESULTS``); :func:`raise_for_status` turns a concrete status array into a readable
exception at the boundary between jitted and user code.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "VPFormsError",
    "TwistConditionError",
    "ConvergenceError",
    "NonFiniteError",
    "NotDivergenceFreeError",
    "NotRealFieldError",
    "BudgetError",
    "InconsistentStepError",
    "SpecError",
    "RESULTS",
    "RECOVERY",
    "raise_for_status",
]


class VPFormsError(Exception):
    """Base class of every error vpforms raises on purpose."""


class SpecError(VPFormsError, ValueError):
    """A method or field cannot be written as (or rebuilt from) a spec."""


class TwistConditionError(VPFormsError):
    """A twist condition failed: ∂₁₂φ = 0 (volpot1) or ∂₂₃Φ = 0 (volpot2) at a point."""


class ConvergenceError(VPFormsError):
    """A Newton iteration did not converge within its iteration cap (or diverged)."""


class NonFiniteError(VPFormsError, ValueError):
    """A point or a potential value was NaN or infinite."""


class InconsistentStepError(VPFormsError):
    """A step solved its equations but does not follow the field: |X − x − h a(x)| exceeded the
    consistency guard (issue #23; e.g. a Newton root on another branch, or potentials that do not
    reproduce the field at that point)."""


class LeftDomainError(VPFormsError):
    """The field line left the field's domain (the grid of a gridded field): the step could not be
    taken because the field is not defined there — a stop, not a failure of the method."""


class NotDivergenceFreeError(VPFormsError, ValueError):
    """A vector field given as divergence free is not."""


class NotRealFieldError(VPFormsError, ValueError):
    """A field is complex or not finite (overflow, a singularity) at sampled points of its box or
    at the initial conditions (issue #22): it cannot be stepped in float64."""


class BudgetError(VPFormsError, ValueError):
    """A symbolic step of field preparation exceeded its budget and has no cheaper exact
    alternative (:mod:`vpforms._budget`); the message names the step and what to do."""


class RESULTS:
    """Per-point status codes returned by jitted solves (``int32`` arrays)."""

    successful = 0
    twist_failure = 1
    not_converged = 2
    nonfinite = 3
    inconsistent = 4
    left_domain = 5

    messages = {
        successful: "converged",
        twist_failure: "twist condition failed (∂₁₂φ = 0 in volpot1 or ∂₂₃Φ = 0 in volpot2)",
        not_converged: "Newton iteration did not converge",
        nonfinite: "non-finite input or result (NaN/inf)",
        inconsistent: "inconsistent step: |X − x − h a(x)| > κ·|h a(x)| (the step does not follow the field)",
        left_domain: "the field line left the domain (a wall, or the grid of a gridded field)",
    }
    #: short reason names for counts ("163 twist condition failed, 8 non-finite")
    short = {
        successful: "succeeded",
        twist_failure: "twist condition failed",
        not_converged: "Newton not converged",
        nonfinite: "non-finite",
        inconsistent: "inconsistent step",
        left_domain: "left the domain",
    }
    errors = {
        twist_failure: TwistConditionError,
        not_converged: ConvergenceError,
        nonfinite: NonFiniteError,
        inconsistent: InconsistentStepError,
        left_domain: LeftDomainError,
    }


def raise_for_status(status, what: str = "generating map", max_indices: int = 5) -> None:
    """Raise the named error for the first failure code present in a concrete status array.

    The message says how many points failed, with which status, and the first indices.
    """
    status = np.asarray(status)
    if status.size == 0 or not np.any(status != RESULTS.successful):
        return
    flat = status.reshape(-1)
    parts = []
    first_code = None
    for code in (RESULTS.nonfinite, RESULTS.twist_failure, RESULTS.not_converged, RESULTS.inconsistent,
                 RESULTS.left_domain):
        idx = np.flatnonzero(flat == code)
        if idx.size:
            first_code = first_code if first_code is not None else code
            shown = ", ".join(str(i) for i in idx[:max_indices])
            more = ", …" if idx.size > max_indices else ""
            parts.append(
                f"{idx.size} of {flat.size} point(s): {RESULTS.messages[code]} "
                f"(first indices: [{shown}{more}])"
            )
    unknown = np.flatnonzero(~np.isin(flat, list(RESULTS.messages)))
    if unknown.size:
        raise VPFormsError(f"{what}: unknown status codes {np.unique(flat[unknown])}")
    raise RESULTS.errors[first_code](f"{what} failed at " + "; ".join(parts))


class RECOVERY:
    """Per-point codes saying how a failed step was recovered (``Method.step_with_recovery``).

    0: the bare step succeeded; otherwise the first alternative that succeeded, in the recovery
    order of :func:`vpforms.scheme` (``recover=True``). ``same_map`` (DL classes in the engine
    form): the same map evaluated by its nested θ-stages (``fast=True``), tried first.
    """

    none = 0
    other_case = 1
    other_class = 2
    substeps = 3
    same_map = 4

    messages = {
        none: "bare step",
        same_map: "the same DL map by its nested θ-stages",
        other_case: "another case of the same class",
        other_class: "another class",
        substeps: "2^k VP sub-steps of the same method",
    }

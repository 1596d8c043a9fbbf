"""Where does the twist condition hold? :func:`twist_map` over classes or cases (issue #12).

A generating-form step of case c exists at x only where its two twist conditions hold
(∂₁₂φ ≠ 0 in volpot1, ∂₂₃Φ ≠ 0 in volpot2).  The one test of that is the engine's: the scalar
Newton solver reports ``RESULTS.twist_failure`` (status 1) when |∂g/∂z| ≤ twist_tol during a solve
(:mod:`vpforms._newton`, used by every :class:`vpforms.GeneratingMap`).  So :func:`twist_map` does
not re-derive any twist formula: it takes ONE bare step Ψ_h of each candidate method (built by
:func:`vpforms.scheme` with ``recover=False``: the class recipe through its generating map) at
every sampled point and counts the status codes.  A point counts as "twist holds" when its step
did not report status 1; a Newton failure or a non-finite result at a point where the twist held
is counted separately (``step_ok`` is the fraction where the step succeeded outright).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import _config  # noqa: F401
from .._case import CLASSES, Case, cases
from .._errors import RESULTS, VPFormsError
from .._methods._scheme import scheme
from .._solution import describe

__all__ = ["TwistRow", "TwistMap", "twist_map"]


@dataclass(frozen=True)
class TwistRow:
    """One candidate of a :class:`TwistMap`.

    ``label`` names it ("SE+SE", a case "(3,2,1)·(1,2,3)", or "this method: …"); ``twist`` the
    fraction of points where its twist condition holds (no status 1), ``step_ok`` where its step
    succeeded (status 0); ``counts`` the number of points per ``RESULTS`` code; ``error`` is the
    reason the recipe does not apply to this field (then the fractions are NaN and no step ran).
    """

    label: str
    cls: str | None
    case: Any
    twist: float
    step_ok: float
    counts: dict = field(default_factory=dict)
    error: str | None = None
    own: bool = False


@dataclass(frozen=True)
class TwistMap:
    """The result of :func:`twist_map`: one :class:`TwistRow` per candidate, in evaluation order.

    ``status`` maps each label to the per-point status array of its step (the data the fractions
    were counted from).  ``str(tm)`` / :meth:`table` is a readable table; :meth:`best` the candidate
    whose step succeeds at most points.
    """

    rows: tuple
    h: float
    n_points: int
    field: str
    status: dict = field(default_factory=dict, repr=False, compare=False)

    def row(self, label: str) -> TwistRow:
        for r in self.rows:
            if r.label == label:
                return r
        raise KeyError(f"no candidate {label!r} in this twist map; candidates: "
                       f"{', '.join(r.label for r in self.rows)}")

    def best(self, exclude: tuple = ()) -> TwistRow | None:
        """The applicable candidate (not its own method, not a label in ``exclude``) with the
        largest step success fraction, then the largest twist fraction (first on ties)."""
        usable = [r for r in self.rows if r.error is None and not r.own and r.label not in exclude
                  and r.cls not in exclude]
        if not usable:
            return None
        return max(usable, key=lambda r: (r.step_ok, r.twist))

    def table(self) -> str:
        """A plain-text table: candidate, twist holds (%), step succeeds (%), failures by reason."""
        head = f"twist condition on {self.field} at h = {self.h:g}, {self.n_points} point(s)"
        width = max([len("candidate")] + [len(r.label) for r in self.rows])
        lines = [head, f"{'candidate':<{width}}  twist holds  step succeeds  failures"]
        for r in self.rows:
            if r.error is not None:
                lines.append(f"{r.label:<{width}}  {'—':>11}  {'—':>13}  recipe does not apply: {r.error}")
                continue
            fails = ", ".join(f"{n} {RESULTS.short[c]}" for c, n in sorted(r.counts.items())
                              if c != RESULTS.successful and n) or "none"
            lines.append(f"{r.label:<{width}}  {100 * r.twist:10.1f}%  {100 * r.step_ok:12.1f}%  {fails}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def _field_of(obj: Any):
    """(field, method or None) from a Field, a Problem or a method."""
    if hasattr(type(obj), "se_potentials"):  # a vpforms.Field
        return obj, None
    if hasattr(obj, "step_with_status"):
        f = getattr(obj, "field", None)
        if f is None or not hasattr(type(f), "se_potentials"):
            raise TypeError("twist_map needs a vpforms method built on a vpforms.Field "
                            f"(its .field), got {type(obj).__name__} without one")
        return f, obj
    f = getattr(obj, "field", None)  # a Problem
    if f is not None and hasattr(type(f), "se_potentials"):
        return f, None
    raise TypeError(f"twist_map needs a vpforms.Field, a Problem or a vpforms method; got {type(obj).__name__}")


def _candidates(which):
    if which == "classes":
        return list(CLASSES)
    if which == "all":
        return list(cases())
    if isinstance(which, str):
        raise ValueError(f"cases must be 'classes', 'all' or a list of classes/cases, not {which!r}")
    out = []
    for c in which:
        out.append(c if isinstance(c, (str, Case)) else Case(*c))
    if not out:
        raise ValueError("cases is empty: give 'classes', 'all' or at least one class/case")
    return out


def _label(c) -> str:
    return c if isinstance(c, str) else f"{c.cls} {c}"


def _statuses(method, pts: np.ndarray, h: float) -> np.ndarray:
    """Per-point RESULTS code of one bare step (a non-finite 'success' counts as non-finite)."""
    X, st = method.step_with_status(pts, h)
    X, st = np.asarray(X), np.asarray(st, dtype=np.int32).reshape(-1)
    bad = ~np.all(np.isfinite(X.reshape(-1, 3)), axis=1)
    return np.where((st == RESULTS.successful) & bad, RESULTS.nonfinite, st).astype(np.int32)


#: bare candidate methods per (field, candidate, options): a repeated twist map (a run's summary,
#: then its explain, the CLI hint) reuses their compiled steps instead of compiling again
_CANDIDATES: dict = {}


def _candidate(f, c, options):
    key = (id(f), c if isinstance(c, str) else (c.sigma.one_line(), c.Sigma.one_line()),
           repr(sorted(options.items())))
    hit = _CANDIDATES.get(key)
    if hit is not None and hit[0] is f:
        return hit[1]
    m = scheme(f, c, recover=False, **options)
    if len(_CANDIDATES) > 256:  # bounded: fields made in a loop do not pile up
        _CANDIDATES.clear()
    _CANDIDATES[key] = (f, m)
    return m


def _row(label, cls, case, st: np.ndarray, own=False) -> TwistRow:
    n = st.size
    counts = {int(c): int(np.count_nonzero(st == c)) for c in np.unique(st)}
    return TwistRow(label, cls, case, float(np.count_nonzero(st != RESULTS.twist_failure) / n),
                    float(np.count_nonzero(st == RESULTS.successful) / n), counts, None, own)


def twist_map(method_or_field: Any, points: Any, h: float = 0.1, cases: Any = "classes",
              **options) -> TwistMap:
    """The fraction of ``points`` where each class's (or case's) twist condition holds at step h.

    Parameters
    ----------
    method_or_field:
        A :class:`vpforms.Field`, a Problem (its field) or a vpforms method.  For a method, its own
        bare step (recovery stripped: a composition counts a failure in any stage) is the first
        row, marked ``own``; the candidates are then built on ``method.field``.
    points:
        Shape (3,) or (N, 3), finite: e.g. the states where a run's steps failed.
    h:
        The step size (the twist of a step's generating form depends on h).
    cases:
        ``"classes"`` (default: the five class representatives S1, S2, SE+SE, DL+DL, SE+DL),
        ``"all"`` (the 36 cases of :func:`vpforms.cases`; one compilation each) or a list of
        class names / :class:`vpforms.Case` / (σ, Σ) pairs.
    options:
        Passed to :func:`vpforms.scheme` for every candidate (e.g. ``newton``); a candidate whose
        recipe does not apply to the field gets a row with ``error`` instead of fractions.

    Notes
    -----
    Each candidate takes one step from every point with ``scheme(field, c, recover=False)`` and its
    per-point status is counted (see the module docstring): no separate twist formula.
    """
    f, method = _field_of(method_or_field)
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim not in (1, 2) or pts.shape[-1] != 3 or pts.size == 0:
        raise ValueError(f"points must have shape (3,) or (N, 3) with N ≥ 1; got {pts.shape}")
    pts = pts.reshape(-1, 3)
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or infinite values")
    h = float(h)
    if not math.isfinite(h) or h == 0.0:
        raise ValueError(f"h must be a finite non-zero number, got {h}")
    if "recover" in options:
        raise ValueError("twist_map always evaluates the bare step (recover=False); drop 'recover'")

    rows, status = [], {}
    if method is not None:
        bare = method.without_recovery() if hasattr(method, "without_recovery") else method
        label = f"this method: {describe(bare)}"
        st = _statuses(bare, pts, h)
        rows.append(_row(label, getattr(method, "cls", None), getattr(method, "case", None), st, own=True))
        status[label] = st
    for c in _candidates(cases):
        label = _label(c)
        try:
            m = _candidate(f, c, options)
        except (VPFormsError, ValueError) as exc:  # the recipe does not apply (e.g. RecipeError)
            cls = c if isinstance(c, str) else c.cls
            rows.append(TwistRow(label, cls, None if isinstance(c, str) else c, math.nan, math.nan,
                                 {}, str(exc).splitlines()[0]))
            continue
        st = _statuses(m, pts, h)
        rows.append(_row(label, m.cls, m.case, st))
        status[label] = st
    return TwistMap(tuple(rows), h, pts.shape[0], getattr(f, "name", "field"), status)

"""Explain failed particles: a breakdown by reason, the first failures, a hint from data (issue #12).

:func:`explain_failures` turns the per-particle status codes of a run (``Solution.status``,
``LogDet.status``, ``PoincareSection.status``) into a :class:`FailureReport`:

* the breakdown by reason with counts ("163 twist condition failed, 8 non-finite");
* the first few failed particles with the step at which they failed;
* a concrete hint computed from the failed steps themselves (when the method and the states
  where the steps failed are known): the largest step h/2^j at which every one of those steps
  succeeds with the same (bare) method, and the class whose twist condition holds — and whose
  step succeeds — at most of those states (:func:`vpforms.diagnostics.twist_map`); for a DL
  class (SE+DL, DL+DL) evaluated through the generic engine, the fraction of those steps that the
  nested θ-stage evaluation of the *same* map (``fast=True``, the default; the engine form is CLI ``--engine``) takes — near the fold
  ∂²H/∂p² = 0 the engine's discrete Lagrangian degenerates, the nested stages do not; and, for a
  method run with recovery off, that recovery would retry those steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._case import Case
from .._errors import RESULTS, VPFormsError
from .._methods._scheme import class_name
from .._solution import explains_failures
from .._spec import method_from_spec, method_spec
from .twist import _statuses, twist_map

__all__ = ["FailureReport", "explain_failures", "failure_breakdown"]

#: halvings of h tried for the "smaller step" hint (h/2 … h/2^k)
_HALVINGS = 6


def failure_breakdown(status: Any) -> dict[str, int]:
    """Failed particles per reason (``RESULTS.short`` names), most frequent first."""
    st = np.atleast_1d(np.asarray(status)).reshape(-1)
    codes = [int(c) for c in np.unique(st) if c != RESULTS.successful]
    unknown = [c for c in codes if c not in RESULTS.short]
    if unknown:
        raise ValueError(f"unknown status codes {unknown}; known: {sorted(RESULTS.short)}")
    counts = {RESULTS.short[c]: int(np.count_nonzero(st == c)) for c in codes}
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


@dataclass(frozen=True)
class FailureReport:
    """Why particles failed (see :func:`explain_failures`).

    ``by_reason`` failed particles per reason; ``first`` up to ``max_shown`` tuples
    (particle, step or −1 if unknown, reason); ``smaller_h`` the largest h/2^j (j ≤ 6) at which
    every failed step succeeds with the bare method (None if none does or not computed) and
    ``smaller_h_ok`` the fraction of failed steps that succeed at h/2^6 when none did;
    ``twist`` the :class:`~vpforms.diagnostics.TwistMap` at the failure states; ``fast_ok`` the
    fraction of the failed steps that the same DL method with ``fast=True`` takes (None where that
    does not apply); ``hint`` the text.
    """

    n_particles: int
    n_failed: int
    by_reason: dict
    first: tuple
    h: float | None = None
    smaller_h: float | None = None
    smaller_h_ok: float | None = None
    twist: Any = None
    recovery_off: bool = False
    fast_ok: float | None = None
    hint: str | None = None

    @property
    def breakdown(self) -> str:
        """'163 twist condition failed, 8 non-finite' (empty when nothing failed)."""
        return ", ".join(f"{n} {reason}" for reason, n in self.by_reason.items())

    def lines(self) -> list[str]:
        """Readable lines: the count and breakdown, the first failures, the hint."""
        if not self.n_failed:
            return [f"all {self.n_particles} particle(s) succeeded"]
        out = [f"{self.n_failed} of {self.n_particles} particle(s) failed and were frozen: {self.breakdown}"]
        shown = "; ".join(f"particle {p}" + (f" at step {s}" if s >= 0 else "") + f" ({r})"
                          for p, s, r in self.first)
        more = ", …" if self.n_failed > len(self.first) else ""
        out.append(f"first: {shown}{more}")
        if self.hint:
            out.append(f"hint: {self.hint}")
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %" if x >= 0.01 or x == 0 else f"{100 * x:.1f} %"


def _smaller_h(bare, pts: np.ndarray, h: float):
    """(largest h/2^j with every step from pts successful or None, success fraction at h/2^k)."""
    frac = 0.0
    for j in range(1, _HALVINGS + 1):
        hj = h / 2**j
        st = _statuses(bare, pts, hj)
        frac = float(np.mean(st == RESULTS.successful))
        if frac == 1.0:
            return hj, 1.0
    return None, frac


@explains_failures  # Solution.explain calls it (issue #40: registered from above, no cycle)
def explain_failures(
    status: Any,
    failed_step: Any = None,
    *,
    points: Any = None,
    method: Any = None,
    h: float | None = None,
    particles: Any = None,
    hint: bool = True,
    cli: bool = False,
    max_shown: int = 5,
    max_points: int = 64,
) -> FailureReport:
    """A :class:`FailureReport` for per-particle ``status`` codes (0 = never failed).

    Parameters
    ----------
    failed_step:
        Per-particle step n of the failure (−1 = none), as ``Solution.failed_step``; optional.
    points:
        Per-particle state at which the step failed (``Solution.x_final``: a failed particle is
        frozen there), shape (N, 3).  With ``method`` and ``h`` it makes the hint computed from
        data: the failing steps are retaken at h/2, h/4, … and :func:`twist_map` is evaluated at
        (up to ``max_points`` of) those states.  Without them the hint says only what applies.
    particles:
        The particle indices to report (default 0 … N−1), e.g. the original indices of a re-run.
    cli:
        Word the hint with the command-line options (``--h``, ``--method``, ``--no-recover``)
        instead of the Python API.
    """
    st = np.atleast_1d(np.asarray(status)).reshape(-1).astype(np.int64)
    N = st.size
    ids = np.arange(N) if particles is None else np.asarray(particles).reshape(-1)
    if ids.size != N:
        raise ValueError(f"particles has {ids.size} entries for {N} status codes")
    fs = None if failed_step is None else np.atleast_1d(np.asarray(failed_step)).reshape(-1)
    if fs is not None and fs.size != N:
        raise ValueError(f"failed_step has {fs.size} entries for {N} status codes")
    by_reason = failure_breakdown(st)
    bad = np.flatnonzero(st != RESULTS.successful)
    if fs is not None:  # the earliest failures first
        bad = bad[np.argsort(fs[bad], kind="stable")]
    first = tuple((int(ids[i]), int(fs[i]) if fs is not None else -1, RESULTS.short[int(st[i])])
                  for i in bad[:max_shown])
    rep = dict(n_particles=N, n_failed=int(bad.size), by_reason=by_reason, first=first,
               h=None if h is None else float(h))
    if not bad.size or not hint:
        return FailureReport(**rep)

    nonfinite = RESULTS.short[RESULTS.nonfinite]
    only_nonfinite = set(by_reason) == {nonfinite}
    strip = getattr(method, "without_recovery", None)
    bare = method if strip is None else strip()
    recovery_off = strip is not None and bare is method and getattr(method, "case", None) is not None
    smaller = smaller_ok = tm = fast_ok = None
    if method is not None and points is not None and h is not None:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if pts.shape[0] != N:
            raise ValueError(f"points has {pts.shape[0]} rows for {N} status codes")
        # the states where the steps failed (evenly spread over the failures, at most max_points)
        sel = bad if bad.size <= max_points else bad[np.linspace(0, bad.size - 1, max_points).astype(int)]
        fail_pts = pts[sel]
        fail_pts = fail_pts[np.all(np.isfinite(fail_pts), axis=1)]
        if fail_pts.shape[0]:
            smaller, smaller_ok = _smaller_h(bare, fail_pts, float(h))
            if not only_nonfinite:  # an overflow is not a twist failure: no twist map for it
                tm = _twist_at(method, fail_pts, float(h))
                fast_ok = _fast_ok(bare, fail_pts, float(h))
    text = _hint_text(method, bare, recovery_off, float(h) if h is not None else None, smaller, smaller_ok,
                      tm, cli, fast_ok)
    if nonfinite in by_reason:
        text = _overflow_hint(by_reason[nonfinite], only_nonfinite, float(h) if h is not None else None,
                              smaller, cli) + ("" if only_nonfinite else f"; for the other failures: {text}")
    return FailureReport(**rep, smaller_h=smaller, smaller_h_ok=smaller_ok, twist=tm,
                         recovery_off=recovery_off, fast_ok=fast_ok, hint=text)


def _with_fast(spec):
    """The spec with ``fast=True`` on every DL-class scheme evaluated by the generic engine, or None
    if there is none (or one is the printed variant, which has no nested stages)."""
    if not isinstance(spec, dict):
        return None
    if spec.get("kind") == "scheme":
        case, opts = spec["case"], dict(spec.get("options", {}))
        cls = class_name(case) if isinstance(case, str) else Case(*(tuple(c) for c in case)).cls
        # the stage form is the default (fast absent or True): only an explicit engine form counts
        if cls not in ("SE+DL", "DL+DL") or opts.get("fast", True) is not False or opts.get("printed"):
            return None
        return {**spec, "options": {**opts, "fast": True, "recover": False}}
    if "base" in spec:
        base = _with_fast(spec["base"])
        return None if base is None else {**spec, "base": base}
    return None


def _fast_ok(bare, pts, h):
    """Fraction of the failed steps that the nested θ-stage evaluation of the same map takes."""
    try:
        spec = _with_fast(method_spec(bare))
        if spec is None:
            return None
        _, st = method_from_spec(spec).step_with_status(pts, h)
    except (TypeError, ValueError, KeyError, VPFormsError):  # not a spec-able method: no such hint
        return None
    return float(np.mean(np.asarray(st) == RESULTS.successful))


def _twist_at(method, pts, h):
    """The class twist map at the failure states, or None where it does not apply (e.g. RK4)."""
    if getattr(method, "case", None) is None:  # not a generating-form method: no twist to compare
        return None
    try:
        return twist_map(method, pts, h=h, cases="classes")
    except (TypeError, ValueError, VPFormsError):
        return None


def _overflow_hint(n: int, only: bool, h, smaller, cli: bool) -> str:
    """The hint for non-finite failures (issue #22): the field overflowed or left its real domain."""
    who = "the failed steps" if only else f"the {n} non-finite failure(s)"
    text = (f"{who} produced a non-finite or complex value (NaN/inf): the field overflowed or left its "
            "real domain along these orbits (e.g. exp of a large argument, sqrt or log of a negative "
            "number) — not a twist failure; check the field where the particles went, shrink the "
            + ("--box or --x0" if cli else "box or the initial conditions") + ", or shorten the run")
    if only and h is not None and smaller is not None:
        text += (f"; here a smaller step avoids it: try {'--h' if cli else 'h ='} {smaller:g} (every "
                 "failed step succeeds at that step size)")
    return text


def _hint_text(method, bare, recovery_off, h, smaller, smaller_ok, tm, cli, fast_ok=None) -> str:
    parts = []
    if fast_ok:  # first: the same map, only evaluated without the degenerate discrete Lagrangian
        parts.append(("leaving out --engine" if cli else "the default fast=True") + " (the nested θ-stage evaluation of the same "
                     f"DL map, well conditioned at the fold ∂²H/∂p² = 0) takes {_pct(fast_ok)} of the "
                     "failed steps")
    if recovery_off:
        parts.append("drop --no-recover (recovery retries a failed step with other cases, other "
                     "classes and VP sub-steps)" if cli else
                     "build the method with recover=True (the default: a failed step is retried "
                     "with other cases, other classes and VP sub-steps)")
    if h is not None and smaller is not None:
        parts.append((f"try --h {smaller:g}" if cli else f"try h = {smaller:g}")
                     + " (every failed step succeeds at that step size)")
    elif h is not None and smaller_ok is not None:
        parts.append(("a smaller --h helps only partly" if cli else "a smaller h helps only partly")
                     + f" (at h = {h / 2**_HALVINGS:g} still only {_pct(smaller_ok)} of the failed "
                       "steps succeed: at the others this case's twist fails whatever the step)")
    elif h is not None:
        parts.append(f"try --h {h / 5:g}" if cli else f"try h = {h / 5:g}")
    if getattr(method, "case", None) is not None:
        parts.append("another case with --case (see 'vpforms cases')" if cli else
                     "another case: scheme(field, Case(sigma, Sigma))")
    if tm is not None:
        own_cls = getattr(method, "cls", None)
        best = tm.best(exclude=(own_cls,) if own_cls else ())
        if best is not None and best.step_ok > 0:
            how = f"--method {best.label}" if cli else f"scheme(field, {best.label!r})"
            parts.append(f"{best.label} ({how}), whose twist holds for this field at {_pct(best.twist)} "
                         f"of the {tm.n_points} sampled failure state(s) (its step succeeds at "
                         f"{_pct(best.step_ok)})")
    if not parts:
        return "the failures are non-finite values: check the field and the initial conditions"
    return ", ".join(parts[:-1]) + (", or " if len(parts) > 1 else "") + parts[-1]

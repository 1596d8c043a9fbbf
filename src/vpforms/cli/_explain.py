"""Explaining failed particles on the command line (issue #12): the breakdown by reason, the first
failures and a hint computed from the failed steps (:func:`vpforms.diagnostics.explain_failures`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from rich.markup import escape

from .._integrate import integrate
from .._recovery import bare_method
from ..diagnostics import explain_failures


def print_report(console, report) -> None:
    """Print a FailureReport: the counts in yellow, the first failures, the hint."""
    lines = report.lines()
    console.print(f"[yellow]{escape(lines[0])}", soft_wrap=True)
    for line in lines[1:]:
        console.print(escape(line), soft_wrap=True)


def explain_solution(console, sol, method: Any) -> None:
    """The report of a :class:`vpforms.Solution` (no output when nothing failed)."""
    if sol.n_failed:
        print_report(console, sol.explain(method, cli=True))


def recovered_text(sol, method: Any) -> str:
    """The summary's "recovered steps": how many steps failed bare and were recovered, in how many
    particles, and by which alternative (``Solution.recovered`` and ``stats["recovered_how"]``)."""
    if bare_method(method) is method:  # RK4, --no-recover: nothing is recovered
        return "off (bare method: a failed step freezes its particle)"
    rec = np.atleast_1d(np.asarray(sol.recovered if sol.recovered is not None else 0))
    total = int(rec.sum())
    if not total:
        return "0"
    n = int(np.count_nonzero(rec))
    how = sol.stats.get("recovered_how", {})
    by = ", ".join(f"{v} with {k}" for k, v in sorted(how.items(), key=lambda kv: -kv[1]))
    return f"{total} in {n} particle{'s' if n != 1 else ''}" + (f" ({by})" if by else "")


def explain_rerun(console, status, method: Any, x0, h: float, n_steps: int, what: str) -> None:
    """The report for a diagnostic that keeps only per-particle status codes (log_det, Poincaré).

    The failed particles are re-run alone with :func:`vpforms.integrate` (the same steps: a
    particle's trajectory does not depend on the others), which gives the step at which each
    failed and the state there for the hint.  Particles are reported by their original index.
    """
    st = np.atleast_1d(np.asarray(status))
    bad = np.flatnonzero(st != 0)
    if not bad.size:
        return
    sub = integrate(method, np.asarray(x0)[bad], h, n_steps, progress=False, backend="jax")
    full_fs = np.full(st.size, -1, np.int64)
    full_fs[bad] = np.atleast_1d(sub.failed_step)
    pts = np.zeros((st.size, 3))
    pts[bad] = np.atleast_1d(sub.x_final).reshape(-1, 3)
    # the re-run's own codes where it failed (it must: same steps), else the diagnostic's code
    codes = st.copy()
    re = np.atleast_1d(sub.status)
    codes[bad] = np.where(re != 0, re, st[bad])
    rep = explain_failures(codes, full_fs, points=pts, method=method, h=h, cli=True)
    console.print(f"{what}:", soft_wrap=True)
    print_report(console, rep)

"""Explaining failed particles on the command line (issue #12): the breakdown by reason, the first
failures and a hint computed from the failed steps (:func:`vpforms.diagnostics.explain_failures`)."""

from __future__ import annotations

from typing import Any

import numpy as np


def print_report(console, report) -> None:
    """Print a FailureReport: the counts in yellow, the first failures, the hint."""
    from rich.markup import escape

    lines = report.lines()
    console.print(f"[yellow]{escape(lines[0])}", soft_wrap=True)
    for line in lines[1:]:
        console.print(escape(line), soft_wrap=True)


def explain_solution(console, sol, method: Any) -> None:
    """The report of a :class:`vpforms.Solution` (no output when nothing failed)."""
    if sol.n_failed:
        print_report(console, sol.explain(method, cli=True))


def explain_rerun(console, status, method: Any, x0, h: float, n_steps: int, what: str) -> None:
    """The report for a diagnostic that keeps only per-particle status codes (log_det, Poincaré).

    The failed particles are re-run alone with :func:`vpforms.integrate` (the same steps: a
    particle's trajectory does not depend on the others), which gives the step at which each
    failed and the state there for the hint.  Particles are reported by their original index.
    """
    from .._integrate import integrate
    from ..diagnostics import explain_failures

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

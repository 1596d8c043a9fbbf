"""The result of a run: :class:`Solution`, built the same by every backend (:func:`make_solution`).

Split from ``_integrate.py`` (issue #19: imports flow one way) so that the backends, which build
Solutions, sit below :func:`vpforms.integrate`, which dispatches to them; ``vpforms.Solution`` and
``vpforms._integrate.Solution`` are this class.

:meth:`Solution.explain` is served from above (issue #40: no import cycle, lazy imports
included): :func:`vpforms.diagnostics.explain_failures` retakes the failed steps with the
methods, a layer above the backends that build Solutions, so it registers itself here
(:func:`explains_failures`) when its module is imported — which ``import vpforms`` always does.
``to_xarray``/``to_netcdf`` use :mod:`vpforms.io`, which sits below (it needs only
:func:`~vpforms._steps.saved_steps`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._errors import RESULTS, VPFormsError, raise_for_status
from ._steps import saved_steps
from .io import solution_to_netcdf, solution_to_xarray

__all__ = ["Solution", "describe", "explains_failures", "make_solution", "saved_steps"]

#: what :meth:`Solution.explain` calls: :func:`vpforms.diagnostics.explain_failures`, registered by
#: its module (a layer above this one) through :func:`explains_failures`
_explain_failures: Callable[..., Any] | None = None


def explains_failures(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Decorator: ``fn`` (``vpforms.diagnostics.explain_failures``) is what :meth:`Solution.explain`
    calls."""
    global _explain_failures
    _explain_failures = fn
    return fn


def describe(method: Any) -> str:
    """A one-line human description of a method: its ``description``, else name, case and order."""
    d = getattr(method, "description", None)
    if isinstance(d, str) and d:
        return d
    name = getattr(method, "name", None)
    if isinstance(name, str) and name:
        parts = [name]
        case = getattr(method, "case", None)
        if case is not None:
            parts.append(f"case {case}")
        cls = getattr(method, "cls", None)
        if isinstance(cls, str) and cls not in name:
            parts.append(f"class {cls}")
        order = getattr(method, "order", None)
        if order is not None:
            parts.append(f"order {order}")
        return ", ".join(parts)
    return repr(method)


@dataclass(frozen=True)
class Solution:
    """The result of :func:`integrate` (NumPy arrays on the host).

    :meth:`summary` and :meth:`explain` give the failures by reason ("163 twist condition failed,
    8 non-finite"), the first failed particles with their steps, and a hint computed from the
    failed steps (:func:`vpforms.diagnostics.explain_failures`).

    Attributes
    ----------
    ts:
        Saved times, shape (S,): ``t0 + h * steps``.
    steps:
        Saved step indices, shape (S,): 0, k, 2k, …, and always ``n_steps`` last (k = save_every).
    xs:
        Saved states, shape (S, 3) for a single x0 of shape (3,), else (N, S, 3).
    status:
        Per-particle ``RESULTS`` code of the first failure (0 = every step succeeded); shape () or (N,).
    failed_step:
        Index n of the step t_n → t_{n+1} at which the particle failed, −1 if it never failed.  A
        failed particle stays frozen at its state at step n.
    method:
        The method's description.
    h, n_steps, save_every, t0:
        The run's parameters.
    stats:
        ``wall_s`` (excluding nothing: compile included), ``n_chunks``, ``chunk_size``,
        ``ns_per_particle_step``, ``recovered_how`` (recovered steps by alternative, issue #12).
    recovered:
        Per-particle number of steps that failed bare and were recovered (issue #12).
    method_object:
        The method that ran (not saved): :meth:`explain` uses it for its hint.

    """

    ts: np.ndarray
    steps: np.ndarray
    xs: np.ndarray
    status: np.ndarray
    failed_step: np.ndarray
    method: str
    h: float
    n_steps: int
    save_every: int | None
    t0: float = 0.0
    stats: dict = field(default_factory=dict)
    #: per-particle number of steps that failed bare and were recovered (issue #12)
    recovered: np.ndarray | None = None
    #: the method object that ran (for :meth:`explain`'s hint); not saved, not compared
    method_object: Any = field(default=None, repr=False, compare=False)

    @property
    def x_final(self) -> np.ndarray:
        """The final state(s): shape (3,) or (N, 3)."""
        return self.xs[..., -1, :]

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.status != RESULTS.successful))

    @property
    def ok(self) -> bool:
        return self.n_failed == 0

    def raise_for_status(self) -> None:
        """Raise the named :class:`vpforms.VPFormsError` if any particle failed."""
        raise_for_status(self.status, what=f"integrate({self.method})")

    def explain(self, method: Any = None, hint: bool = True, cli: bool = False, max_shown: int = 5):
        """Why particles failed: a :class:`vpforms.diagnostics.FailureReport` (issue #12).

        The breakdown by reason with counts, the first failed particles and their steps, and —
        with the method (default: the one :func:`integrate` ran, :attr:`method_object`) — a hint
        computed from the failed steps: the states where they failed are the frozen states, so
        the steps are retaken there at smaller h and :func:`vpforms.diagnostics.twist_map` says
        which class's twist condition holds there.
        """
        if _explain_failures is None:  # only while vpforms itself is being imported
            raise VPFormsError("Solution.explain needs vpforms.diagnostics: import vpforms first")
        m = self.method_object if method is None else method
        cache = self.__dict__.setdefault("_explained", {})  # summary() then explain(): computed once
        key = (id(m), bool(hint), bool(cli), int(max_shown))
        if key not in cache or cache[key][0] is not m:
            cache[key] = (m, _explain_failures(self.status, self.failed_step, points=self.x_final, method=m,
                                              h=self.h, hint=hint, cli=cli, max_shown=max_shown))
        return cache[key][1]

    def summary(self, hint: bool = True) -> dict[str, Any]:
        """A flat dictionary for printing: counts, times, failures by reason (and a hint, see
        :meth:`explain`; ``hint=False`` skips its computation)."""
        st = np.atleast_1d(self.status)
        fails = {
            RESULTS.messages[int(c)]: int(np.count_nonzero(st == c))
            for c in np.unique(st)
            if c != RESULTS.successful
        }
        out = {
            "method": self.method,
            "particles": int(st.size),
            "h": self.h,
            "steps": self.n_steps,
            "t_final": float(self.ts[-1]),
            "saved states": int(self.ts.size),
            "failed particles": int(np.count_nonzero(st != RESULTS.successful)),
        }
        if fails:
            rep = self.explain(hint=hint)
            out["failures"] = fails
            out["failure breakdown"] = rep.breakdown
            out["first failed"] = list(rep.first)
            if rep.hint:
                out["hint"] = rep.hint
        if self.recovered is not None:
            out["recovered steps"] = int(np.sum(self.recovered))
        return {**out, **self.stats}

    def save(self, path: str) -> str:
        """Write an ``.npz`` with ts, steps, xs, status, failed_step, recovered, recovered_how and the
        run parameters; returns the name of the file written (NumPy appends ``.npz`` to a name
        without it: ``run.txt`` → ``run.txt.npz``).

        ``recovered`` is :attr:`recovered` (steps per particle that failed bare and were recovered;
        absent when the run did not count them) and ``recovered_how`` a JSON object (a 0-d string
        array) of the recovered steps by alternative, ``stats["recovered_how"]`` (``{}`` = none).
        """
        if isinstance(path, (str, os.PathLike)):
            path = os.fspath(path)
            if not path.endswith(".npz"):
                path += ".npz"
        rec = {} if self.recovered is None else {"recovered": np.asarray(self.recovered)}
        np.savez_compressed(
            path,
            **rec,
            recovered_how=np.array(json.dumps(self.stats.get("recovered_how", {}), ensure_ascii=False)),
            ts=self.ts,
            steps=self.steps,
            xs=self.xs,
            status=self.status,
            failed_step=self.failed_step,
            method=np.array(self.method),
            h=np.array(self.h),
            n_steps=np.array(self.n_steps),
            save_every=np.array(-1 if self.save_every is None else self.save_every),
            t0=np.array(self.t0),
        )
        return path

    def to_xarray(self, method: Any = None):
        """This solution as an ``xarray.Dataset`` (:mod:`vpforms.io`; ``method`` adds its spec)."""
        return solution_to_xarray(self, method)

    def to_netcdf(self, path: str, method: Any = None) -> None:
        """Write :meth:`to_xarray` to a netCDF file (:mod:`vpforms.io`)."""
        solution_to_netcdf(self, path, method)


def make_solution(method, single, h, n_steps, save_every, t0, steps, xs, status, failed, recovered,
                  stats: dict, how: dict) -> Solution:
    """The :class:`Solution` of a finished run, the same from every backend: ``stats`` (wall time,
    chunking, backend) gains the throughput and the recovery breakdown; a single point is unbatched."""
    N = xs.shape[0]
    stats = {**stats, "ns_per_particle_step": (1e9 * stats["wall_s"] / (N * n_steps)) if N * n_steps
             else float("nan"), **({"recovered_how": how} if how else {})}
    ts = t0 + h * steps.astype(np.float64)
    if single:
        return Solution(ts, steps, xs[0], status[0], failed[0], describe(method), h, n_steps, save_every, t0, stats,
                        int(recovered[0]), method)
    return Solution(ts, steps, xs, status, failed, describe(method), h, n_steps, save_every, t0, stats, recovered,
                    method)

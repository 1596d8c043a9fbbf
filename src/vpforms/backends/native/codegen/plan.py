"""One step of a method as generated stages: ``plan(method) -> [(stage, coefficient of h)]``.

The stages are applied left to right, stage k at step ``coefficient·h``; a failing stage's status
is the step's (the first failure wins, as ``merge_status``). The method tree that
:func:`vpforms.scheme` / :func:`vpforms.compose` build maps to stages by:

* a class representative (SE+SE, linear S1/S2): its generating map; nonlinear S1/S2: Quispel's
  correction map (:func:`.potentials.class_stage`);
* :class:`~vpforms._methods._base.Relabelled` (π, π)·Ψ (prop:trivperm): each stage of Ψ relabelled
  (conjugation by π commutes with composition);
* :class:`~vpforms._methods._base.Adjoint` Ψ*_h = (Ψ_{−h})⁻¹ (prop:switchperm): the adjoint of each
  stage, in reverse order, same coefficients;
* ``SymmetricPair`` Ψ*_{h/2}∘Ψ_{h/2}, ``Composition`` S_{γ_s h}∘…∘S_{γ_1 h},
  ``AdjointComposition`` Ψ*_{α_s h}∘Ψ_{β_s h}∘…∘Ψ_{β_1 h}: concatenation;
* recovering methods: their bare method (the runner recovers failed steps through JAX);
* :class:`vpforms.RK4`: one explicit stage (no adjoint).
"""

from __future__ import annotations

from typing import Any

from ...._methods._base import Adjoint, Method, Relabelled
from ...._methods._compose import AdjointComposition, Composition, SymmetricPair
from ...._methods.rk4 import RK4
from .potentials import RK4Stage, class_stage, field_reason
from .splines import domain_reason

__all__ = ["plan", "unsupported_reason"]


def _bare(method: Any) -> Any:
    return getattr(method, "without_recovery", lambda: method)()


def plan(method: Any) -> list[tuple[Any, float]] | str:
    """The stages of one step of ``method``, or the reason it cannot be generated."""
    m = _bare(method)
    if isinstance(m, Composition):
        inner = plan(m.base)
        return inner if isinstance(inner, str) else [(s, c * g) for g in m.gammas for s, c in inner]
    if isinstance(m, (SymmetricPair, AdjointComposition)):
        fwd, adj = plan(m.base), plan(m.adj)
        for p in (fwd, adj):
            if isinstance(p, str):
                return p
        pairs = [(0.5, 0.5)] if isinstance(m, SymmetricPair) else zip(m.betas, m.alphas)
        return [(s, g * c) for b, a in pairs for g, p in ((b, fwd), (a, adj)) for s, c in p]
    if isinstance(m, Adjoint):
        inner = plan(m.base)
        if isinstance(inner, str):
            return inner
        if any(isinstance(s, RK4Stage) for s, _ in inner):
            return f"the adjoint of {getattr(m.base, 'name', m.base)} is implicit and not generated"
        return [(s.adjoint(), c) for s, c in reversed(inner)]
    if isinstance(m, Relabelled):
        inner = plan(m.base)
        if isinstance(inner, str):
            return inner
        if any(isinstance(s, RK4Stage) for s, _ in inner):
            return "RK4 is not relabelled natively"
        return [(s.relabel(m.pi), c) for s, c in inner]
    if isinstance(m, RK4):
        why = field_reason(m.field)
        return why if why else [(RK4Stage(m.field), 1.0)]
    st = class_stage(m)
    return st if isinstance(st, str) else [(st, 1.0)]


def unsupported_reason(method: Any) -> str | None:
    """None if :func:`.emit.kernel_source` can generate ``method``, else the reason it cannot."""
    p = plan(method)
    if isinstance(p, str):
        return p
    # the statuses of a step (Method._accept) test the top-level field's domain; RK4 has none
    return domain_reason(method.field) if isinstance(method, Method) else None

"""One step of a method as generated stages: ``plan(method) -> [(stage, coefficient of h)]``.

The stages are applied left to right, stage k at step ``coefficient·h``; a failing stage's status
is the step's (the first failure wins, as ``merge_status``). The plan is a fold over the method's
stage list (``method.stages``, :mod:`vpforms._methods._stages`: compositions already concatenated,
adjoints reversed), each stage in its normal form ((π, π)·recipe, adjoined or not):

* the recipe: a class representative (SE+SE, linear S1/S2) → its generating map; nonlinear S1/S2
  → Quispel's correction map; the DL classes → their nested θ-stages
  (:func:`.potentials.class_stage`); :class:`vpforms.RK4` → one explicit stage (no adjoint, not
  relabelled);
* π (prop:trivperm): the generated stage relabelled (``.relabel(π)``);
* adjoint (prop:switchperm): the generated stage's adjoint (``.adjoint()``).

A recovering method is generated as its bare method (the runner recovers failed steps through
JAX).
"""

from __future__ import annotations

from typing import Any

from ...._methods._base import Method, Stage
from ...._methods.rk4 import RK4
from .potentials import RK4Stage, class_stage, field_reason
from .splines import domain_reason

__all__ = ["plan", "unsupported_reason"]


def _bare(method: Any) -> Any:
    return getattr(method, "without_recovery", lambda: method)()


def _recipe_stage(recipe: Any):
    if isinstance(recipe, RK4):
        why = field_reason(recipe.field)
        return why if why else RK4Stage(recipe.field)
    return class_stage(recipe)


def plan(method: Any) -> list[tuple[Any, float]] | str:
    """The stages of one step of ``method``, or the reason it cannot be generated."""
    out = []
    m = _bare(method)
    made: dict = {}  # one generated stage per distinct normal form (Ψ and Ψ* repeat in a composition)
    # a user's method (not a vpforms Method) is one stage of itself: class_stage says why it is not generated
    for st in getattr(m, "stages", None) or (Stage(m, 1.0, m),):
        key = (id(st.recipe), st.pi, st.adjoint)
        if key not in made:
            made[key] = _generated(st)
        gen = made[key]
        if isinstance(gen, str):
            return gen
        out.append((gen, st.coefficient))
    return out


def _generated(st: Stage):
    """The generated stage of ``st``'s normal form, ((π, π)·recipe)^(*adjoint), or why not."""
    gen = _recipe_stage(st.recipe)
    if isinstance(gen, str):
        return gen
    if isinstance(gen, RK4Stage) and (st.adjoint or not st.pi.is_identity):
        return ("the adjoint of RK4 is implicit and not generated" if st.adjoint
                else "RK4 is not relabelled natively")
    if not st.pi.is_identity:
        gen = gen.relabel(st.pi)
    return gen.adjoint() if st.adjoint else gen


def unsupported_reason(method: Any) -> str | None:
    """None if :func:`.emit.kernel_source` can generate ``method``, else the reason it cannot."""
    p = plan(method)
    if isinstance(p, str):
        return p
    # the statuses of a step (Method._accept) test the top-level field's domain; RK4 has none
    return domain_reason(method.field) if isinstance(method, Method) else None

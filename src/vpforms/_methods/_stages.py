"""Stages as data (issue #19, item 1): a method's step is a list of order-1 stages.

Every method has ``stages``: the tuple of :class:`Stage` (map, coefficient) that its step applies
left to right, stage k at ``coefficient·h``.  A bare method is one stage of itself at 1.  The
operations of the paper act on the list, and every consumer folds over it:

* a composition concatenates its methods' lists, each coefficient times its own (HLW II.4, V.3);
* the adjoint Ψ*_h = (Ψ_{−h})⁻¹ (prop:switchperm) reverses the list and adjoins each stage, same
  coefficients, since (Ψ_b∘Ψ_a)* = Ψ_a*∘Ψ_b*;
* the relabelling (π, π)·Ψ (prop:trivperm) relabels each stage: conjugation by π commutes with
  composition.

:class:`Composition` is the one composition type: :func:`vpforms.compose` builds the symmetric
pair Ψ*_{h/2}∘Ψ_{h/2}, the symmetric compositions of it and the compositions of Ψ with its adjoint
as lists of this kind.  The JAX step (here), the host-side recovery (:mod:`vpforms._recovery`) and
the native plan (:mod:`vpforms.backends.native.codegen.plan`) fold over ``stages``; each stage
also carries its normal form (class recipe, relabelling π, adjoint or not), which is what the
native backend generates.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np
from jax import lax

from ._base import Method, Stage, memo_relabel, merge_status

__all__ = ["Composition", "Stage"]


def _cycle(atoms: tuple) -> int:
    """The shortest period p of the stage maps (by identity): atoms[i] is atoms[i mod p]."""
    s = len(atoms)
    for p in range(1, s + 1):
        if s % p == 0 and all(atoms[i] is atoms[i % p] for i in range(s)):
            return p
    return s  # pragma: no cover


class Composition(Method):
    """Ψ_{c_s h}∘…∘Ψ_{c_1 h}: the stage list ``stages`` ((Ψ₁, c₁) first) as one method.

    Built from (method, coefficient) pairs in the order they act; a method that is itself a
    composition contributes its own stages, scaled.  The traits are given by the builder
    (:func:`vpforms.compose` knows the order of its coefficients and whether they are symmetric).

    Evaluation: the stage maps repeat with a period p (2 for Ψ, Ψ* in alternation), so the step is
    a ``lax.scan`` of the p maps over the rows of coefficients — one compiled copy of each map,
    whatever the number of stages (unrolled in the per-point kernel, rolled on batches).
    """

    def __init__(self, parts, order: int, symmetric: bool, name: str, field: Any = None,
                 case: Any = None):
        flat: list[Stage] = []
        for m, c in parts:
            flat.extend(s.scaled(float(c)) for s in m.stages)
        if not flat:
            raise ValueError("a composition needs at least one stage")
        self._stages = tuple(flat)
        first = flat[0].method  # the case of a composition is that of the method composed
        self.case = case if case is not None else first.case
        self.field = field if field is not None else first.field
        self.order, self.symmetric, self.name = int(order), bool(symmetric), name
        atoms = tuple(s.method for s in flat)
        p = _cycle(atoms)
        self._atoms = atoms[:p]
        self._rows = np.asarray([s.coefficient for s in flat], float).reshape(-1, p)

    @property
    def stages(self) -> tuple[Stage, ...]:
        return self._stages

    @property
    def coefficients(self) -> tuple[float, ...]:
        """The coefficient of h of each stage, in the order they act."""
        return tuple(s.coefficient for s in self._stages)

    def _submethods(self) -> tuple:
        return tuple({id(m): m for m in self._atoms}.values())

    def _rebuilt(self, fn, reverse: bool = False, name: str | None = None, field: Any = None,
                 case: Any = None):
        """The composition of fn(map) at the same coefficients (fn once per distinct map, so that
        the period, and the compiled maps, are shared)."""
        memo: dict[int, Any] = {}
        for m in self._atoms:
            memo[id(m)] = fn(m)
        stages = reversed(self._stages) if reverse else self._stages
        parts = [(memo[id(s.method)], s.coefficient) for s in stages]
        return Composition(parts, self.order, self.symmetric, name or self.name, field,
                           case if case is not None else self.case)

    def adjoint(self) -> Method:
        """(Ψ_{c_s h}∘…∘Ψ_{c_1 h})* = Ψ*_{c_1 h}∘…∘Ψ*_{c_s h} (prop:switchperm, stage by stage)."""
        memo = self.__dict__.get("_adjoint")
        if memo is None:  # the same object on every call, and (Ψ*)* is Ψ itself
            memo = self._rebuilt(lambda m: m.adjoint(), reverse=True, name=self.name + "*",
                                 case=self.case.switched())
            memo.adjoint_of = self  # its spec is {"kind": "adjoint", "base": self.spec()}
            memo.__dict__["_adjoint"] = self
            self.__dict__["_adjoint"] = memo
        return memo

    def relabel(self, pi) -> Method:
        """(π, π)·composition = the composition of the relabelled stages (prop:trivperm)."""
        return memo_relabel(self, pi, lambda pi: self._rebuilt(lambda m: m.relabel(pi),
                                                               case=self.case.relabel(pi)))

    def _strip_recovery(self) -> Method:
        bare = self._rebuilt(lambda m: m.without_recovery())
        return self if all(a is b for a, b in zip(bare._atoms, self._atoms)) else bare

    # -- evaluation: a scan of the period's maps over the rows of coefficients -------------------
    def _fold(self, kernel, x, h, zeros, merge, backward: bool, rolled: bool):
        """kernel(map, x, c·h) -> (X, status, iterations[, recovered]) folded over the stages:
        the first failure's status, the iterations summed, the largest recovery code."""
        atoms, rows = self._atoms, self._rows
        if backward:  # (Ψ_s∘…∘Ψ₁)⁻¹ = Ψ₁⁻¹∘…∘Ψ_s⁻¹
            atoms, rows = atoms[::-1], rows[::-1, ::-1]

        def apply(carry, row):
            for a, c in zip(atoms, row):
                out = kernel(a, carry[0], c * h)
                carry = ((out[0], merge(carry[1], out[1]), carry[2] + out[2])
                         + tuple(jnp.maximum(r, q) for r, q in zip(carry[3:], out[3:])))
            return carry

        init = (x, *zeros)
        if rows.shape[0] == 1:  # one period: plain Python, constant coefficients
            return apply(init, tuple(float(c) for c in rows[0]))
        out, _ = lax.scan(lambda c, r: (apply(c, r), None), init, jnp.asarray(rows),
                          unroll=not rolled)
        return out

    def _forward(self, x, h):
        z = jnp.int32(0)
        return self._fold(lambda m, p, h: m._forward(p, h), x, h, (z, z), merge_status,
                          backward=False, rolled=False)

    def _backward(self, X, h):
        z = jnp.int32(0)
        return self._fold(lambda m, p, h: m._backward(p, h), X, h, (z, z), merge_status,
                          backward=True, rolled=False)

    def _batched_step(self, x, h):  # stage by stage: each stage decides its own recovery
        z = jnp.zeros(x.shape[0], jnp.int32)
        return self._fold(lambda m, p, h: m._batched_step(p, h), x, h, (z, z, z), _merge,
                          backward=False, rolled=True)


def _merge(a, b):
    return jnp.where(a == 0, b, a).astype(jnp.int32)

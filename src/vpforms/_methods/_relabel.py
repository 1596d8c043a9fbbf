"""The relabelled field (π⁻¹, π⁻¹)·a of prop:trivperm, built by the Field machinery.

ã(x) = a(x·π⁻¹)·π, i.e. ã_i(x) = a_{π(i)}(x·π⁻¹). Its SE/DL potentials are *not* in general a
permutation of those of a (vf_k(F) relabels to sgn π · vf_{π⁻¹(k)}(F∘π⁻¹), a different splitting
when π moves the index pair), so ã is constructed as a Field of its own: linear → Field.linear
(Ã_ij = A_{π(i)π(j)}), SymPy → Field.from_sympy (closed-form potentials), callable →
Field.from_callable (quadrature potentials). Results are cached per (field, π).

Where the user supplied potentials (a pair or a vector potential A), the relabelled field derives
its pairs from them — Ã(x) = sgn π · A(x·π⁻¹)·π, then the gauge of its splitting
(:mod:`vpforms._potentials`) — and never from its own components (issue #23): the field's own
closed forms may be singular where the user's potentials are not.
"""

from __future__ import annotations

import functools
import weakref

import jax.numpy as jnp
import numpy as np

from .._perm import Perm, as_perm
from .._potentials import relabel_vector_potential
from .._vecpot import VectorPotential
from ..fields import Field

__all__ = ["relabelled_field"]

_CACHE: "weakref.WeakKeyDictionary[object, dict]" = weakref.WeakKeyDictionary()


def relabelled_field(field, pi: Perm | tuple) -> Field:
    """(π⁻¹, π⁻¹)·a: the field the class representative is run on to build case (π∘σ, π∘Σ)."""
    pi = as_perm(pi)
    if pi.is_identity:
        return field
    per = _CACHE.setdefault(field, {})
    if pi not in per:
        per[pi] = _build(field, pi)
    return per[pi]


def _build(field, pi: Perm) -> Field:
    idx, inv = list(pi.index), list(pi.inverse().index)
    name = f"{field.name}·{pi.one_line()}"
    box = tuple(field.box[k] for k in idx)  # x_k ranges over box_{π(k)}
    origin = tuple(field.origin[k] for k in idx)
    A = getattr(field, "linear_matrix", None)
    if A is not None:
        At = np.asarray(A, float)[np.ix_(idx, idx)]  # Ã_ij = A_{π(i) π(j)}
        return Field.linear(At, name=name, box=box)
    if field.exprs is not None:
        s = field.symbols
        sub = {s[j]: s[inv[j]] for j in range(3)}  # y_j → (x·π⁻¹)_j = x_{π⁻¹(j)}
        exprs = tuple(field.exprs[k].xreplace(sub) for k in idx)
        out = Field.from_sympy(
            exprs, s, name=name, box=box, origin=origin,
            quadrature_n=field.quadrature_n, closed_form=field.closed_form, _relabelled_from=field,
        )
        out._vector_potentials = [
            relabel_vector_potential(A, pi, s)
            if not isinstance(A, VectorPotential) and not any(callable(c) for c in A)
            else _relabel_callables(A, pi) for A in field._vector_potentials]
        return out
    comps = field.components

    def a_tilde(x):
        y = x[jnp.asarray(inv)]
        return jnp.stack([jnp.asarray(comps[k](y[0], y[1], y[2]), float) for k in idx])

    sampler = None
    if getattr(field, "sampler", None) is not None or field.domain is not None:  # where a samples, as x = y·π
        sampler = functools.partial(_permuted_samples, field, tuple(idx))  # picklable (Dask ships methods)

    out = Field.from_callable(
        a_tilde, box=box, name=name, origin=origin, quadrature_n=field.quadrature_n, sampler=sampler
    )
    out._vector_potentials = [_relabel_callables(A, pi) for A in field._vector_potentials]
    out.periods = tuple(getattr(field, "periods", (None,) * 3)[k] for k in idx)
    check = getattr(field, "domain_check", None)
    if check is not None:  # a point x of ã is the point x·π⁻¹ of a
        out.domain_check = lambda pts: check(np.asarray(pts, float)[..., inv])
    inside = getattr(field, "inside", None)
    if inside is not None:
        out.inside = lambda x: inside(x[jnp.asarray(inv)])
    return out


def _permuted_samples(field, idx: tuple, n: int, seed: int) -> np.ndarray:
    """The sample points of ``field`` with their coordinates permuted (a relabelled field's sampler)."""
    return np.asarray(field.sample_points(n, seed), float)[..., list(idx)]


def _relabel_callables(A, pi: Perm) -> tuple:
    """:func:`~vpforms._potentials.relabel_vector_potential` for scalar callables (0 stays 0), or
    a :class:`~vpforms._vecpot.VectorPotential` relabelled by its own rule (exact stays exact)."""
    if isinstance(A, VectorPotential):
        return A.relabel(pi)
    idx, inv, sgn = list(pi.index), list(pi.inverse().index), float(pi.sign)

    def comp(k):
        c = A[k]
        if not callable(c):
            return 0

        def Ak(x1, x2, x3):
            x = (x1, x2, x3)
            return sgn * c(x[inv[0]], x[inv[1]], x[inv[2]])

        return Ak

    return tuple(comp(k) for k in idx)

"""The relabelled field (π⁻¹, π⁻¹)·a of prop:trivperm, built by the Field machinery.

ã(x) = a(x·π⁻¹)·π, i.e. ã_i(x) = a_{π(i)}(x·π⁻¹). Its SE/DL potentials are *not* in general a
permutation of those of a (vf_k(F) relabels to sgn π · vf_{π⁻¹(k)}(F∘π⁻¹), a different splitting
when π moves the index pair), so ã is constructed as a Field of its own: linear → Field.linear
(Ã_ij = A_{π(i)π(j)}), SymPy → Field.from_sympy (closed-form potentials), callable →
Field.from_callable (quadrature potentials). Results are cached per (field, π).
"""

from __future__ import annotations

import weakref

import jax.numpy as jnp
import numpy as np

from .._perm import Perm, as_perm
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
        return Field.from_sympy(
            exprs, s, name=name, box=box, origin=origin,
            quadrature_n=field.quadrature_n, closed_form=field.closed_form,
        )
    comps = field.components

    def a_tilde(x):
        y = x[jnp.asarray(inv)]
        return jnp.stack([jnp.asarray(comps[k](y[0], y[1], y[2]), float) for k in idx])

    return Field.from_callable(
        a_tilde, box=box, name=name, origin=origin, quadrature_n=field.quadrature_n
    )

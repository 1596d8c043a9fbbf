"""The :class:`Problem` record shared by every test problem."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numbers

import numpy as np
import sympy as sp

from .._parse import parse_number
from ..fields import SYMBOLS, Field, _lambdify_scalar, uniform_in_box

__all__ = ["Problem", "invariant_callables", "box_sampler", "real_param"]


@dataclass(frozen=True, eq=False)
class Problem:
    """A divergence-free test problem x' = a(x).

    Attributes
    ----------
    name:
        registry name (``vpforms.problems.get(name)``).
    field:
        the :class:`~vpforms.fields.Field`.
    params:
        the parameter values used (name → float).
    x0:
        default initial conditions, shape (N, 3).
    invariants:
        name → JAX scalar callable of a point x of shape (3,) (vmap it for batches).
    invariant_exprs:
        name → SymPy expression in :data:`vpforms.fields.SYMBOLS`.
    source:
        citation string.
    periodic:
        periods per axis (None for a non-periodic axis), or None if nothing is periodic.
    box:
        a sensible bounding box ((lo, hi),)*3 for sampling and plots.
    description:
        one line.
    wall:
        the physical domain, an (R, Z) polygon (:class:`vpforms.fieldlines.Wall`), or None.
    domain:
        the default domain that follows the plasma (:class:`vpforms.domains.ToroidalDomain`), or None.
    """

    name: str
    field: Field
    params: Mapping[str, Any]
    x0: np.ndarray
    invariants: Mapping[str, Callable[[Any], Any]]
    invariant_exprs: Mapping[str, Any]
    source: str
    periodic: tuple | None
    box: tuple
    description: str = ""
    sampler: Callable[[np.random.Generator, int], np.ndarray] | None = field(
        default=None, repr=False
    )
    #: for toroidal fields: a guess (R, Z) of the magnetic axis on φ = 0 (field-line studies, #21)
    axis_guess: tuple | None = None
    #: the physical domain as an (R, Z) polygon about the x₃ axis (:class:`vpforms.fieldlines.Wall`),
    #: where the problem has one: ``trace_to_wall(method, x0, h, n, problem.wall)`` stops the lines
    #: that leave it with status ``left_domain`` (#21 item 4); None where there is none
    wall: Any = None
    #: for toroidal fields whose plasma is not a surface of revolution (the real stellarators,
    #: :mod:`vpforms.problems.devices`): the default domain, a :class:`vpforms.domains.ToroidalDomain`
    #: (``trace_to_wall(method, x0, h, n, problem.domain)``); None where there is none
    domain: Any = None

    def initial_conditions(self, n: int, seed: int = 0) -> np.ndarray:
        """n seeded initial conditions in the problem's natural region, shape (n, 3)."""
        if not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"n must be a non-negative integer; got {n!r}")
        rng = np.random.default_rng(seed)
        sampler = self.sampler if self.sampler is not None else box_sampler(self.box)
        return np.asarray(sampler(rng, int(n)), dtype=float).reshape(int(n), 3)

    def invariant_values(self, x: Any) -> dict[str, jax.Array]:
        """Every invariant at x of shape (3,) or (N, 3)."""
        x = jnp.asarray(x, dtype=float)
        out = {}
        for k, f in self.invariants.items():
            out[k] = f(x) if x.ndim == 1 else jax.vmap(f)(x.reshape(-1, 3)).reshape(x.shape[:-1])
        return out


def invariant_callables(exprs: Mapping[str, Any], symbols=SYMBOLS) -> dict[str, Callable]:
    """SymPy invariants → JAX callables of a point x of shape (3,)."""
    out = {}
    for k, e in exprs.items():
        g = _lambdify_scalar(e, symbols)

        def inv(x, _g=g):
            x = jnp.asarray(x, dtype=float)
            return _g(x[0], x[1], x[2])

        inv.__name__ = k
        out[k] = inv
    return out


def box_sampler(box) -> Callable[[np.random.Generator, int], np.ndarray]:
    """A sampler (rng, n) -> (n, 3) uniform in the box (:func:`vpforms.fields.uniform_in_box`)."""
    return lambda rng, n: uniform_in_box(box, rng, n)


def real_param(name: str, value: Any):
    """A problem parameter as a SymPy number: numbers as they are, text through the safe reader
    :func:`vpforms._parse.parse_number` (never ``sympify``/eval of text); anything else is a
    TypeError naming the parameter (found by tests/test_fuzz.py: a list gave AttributeError)."""
    if isinstance(value, str):
        return parse_number(value, what=f"parameter {name}")
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, sp.Basic)):
        raise TypeError(f"parameter {name} must be a real number, not {type(value).__name__} {value!r}")
    v = sp.sympify(value)
    if not isinstance(v, sp.Expr):
        raise TypeError(f"parameter {name} must be a real number, not {v!r}")
    return v

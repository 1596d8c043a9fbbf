"""The baseline every comparison uses: classical explicit RK4 (not volume preserving).

Moved here from ``_integrate.py`` (issue #19: imports flow one way); ``vpforms.RK4`` and
``vpforms._integrate.RK4`` are this class.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from .._errors import RESULTS
from .._guard import rk4_step
from .._spec_record import method_spec
from ._base import Stage

__all__ = ["RK4"]


class RK4:
    """Classical fourth-order Runge–Kutta for x' = a(x): the usual baseline (not volume preserving).

    ``field`` is any callable x (3,) -> a(x) (3,) in JAX, e.g. a :class:`vpforms.Field`.  It has the
    method interface that :func:`vpforms.integrate` and the diagnostics need: ``step``,
    ``step_with_status`` (status is ``nonfinite`` when the result is not finite), ``order = 4``.
    """

    order = 4
    symmetric = False
    #: ``step_with_status`` takes a batch (N, 3) (vpforms._recovery)
    takes_batches = True

    def __init__(self, field: Callable[[jax.Array], jax.Array]):
        self.field = field
        self.description = f"RK4 (classical, explicit) on {getattr(field, 'name', 'field')}"
        self._spec_record = ("rk4", (field,), {})  # its construction record (vpforms._spec_record)

    @property
    def stages(self) -> tuple:
        """One explicit stage, itself (stages as data, :class:`~vpforms._methods._base.Stage`)."""
        return (Stage(self, 1.0, self),)

    def step(self, x: Any, h: Any) -> jax.Array:
        a = self.field
        x = jnp.asarray(x, dtype=jnp.result_type(float))
        if x.ndim == 2:
            return jax.vmap(lambda p: self.step(p, h))(x)
        return rk4_step(a, x, h)

    def step_with_status(self, x: Any, h: Any):
        X = self.step(x, h)
        bad = ~jnp.all(jnp.isfinite(X), axis=-1)
        return X, jnp.where(bad, RESULTS.nonfinite, RESULTS.successful).astype(jnp.int32)

    def spec(self) -> dict:
        """The JSON-able spec that rebuilds this RK4 (:func:`vpforms.method_from_spec`)."""
        return method_spec(self)

    def __repr__(self) -> str:
        return f"RK4({getattr(self.field, 'name', self.field)!s})"

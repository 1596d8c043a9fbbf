"""Section surfaces: the planes x_axis = value (+ k·period) and the toroidal half-planes φ = φ₀ (+ k·2π/nfp).

A surface is a small hashable object (a static argument of the jitted kernels) with two pure
functions of points of shape (3,):

* ``crossing(x, X) -> (up, down, level)``: whether the step x → X crosses a level of the surface
  going up or down (at most one level per step), and that level;
* ``gap(Y, level)``: a signed distance of Y to that level, continuous along a step, zero on it —
  what the location on the method's step family solves for;
* ``snap(Y, level)``: Y put exactly on the level where a coordinate *is* the level (planes), else Y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp

__all__ = ["Plane", "ToroidalAngle", "wrap_angle"]


def wrap_angle(a):
    """a reduced to (−π, π]."""
    return a - 2 * jnp.pi * jnp.ceil((a - jnp.pi) / (2 * jnp.pi))


@dataclass(frozen=True)
class Plane:
    """x_axis = value, and with ``period`` P every x_axis = value + kP (the orbit itself not wrapped)."""

    axis: int
    value: float
    period: float | None = None

    def _level_index(self, s):  # floor(s/P), or s ≥ 0 without a period
        P = self.period
        return jnp.floor(s / P) if P is not None else (s >= 0).astype(jnp.float64)

    def crossing(self, x, X):
        m0 = self._level_index(x[self.axis] - self.value)
        m1 = self._level_index(X[self.axis] - self.value)
        up, down = m1 > m0, m1 < m0
        # crossed level: value + m1·P going up, value + m0·P going down (one per step)
        level = self.value + (0.0 if self.period is None else self.period) * jnp.where(up, m1, m0)
        return up, down, level

    def gap(self, Y, level):
        return Y[self.axis] - level

    def snap(self, Y, level):
        return Y.at[self.axis].set(level)


@dataclass(frozen=True)
class ToroidalAngle:
    """The half-planes φ = value + k·2π/nfp of Cartesian points, φ = atan2(x₂, x₁) (major axis x₃).

    φ is not a coordinate of the state, so a step's angle is lifted by its wrapped increment: the
    step must turn by less than π about the major axis (|Δφ| < π; checked in the kernels that use it
    by the caller's step size, see :func:`vpforms.fieldlines.toroidal_section`)."""

    value: float
    nfp: int = 1

    @property
    def period(self) -> float:
        return 2 * math.pi / self.nfp

    def crossing(self, x, X):
        phi0 = jnp.arctan2(x[1], x[0])
        phi1 = phi0 + wrap_angle(jnp.arctan2(X[1], X[0]) - phi0)
        m0 = jnp.floor((phi0 - self.value) / self.period)
        m1 = jnp.floor((phi1 - self.value) / self.period)
        up, down = m1 > m0, m1 < m0
        # the level modulo 2π (value + P·(m mod nfp)): no precision lost to large lifted angles
        level = self.value + self.period * jnp.mod(jnp.where(up, m1, m0), self.nfp)
        return up, down, level

    def gap(self, Y, level):  # the angle to the level, in (−π, π]: continuous near the level
        return wrap_angle(jnp.arctan2(Y[1], Y[0]) - level)

    def snap(self, Y, level):
        return Y

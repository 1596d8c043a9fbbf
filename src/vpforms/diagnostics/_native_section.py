"""The crossings of a section surface by orbits traced natively (:mod:`vpforms.backends.native.events`).

The kernel records, per line, the steps where the section function changes level (step index, the
states before and after); here each recorded step gets the level the JAX scan would record — the
surface's own :meth:`crossing` on those two states, batched — so that only those steps are refined,
on the method's step family, exactly as :func:`vpforms.diagnostics.poincare_section` refines the
crossings of its JAX scan.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from ..backends.native.codegen.sections import KINDS
from ..backends.native.events import Crossings, locate, run_events
from ._common import _chunks, _pad
from ._surfaces import Plane, ToroidalAngle

__all__ = ["native_crossings", "native_locator", "surface_spec"]


def surface_spec(surface) -> tuple[int, int, float, float]:
    """(kind, axis, value, period) of ``surface`` for the kernel's ``vp_sections``."""
    if isinstance(surface, Plane):
        if surface.period is None:
            return KINDS["side"], surface.axis, surface.value, 1.0
        return KINDS["levels"], surface.axis, surface.value, surface.period
    if isinstance(surface, ToroidalAngle):
        return KINDS["angle"], 0, surface.value, surface.period
    raise TypeError(f"no native section function for {surface!r}")


@partial(jax.jit, static_argnums=(0, 1))
def _crossing_kernel(surface, direction, x, X):
    """(crosses in ``direction``, crossed level) of the steps x → X, as the JAX scan decides them."""

    def one(x, X):
        up, down, lvl = surface.crossing(x, X)
        return (up if direction > 0 else down if direction < 0 else up | down), lvl

    return jax.vmap(one)(x, X)


def _crossing(surface, direction, x: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_crossing_kernel` on (M, 3) arrays, in padded power-of-two chunks (few compilations)."""
    M = x.shape[0]
    cross, lvl = np.zeros(M, bool), np.zeros(M)
    R = min(1 << max(M - 1, 1).bit_length(), 2**14)
    for lo, hi in _chunks(M, R):
        c, v = _crossing_kernel(surface, direction, jnp.asarray(_pad(x[lo:hi], R)), jnp.asarray(_pad(X[lo:hi], R)))
        cross[lo:hi], lvl[lo:hi] = np.asarray(c)[: hi - lo], np.asarray(v)[: hi - lo]
    return cross, lvl


def native_crossings(method, pts: np.ndarray, h: float, n_steps: int, surface, direction: int, progress_cb=None,
                     capacity: int | None = None) -> tuple[Crossings, np.ndarray, np.ndarray]:
    """Trace pts natively and return (crossings sorted by line and step, which of them cross in
    ``direction`` by the JAX test, their levels). The kernel's test and the JAX one are the same
    arithmetic; where they could part (an ulp at a level) the JAX test decides which recorded steps
    count, as in the JAX scan."""
    c = run_events(method, pts, h, n_steps, surface_spec(surface), direction,
                   lambda x, X: _crossing(surface, direction, x, X)[0], progress_cb, capacity=capacity)
    cross, lvl = _crossing(surface, direction, c.before, c.after)
    return c, cross, lvl


def native_locator(method, h: float, surface):
    """(x (M, 3), X (M, 3), levels (M,)) -> (points, θ, undecided): the crossings in the steps x → X
    located by the kernel's ``vp_locate`` on the bare step family of ``method`` (undecided: an
    evaluation failed — for the JAX locator, which owns the fallback rules). Where no evaluation
    fails the bare and the recovering step families are the same map, so one location serves both."""
    return partial(locate, method, h, surface_spec(surface))

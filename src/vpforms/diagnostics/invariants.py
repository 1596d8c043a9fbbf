"""Invariants along saved states: I(x(t)) − I(x(0))."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401

__all__ = ["invariant_drift"]


def invariant_drift(invariants: dict[str, Any], xs: Any, relative: bool = False) -> dict[str, np.ndarray]:
    """I(x_t) − I(x_0) for each named invariant, for saved states xs of shape (S, 3) or (N, S, 3).

    ``invariants`` maps a name to a JAX scalar callable of x (3,) (a Problem's ``invariants``);
    ``xs`` may also be a :class:`vpforms.Solution`.  With ``relative=True`` the drift
    is divided by max(|I(x_0)|, 1e-300).  Returns name → array of the shape of xs without the
    last axis.
    """
    xs = np.asarray(getattr(xs, "xs", xs), dtype=np.float64)
    if xs.ndim < 2 or xs.shape[-1] != 3:
        raise ValueError(f"xs must have shape (S, 3) or (N, S, 3); got {xs.shape}")
    flat = jnp.asarray(xs.reshape(-1, 3))
    out = {}
    for name, fn in invariants.items():
        vals = np.asarray(jax.jit(jax.vmap(fn))(flat)).reshape(xs.shape[:-1])
        d = vals - vals[..., :1]
        if relative:
            d = d / np.maximum(np.abs(vals[..., :1]), 1e-300)
        out[name] = d
    return out

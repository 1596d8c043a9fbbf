"""``jax.jit`` for closures over large arrays: the arrays are passed to the compiled program as
arguments instead of being written into it as constants.

``jax.jit(f)`` of a function that closes over a spline's coefficients (a grid of A or K: 40 MB)
embeds them in the HLO: every such function's compilation folds and serialises them, each entry of
JAX's persistent cache holds a copy (39–78 MB compressed on W7-X's grids, 0.1–0.8 s each to read
back), and the cache key depends on their values, so a new grid of the same shape compiles again.
:func:`jit_hoisted` traces ``f`` once per argument signature (:func:`jax.make_jaxpr`), keeps the
arrays it closes over (the jaxpr's constants), and jits the jaxpr's evaluation with them as
arguments: the program depends on their shapes only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["jit_hoisted"]


def _signature(args: tuple) -> tuple:
    leaves, tree = jax.tree_util.tree_flatten(args)
    return tree, tuple((np.shape(a), jnp.result_type(a), getattr(a, "weak_type", False)) for a in leaves)


def jit_hoisted(fun: Callable[..., Any]) -> Callable[..., Any]:
    """``fun`` jitted, its closed-over arrays passed as arguments (module docstring). Positional
    array (pytree) arguments only; each new signature of them traces ``fun`` again, as jit does."""
    programs: dict[tuple, tuple] = {}

    def call(*args: Any) -> Any:
        key = _signature(args)
        entry = programs.get(key)
        if entry is None:
            closed, shape = jax.make_jaxpr(fun, return_shape=True)(*args)
            if any(isinstance(c, jax.core.Tracer) for c in closed.consts):
                return fun(*args)  # closes over an outer trace's values: nothing to keep or hoist
            jaxpr = closed.jaxpr
            run = jax.jit(lambda consts, *xs: jax.core.eval_jaxpr(jaxpr, consts, *xs))
            consts = [jnp.asarray(c) if isinstance(c, np.ndarray | np.generic) else c for c in closed.consts]
            entry = programs[key] = (run, consts, jax.tree_util.tree_structure(shape))
        run, consts, out_tree = entry
        return jax.tree_util.tree_unflatten(out_tree, run(consts, *jax.tree_util.tree_leaves(args)))

    call.__wrapped__ = fun
    call.programs = programs  # signature → (jitted program, hoisted arrays, output tree)
    return call

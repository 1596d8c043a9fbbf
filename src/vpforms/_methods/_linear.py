"""Shared machinery of the linear S1/S2 recipes: the SymPy recipes of :mod:`vpforms.symbolic.recipes`
(the ONE definition of eq:S1_quispel, eq:S1_AZ, eq:S2_quispel, printed and corrected) lambdified
to JAX in the generic argument order of the engine."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .._map import GeneratingMap
from ..symbolic import recipes as _recipes
from ._base import GeneratingMethod, RecipeError

__all__ = ["LinearRecipeMethod", "lambdified_recipe"]

_H = _recipes.SYMBOLS["h"]
_A = tuple(_recipes.SYMBOLS[f"a{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3))


@lru_cache(maxsize=None)
def lambdified_recipe(cls: str, variant: str, printed: bool):
    """(phi, Phi): JAX callables f(Y3, y2, y3, h, a11, …, a33) of the recipe in generic order."""
    rec = (
        _recipes.s1_potentials(variant, printed)
        if cls == "S1"
        else _recipes.s2_potentials(printed)
    )
    gen = rec.generic()
    phi, Phi = gen.lambdify(params=(_H,) + _A, modules="jax")
    return phi, Phi, rec


class LinearRecipeMethod(GeneratingMethod):
    """A linear-field S1/S2 recipe: potentials quadratic in the variables, so each step is
    X = M(h) x with det M = 1 (the engine's Newton converges in one iteration)."""

    cls_name: str = ""
    required: tuple[tuple[int, int], ...] = ()

    def __init__(self, field, *, variant: str = "quispel", printed: bool = False,
                 newton: dict | None = None):
        A = getattr(field, "linear_matrix", None)
        if A is None:
            raise RecipeError(
                f"the {self.cls_name} recipes of the paper are for linear fields a = A x only "
                f"(field {getattr(field, 'name', field)!r} is not linear); use "
                f"vpforms.scheme(field, {self.cls_name!r}) for Quispel's correction map"
            )
        A = np.asarray(A, dtype=float)
        for i, j in self.required:
            if A[i - 1, j - 1] == 0.0:
                raise RecipeError(
                    f"the {self.cls_name} recipe divides by a{i}{j}, which is 0 for field "
                    f"{getattr(field, 'name', field)!r} (A = {A.tolist()}); choose another case of "
                    f"the class (relabelling) or recipe='correction'"
                )
        self.field = field
        self.matrix = A
        self.variant, self.printed = variant, bool(printed)
        self.order, self.symmetric = 1, False
        self.newton = {**GeneratingMethod.newton, **(newton or {})}
        self._phi, self._Phi, self.recipe = lambdified_recipe(self.cls_name, variant, self.printed)
        self._coeffs = tuple(float(v) for v in A.ravel())

    def generating_map(self, h, x=None):
        f, F, a = self._phi, self._Phi, self._coeffs

        def phi(Y3, y2, y3):
            return f(Y3, y2, y3, h, *a)

        def Phi(Y3, Y2, y3):
            return F(Y3, Y2, y3, h, *a)

        return GeneratingMap(phi, Phi, self.case, **self.newton)

    def matrix_step(self, h):
        """M(h) with X = M(h) x (the step of a linear recipe is linear)."""
        return np.asarray(self.jacobian(np.zeros(3), h))

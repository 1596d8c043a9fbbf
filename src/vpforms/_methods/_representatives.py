"""The five class representatives (σ = (3,2,1) throughout Section 4 of the paper), defined once in
the symbolic layer (:data:`vpforms.symbolic.recipes.REPRESENTATIVES`)."""

from __future__ import annotations

from ..symbolic.recipes import REPRESENTATIVES

__all__ = ["REPRESENTATIVES"]

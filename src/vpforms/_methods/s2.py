"""Class S2 (eq:S2) for linear fields a = A x: eq:S2_quispel (correct as printed).

Representative σ = (3,2,1), Σ = (2,3,1), sign −1; LM equations x₃ = ∂_{x₂}φ, ∂_{X₁}φ = ∂_{x₁}Φ,
X₂ = ∂_{X₃}Φ with φ(x₁, x₂, X₁), Φ(x₁, X₁, X₃), from
:func:`vpforms.symbolic.recipes.s2_potentials`. Needs a₁₂ ≠ 0 **and** a₁₃ ≠ 0. Equals Quispel's
correction map (t5vps2); for nonlinear fields use :class:`vpforms._methods.correction.QuispelS2`.
"""

from __future__ import annotations

from ._linear import LinearRecipeMethod
from ._representatives import REPRESENTATIVES

__all__ = ["S2"]


class S2(LinearRecipeMethod):
    """S2 for linear fields (eq:S2_quispel): order 1, not symmetric."""

    cls_name = "S2"
    required = ((1, 3), (1, 2))

    def __init__(self, field, *, variant: str = "quispel", printed: bool = False,
                 newton: dict | None = None):
        if variant != "quispel":
            raise ValueError(f"S2 has only the 'quispel' variant (eq:S2_quispel), not {variant!r}")
        self.case = REPRESENTATIVES["S2"]
        self.name = "S2-quispel"
        super().__init__(field, variant=variant, printed=printed, newton=newton)

"""Class S1 (eq:S1) for linear fields a = A x: eq:S1_quispel (default) and eq:S1_AZ, corrected.

Representative σ = Σ = (3,2,1), sign +1; LM equations x₃ = ∂_{x₂}φ, ∂_{X₁}φ = ∂_{x₁}Φ,
X₃ = −∂_{X₂}Φ with φ(x₁, x₂, X₁), Φ(x₁, X₁, X₂). The potentials are the SymPy expressions of
:func:`vpforms.symbolic.recipes.s1_potentials` (corrected per spec §4; ``printed=True`` gives the
paper's formulas, volume preserving but inconsistent). Needs a₁₃ ≠ 0. The corrected Quispel
variant equals Quispel's correction map (t5vp); for nonlinear fields use
:class:`vpforms._methods.correction.QuispelS1`.
"""

from __future__ import annotations

from ._linear import LinearRecipeMethod
from ._representatives import REPRESENTATIVES

__all__ = ["S1"]


class S1(LinearRecipeMethod):
    """S1 for linear fields (eq:S1_quispel / eq:S1_AZ): order 1, not symmetric.

    ``variant``: ``"quispel"`` (default) or ``"az"``; ``printed``: the paper's printed formula.
    """

    cls_name = "S1"
    required = ((1, 3),)

    def __init__(self, field, *, variant: str = "quispel", printed: bool = False,
                 newton: dict | None = None):
        if variant not in ("quispel", "az"):
            raise ValueError(f"S1 variant must be 'quispel' or 'az', not {variant!r}")
        self.case = REPRESENTATIVES["S1"]
        self.name = f"S1-{variant}" + ("(printed)" if printed else "")
        super().__init__(field, variant=variant, printed=printed, newton=newton)

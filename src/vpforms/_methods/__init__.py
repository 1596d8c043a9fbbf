"""Volume-preserving integrators for the five classes and all 36 cases (issue #5).

One file per class recipe (se_se, se_dl, dl_dl, s1, s2), Quispel's correction maps for S1/S2 on
nonlinear fields (correction), the case machinery (scheme: relabelling and adjunction) and
higher order by composition (compose: one :class:`Composition`, a list of stages). Every recipe
hands its potentials to the one engine
:class:`vpforms.GeneratingMap`.
"""

from ._base import Adjoint, GeneratingMethod, Method, RecipeError, Relabelled, Stage
from ._compose import (ADJOINT_COMPOSITIONS, COMPOSITIONS, Composition, adjoint_composition,
                       compose, symmetric_pair, triple_jump)
from .rk4 import RK4
from .correction import QuispelCorrection, QuispelS1, QuispelS2
from .dl_dl import DLDL
from .s1 import S1
from .s2 import S2
from ._scheme import representative_method, scheme
from .se_dl import SEDL
from .se_se import SESE, SESEFast

__all__ = [
    "Method",
    "GeneratingMethod",
    "Relabelled",
    "Adjoint",
    "RecipeError",
    "SESE",
    "SESEFast",
    "SEDL",
    "DLDL",
    "S1",
    "S2",
    "QuispelCorrection",
    "QuispelS1",
    "QuispelS2",
    "scheme",
    "representative_method",
    "compose",
    "ADJOINT_COMPOSITIONS",
    "COMPOSITIONS",
    "Composition",
    "Stage",
    "adjoint_composition",
    "symmetric_pair",
    "triple_jump",
    "RK4",
]

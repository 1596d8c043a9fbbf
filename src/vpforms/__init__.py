"""vpforms — volume-preserving generating forms in R³ as numerical integrators.

Reference implementation of Verdier, Xue & Zanna, *A classification of volume preserving
generating forms in R³* (arXiv 1412.6345), with the corrections of the project's MATH.md.

Importing vpforms enables JAX float64 (see :mod:`vpforms._config`, the one place it is set).
"""

from . import _config  # noqa: F401  (enables jax_enable_x64 before any array is made)
from ._case import CLASSES, Case, cases, class_of_tau
from ._errors import (
    RECOVERY,
    RESULTS,
    ConvergenceError,
    InconsistentStepError,
    LeftDomainError,
    NonFiniteError,
    NotDivergenceFreeError,
    TwistConditionError,
    VPFormsError,
    raise_for_status,
)
from ._map import GeneratingMap
from .fields import Field, PotentialError
from ._newton import newton_scalar
from ._perm import FLIP, Perm, as_perm
from ._methods import (
    DLDL,
    S1,
    S2,
    SEDL,
    SESE,
    Method,
    QuispelCorrection,
    RecipeError,
    compose,
    scheme,
)
from ._integrate import RK4, Solution, integrate  # noqa: E402
from ._version import __version__  # noqa: F401  (vpforms.__version__)
from . import diagnostics  # noqa: E402
from ._spec import SpecError, field_from_spec, method_from_spec  # noqa: E402
from . import native  # noqa: E402  (native.available(); backends: issue 9)


__all__ = [
    "CLASSES",
    "Case",
    "cases",
    "class_of_tau",
    "RECOVERY",
    "RESULTS",
    "ConvergenceError",
    "InconsistentStepError",
    "LeftDomainError",
    "PotentialError",
    "NonFiniteError",
    "NotDivergenceFreeError",
    "TwistConditionError",
    "VPFormsError",
    "raise_for_status",
    "GeneratingMap",
    "Field",
    "newton_scalar",
    "FLIP",
    "Perm",
    "as_perm",
    "scheme",
    "compose",
    "Method",
    "SESE",
    "SEDL",
    "DLDL",
    "S1",
    "S2",
    "QuispelCorrection",
    "RecipeError",
    "integrate",
    "Solution",
    "RK4",
    "diagnostics",
    "SpecError",
    "method_from_spec",
    "field_from_spec",
]

"""``scheme(field, case)``: a method for any of the 36 cases from the five class recipes.

For a case c = (σ, Σ) of class K with representative (σ₀, Σ₀) (σ₀ = (3,2,1)):

* if τ(c) = τ₀, then c = (π∘σ₀, π∘Σ₀) with π = σ∘σ₀⁻¹ and (prop:trivperm) the method is
  (π, π)·Ψ[(π⁻¹, π⁻¹)·a]: the representative recipe run on the relabelled field, conjugated by π
  (``GeneratingMap.relabel(π)``);
* otherwise τ(c) = τ₀⁻¹ ≠ τ₀ (only the SE+DL 3-cycles) and the method is the adjoint of the method
  for (Σ, σ) (prop:switchperm): Ψ*_h = (Ψ_{−h})⁻¹, via ``GeneratingMap.inverse()``.

No per-case code: one recipe per class and these two operations give all 36 cases.
"""

from __future__ import annotations

from typing import Any

from .._case import CLASSES, Case
from .._perm import Perm
from .._spec_record import records_spec
from .._fieldops import PotentialError
from ._base import Method, Relabelled, RecipeError
from ._relabel import relabelled_field
from ._representatives import REPRESENTATIVES
from .correction import QuispelCorrection
from .recover import recovering_scheme
from .dl_dl import DLDL
from .s1 import S1
from .s2 import S2
from .se_dl import SEDL
from .se_se import SESE, SESEFast

__all__ = ["scheme", "representative_method", "class_name"]

_ALIASES = {"DL+SE": "SE+DL", "SE": "SE+SE", "DL": "DL+DL"}


def class_name(name: str) -> str:
    """Normalise a class name ("se+se", "DL+SE", …) or raise ValueError listing the classes."""
    key = str(name).strip().upper().replace(" ", "")
    key = _ALIASES.get(key, key)
    if key not in CLASSES:
        raise ValueError(
            f"unknown class {name!r}; the five classes are {', '.join(CLASSES)} (or 'DL+SE')"
        )
    return key


def representative_method(field: Any, cls: str, **options) -> Method:
    """The class recipe on its representative case (σ = (3,2,1)) for ``field``.

    Options: ``theta`` (DL classes), ``printed`` (SE+DL, DL+DL, S1), ``variant`` (S1),
    ``recipe`` ("generating" | "correction" for S1/S2; default: generating for linear fields,
    correction otherwise), ``integral``/``quadrature_n`` (correction maps),
    ``newton`` (Newton controls). ``fast`` evaluates the step directly instead of through the
    engine — the same map, tested equal to it: SE+SE's closed-form shears (``fast=True``; default
    False), the DL classes' nested θ-stages (default; ``fast=False`` asks for the engine form, the
    reference, which fails at the fold of a stage).
    """
    cls = class_name(cls)
    newton = options.pop("newton", None)
    if cls == "SE+SE":
        _only(options, cls, ("fast", "printed"))
        fast = options.get("fast", False)
        return (SESEFast if fast else SESE)(field, newton=newton)
    if cls in ("SE+DL", "DL+DL"):
        _only(options, cls, ("theta", "printed", "fast"))
        M = SEDL if cls == "SE+DL" else DLDL
        return M(field, theta=options.get("theta", 0.0), printed=options.get("printed", False),
                 fast=options.get("fast"), newton=newton)
    # S1, S2
    _only(options, cls, ("recipe", "variant", "printed", "integral", "quadrature_n"))
    recipe = options.get("recipe")
    if recipe is None:
        recipe = "generating" if getattr(field, "linear_matrix", None) is not None else "correction"
    if recipe == "generating":
        M = S1 if cls == "S1" else S2
        return M(field, variant=options.get("variant", "quispel"),
                 printed=options.get("printed", False), newton=newton)
    if recipe == "correction":
        if options.get("printed", False) or options.get("variant", "quispel") != "quispel":
            raise ValueError("the correction map has no printed/AZ variant (use recipe='generating')")
        kw = {k: options[k] for k in ("integral", "quadrature_n") if k in options}
        return QuispelCorrection(field, cls, newton=newton, **kw)
    raise ValueError(f"recipe must be 'generating' or 'correction', not {recipe!r}")


def _only(options, cls, allowed):
    bad = set(options) - set(allowed)
    if bad:
        raise ValueError(f"option(s) {sorted(bad)} do not apply to class {cls} (allowed: {allowed})")


@records_spec("scheme")
def scheme(field: Any, case: Case | str | tuple = "SE+SE", **options) -> Method:
    """A volume-preserving method for ``field`` and ``case``.

    ``case`` is a :class:`~vpforms.Case`, a pair ``(sigma, Sigma)``, or a class name ("SE+SE",
    "SE+DL" (= "DL+SE"), "DL+DL", "S1", "S2") for its representative. The method is the class
    recipe (:func:`representative_method`, whose options apply) relabelled (prop:trivperm) and,
    for the SE+DL 3-cycle τ₀⁻¹, adjoined (prop:switchperm).

    ``recover=True`` (default): where the step fails, the same DL map by its nested θ-stages (DL
    classes in the engine form), other cases of the class, then other classes, then
    2…2^``recover_substeps`` sub-steps are tried (``vpforms._methods.recover``); an alternative
    is accepted only if it passes the consistency guard and agrees with RK4 (``vpforms._guard``).
    ``recover=False`` is the bare method. ``recover_classes=False`` skips the other classes.
    A recovered step is an exactly VP, consistent step of the same order (a composition of a
    recovering method recovers its composed step), but only as accurate as the alternative taken.
    ``Solution.recovered`` counts the switched steps per particle; ``method.refused`` lists the
    alternatives whose potentials were refused on the field's box.

    The case's own potentials are checked on the field's box here (``Method.check_domain``): a
    pair that is singular inside it, or a numerical pair that does not reproduce the field, is a
    :class:`~vpforms.PotentialError` naming the case, the potential and a point (issue #23).
    """
    if not (callable(field) and hasattr(type(field), "se_potentials") and hasattr(type(field), "dl_potentials")):
        raise TypeError(f"scheme needs a vpforms.Field (e.g. vpforms.problems.get('abc').field), "
                        f"got {type(field).__name__}")
    recover = options.pop("recover", True)
    substeps = options.pop("recover_substeps", 6)
    classes = options.pop("recover_classes", True)
    if recover:  # issue #12: alternatives where the bare step fails (see _methods/recover.py)
        return recovering_scheme(scheme, field, case, options, substeps, classes)
    if isinstance(case, str):
        c = REPRESENTATIVES[class_name(case)]
    elif isinstance(case, Case):
        c = case
    else:
        try:
            c = Case(*case)
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"case must be a Case, a pair (sigma, Sigma) or a class name; got {case!r} ({err})"
            ) from None
    rep = REPRESENTATIVES[c.cls]
    pi = c.sigma * rep.sigma.inverse()  # c.sigma = π∘σ₀
    if pi * rep.Sigma != c.Sigma:
        # τ(c) = τ₀⁻¹: the adjoint of the method for the switched case (prop:switchperm)
        # bare like this call (recover was popped above): no recovery wrapper inside the adjoint
        try:
            return scheme(field, c.switched(), recover=False, **options).adjoint()
        except PotentialError as err:
            raise PotentialError(f"case {c} is the adjoint of {err}") from None
    try:
        base = representative_method(relabelled_field(field, pi), c.cls, **dict(options))
    except RecipeError as err:
        if pi.is_identity:
            raise
        raise RecipeError(
            f"case {c} = relabelling by π = {pi.one_line()} of {rep}: {err}"
        ) from None
    method = base if pi == Perm((1, 2, 3)) else Relabelled(base, pi, field)
    method.check_domain()  # issue #23: refused here, with the reason, never at a step
    return method

"""Which cases step φ by exactly h on a φ-time field, and the method built from one."""

from __future__ import annotations

from typing import Any

from .._case import Case, cases
from .._methods import Method, compose, scheme
from .._methods._representatives import REPRESENTATIVES
from .._methods._scheme import class_name
from ..fields import Field

__all__ = ["advances_phi_exactly", "phi_exact_cases", "phi_time_scheme"]


#: per class, the axis (1-based) of the field the class recipe treats specially, on the relabelled
#: field it runs on: the gauge axis of its pair (SE: x₂, DL: x₃) or the role j of Quispel's
#: correction map (S1: x₂, S2: x₃; the recipe of vpforms.scheme for nonlinear fields)
_SPECIAL_AXIS = {"SE+SE": 2, "DL+DL": 3, "SE+DL": 3, "S1": 2, "S2": 3}


def advances_phi_exactly(case: Case | str | tuple) -> bool:
    """Whether the step of ``case`` on a φ-time field advances φ by exactly h (to rounding).

    The rule: the axis its class treats specially (:data:`_SPECIAL_AXIS`), mapped back through the
    relabelling π the case is built with (relabelled x_k is the field's x_{π(k)}; for the SE+DL
    3-cycles τ₀⁻¹, of the switched case whose adjoint it is), must not be φ (axis 2). Then the pair
    is C's own gauge along v (χ = 0) or Z (χ = −v(Z − c)), which splits b into the φ-translation
    (0, 1, 0) and the frozen-φ flow (−∂_ZK, 0, ∂_vK), or the correction map's φ update is explicit
    (X_φ = φ + h·1). Verified on all 36 cases by ``tests/test_phitime.py`` (slow tier): 24 are
    φ-exact — S1 4, S2 4, SE+SE 4, DL+DL 4, SE+DL 8 — and those are also the cheap ones (no
    quadrature of K along φ). The DL classes must run by their θ-stages (``fast=True``): their
    φ-exact pairs contain a potential linear in the momentum, where the engine's DL generating form
    fails its twist condition.
    """
    c = _as_case(case)
    rep = REPRESENTATIVES[c.cls]
    pi = c.sigma * rep.sigma.inverse()
    if pi * rep.Sigma != c.Sigma:  # τ(c) = τ₀⁻¹: the adjoint of the switched case (vpforms.scheme)
        c = c.switched()
        pi = c.sigma * rep.sigma.inverse()
    return pi(_SPECIAL_AXIS[c.cls]) != 2


def phi_exact_cases(cls: str | None = None) -> tuple[Case, ...]:
    """The cases (of class ``cls``, or all) whose steps advance φ by exactly h
    (:func:`advances_phi_exactly`), in the order of :func:`vpforms.cases`."""
    want = None if cls is None else class_name(cls)
    return tuple(c for c in cases() if (want is None or c.cls == want) and advances_phi_exactly(c))


def phi_time_scheme(field: Field, cls: str = "SE+SE", *, order: int | None = None,
                    composition: str | None = None, recover: bool = False, **options: Any) -> Method:
    """A method on a φ-time field whose every step advances φ by exactly h, so that the sections
    φ = φ₀ + k·h are step boundaries: the first φ-exact case of class ``cls``
    (:func:`phi_exact_cases`), by θ-stages for the DL classes (``fast=True``), composed to
    ``order`` (2, 4, 6; :func:`vpforms.compose`, ``composition`` its scheme name) if given.

    ``recover`` defaults to False: a recovered step may switch to a case that is not φ-exact (and
    whose pair is a quadrature of K along φ, expensive to compile); where a step fails, the line
    has usually left the (v, φ, Z) box (``RESULTS.left_domain``)."""
    if not hasattr(field, "phi_time"):
        raise TypeError("phi_time_scheme needs a φ-time field (vpforms.phitime.phi_time_field)")
    key = class_name(cls)
    if key in ("DL+DL", "SE+DL"):
        options.setdefault("fast", True)
    method = scheme(field, phi_exact_cases(key)[0], recover=recover, **options)
    if order is None:
        if composition is not None:
            raise ValueError("composition needs an order")
        return method
    return compose(method, order, composition)


def _as_case(case: Any) -> Case:
    if isinstance(case, Case):
        return case
    if isinstance(case, str):
        return REPRESENTATIVES[class_name(case)]
    return Case(*case)

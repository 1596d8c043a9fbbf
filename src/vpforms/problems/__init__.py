"""A library of divergence-free test problems, one module per problem.

>>> import vpforms.problems as P
>>> P.names()
('abc', 'abc_gi', 'linear', 'lotka_volterra', 'stokes_sphere', 'tokamak', 'rigid_body')
>>> prob = P.get("abc")            # default parameters (cached)
>>> prob = P.get("abc", C=0)       # the integrable ABC flow, with invariant A cos x3 + B sin x1

Each module has ``make(**params) -> Problem`` and a cached ``default()``.  Every problem's field
is a SymPy :class:`vpforms.Field` with closed-form SE and DL potentials.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from . import abc, coil_fields, devices, linear, lotka_volterra, rigid_body, stokes_sphere, tokamak
from ..coils import device_names
from ._base import Problem

__all__ = [
    "Problem",
    "get",
    "names",
    "coil_names",
    "abc",
    "linear",
    "lotka_volterra",
    "stokes_sphere",
    "tokamak",
    "rigid_body",
]

_MAKERS: dict[str, tuple[Callable[..., Problem], Callable[[], Problem] | None]] = {
    "abc": (abc.make, abc.default),
    "abc_gi": (abc.make_geometric_integrators, None),
    "linear": (linear.make, linear.default),
    "lotka_volterra": (lotka_volterra.make, lotka_volterra.default),
    "stokes_sphere": (stokes_sphere.make, stokes_sphere.default),
    "tokamak": (tokamak.make, tokamak.default),
    "rigid_body": (rigid_body.make, rigid_body.default),
}
_GI_DEFAULT: list[Problem] = []
#: field lines of coil sets (issue #20): fields in (u = R²/2, φ, Z) given by a spline of the coils'
#: vector potential, or (the real stellarators of issue #38) by the coils themselves, not SymPy
#: fields — kept out of :func:`names`, whose problems all have closed-form potentials and symbolic
#: invariants (and run on the native backend)
_COIL_MAKERS: dict[str, tuple[Callable[..., Problem], Callable[[], Problem]]] = {
    "coil_tokamak": (coil_fields.make_tokamak, coil_fields.default_tokamak),
    "coil_stellarator": (coil_fields.make_stellarator, coil_fields.default_stellarator),
    **{name: (partial(devices.make, name), partial(devices.default, name)) for name in device_names()},
}


def names() -> tuple[str, ...]:
    """The registered problem names."""
    return tuple(_MAKERS)


def coil_names() -> tuple[str, ...]:
    """The coil-field problems in (u = R²/2, φ, Z): a spline of the coils' vector potential
    (:mod:`vpforms.problems.coil_fields`) or, for the real stellarators ``w7x``, ``ncsx``, ``hsx``,
    the coils traced directly (:mod:`vpforms.problems.devices`)."""
    return tuple(_COIL_MAKERS)


def get(name: str, **params) -> Problem:
    """The problem ``name`` with the given parameters (the cached default when none are given)."""
    key = str(name).lower().replace("-", "_")
    if key in _COIL_MAKERS:
        make, default = _COIL_MAKERS[key]
        return make(**params) if params else default()
    if key not in _MAKERS:
        raise KeyError(f"unknown problem {name!r}; known problems: {', '.join((*_MAKERS, *_COIL_MAKERS))}")
    make, default = _MAKERS[key]
    if params:
        return make(**params)
    if default is not None:
        return default()
    if key == "abc_gi":
        if not _GI_DEFAULT:
            _GI_DEFAULT.append(make())
        return _GI_DEFAULT[0]
    return make()

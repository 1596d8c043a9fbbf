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

from . import abc, linear, lotka_volterra, rigid_body, stokes_sphere, tokamak
from ._base import Problem

__all__ = [
    "Problem",
    "get",
    "names",
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


def names() -> tuple[str, ...]:
    """The registered problem names."""
    return tuple(_MAKERS)


def get(name: str, **params) -> Problem:
    """The problem ``name`` with the given parameters (the cached default when none are given)."""
    key = str(name).lower().replace("-", "_")
    if key not in _MAKERS:
        raise KeyError(f"unknown problem {name!r}; known problems: {', '.join(_MAKERS)}")
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

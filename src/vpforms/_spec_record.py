"""The construction record of a method (issue #10), below the methods that record it.

``records_spec(kind)`` decorates a method factory (``scheme``, ``compose``): the method it returns
remembers its construction arguments; :func:`method_spec` turns them into JSON on demand
(``_case_json``, ``_jsonable``).  Split from ``_spec.py`` (issue #19: imports flow one way).

:func:`method_spec` reads only data a method carries — its record ``_spec_record`` (``RK4`` records
``("rk4", (field,), {})`` itself), ``adjoint_of`` (an :class:`~vpforms.Method.adjoint`) or
``relabel_of`` (a :meth:`~vpforms.Method.relabel`) — so it sits here, below the methods whose
``spec()`` it is (issue #40: no import cycle, lazy ones included); :mod:`vpforms._spec`, above
the methods, rebuilds a method from its spec.
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np

from ._case import Case
from ._errors import SpecError
from ._perm import as_perm
from ._version import __version__
from .fields import field_spec

__all__ = ["SPEC_VERSION", "method_spec", "records_spec"]

SPEC_VERSION = 1


def _case_json(case: Any) -> Any:
    if isinstance(case, str):
        return case
    if isinstance(case, Case):
        return [list(map(int, case.sigma)), list(map(int, case.Sigma))]
    return [list(map(int, c)) if not isinstance(c, str) else c for c in case]


def _jsonable(options: dict) -> dict:
    out = {}
    for k, v in options.items():
        if isinstance(v, np.generic):
            v = v.item()
        try:
            json.dumps(v)
        except TypeError:
            raise SpecError(f"scheme option {k}={v!r} is not JSON-able: the method cannot be shipped") from None
        out[k] = v
    return out


def records_spec(kind: str):
    """Decorator for a method FACTORY: the method it returns remembers its construction arguments.

    The record keeps the live arguments; :func:`method_spec` turns them into JSON on demand.
    """

    def deco(fn):
        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            m = fn(*args, **kwargs)
            try:
                m._spec_record = (kind, args, kwargs)
            except AttributeError:  # pragma: no cover — a slotted object
                pass
            return m

        return wrapper

    return deco


def method_spec(method: Any) -> dict:
    """The JSON-able spec of a method built by scheme/compose/adjoint/relabel, or of RK4."""
    rec = getattr(method, "_spec_record", None)
    if rec is None:
        base = getattr(method, "adjoint_of", None)
        if base is not None:  # an Adjoint, or the adjoint of a recovering method or composition
            return {"kind": "adjoint", "base": method_spec(base), "version": __version__}
        relabel_of = getattr(method, "relabel_of", None)
        if relabel_of is not None:  # Method.relabel(π)
            base, pi = relabel_of
            return {"kind": "relabel", "base": method_spec(base), "pi": list(as_perm(pi)),
                    "version": __version__}
        raise SpecError(
            f"{type(method).__name__} was not built by vpforms.scheme/compose/adjoint: it has no spec "
            "(build it with vpforms.scheme(field, case, **options) to ship it)"
        )
    kind, args, kwargs = rec
    if kind == "rk4":
        return {"kind": "rk4", "field": field_spec(args[0]), "version": __version__}
    if kind == "scheme":
        names = ("field", "case")
        bound = dict(zip(names, args))
        options = {k: v for k, v in kwargs.items() if k not in names}
        bound.update({k: kwargs[k] for k in names if k in kwargs})
        return {"kind": "scheme", "field": field_spec(bound["field"]),
                "case": _case_json(bound.get("case", "SE+SE")), "options": _jsonable(options),
                "version": __version__}
    if kind == "compose":
        names = ("method", "order", "scheme")
        bound = dict(zip(names, args))
        bound.update(kwargs)
        return {"kind": "compose", "base": method_spec(bound["method"]),
                "order": int(bound.get("order", 2)), "scheme": bound.get("scheme"),
                "version": __version__}
    raise SpecError(f"unknown spec record {kind!r}")  # pragma: no cover

"""Methods as data: a JSON spec that rebuilds a method bit for bit (issue #10).

A method is shipped to another process (a Dask worker, a file's attributes) as the arguments it
was BUILT from, never as pickled jitted functions:

* ``scheme(field, case, **options)`` → ``{"kind": "scheme", "field": …, "case": …, "options": …}``
  (options are recorded generically: any JSON-able value flows through, so new scheme options
  need no change here);
* ``compose(m, order, scheme)`` → ``{"kind": "compose", "base": …, "order": …, "scheme": …}``;
* ``m.adjoint()`` → ``{"kind": "adjoint", "base": …}``; ``RK4(field)`` → ``{"kind": "rk4", …}``.

A field is its SymPy expressions (``sympy.srepr``, exact for Floats), symbols, box, name and the
construction settings (plus user-supplied symbolic potentials), or the matrix of a linear field.
A field given only as a JAX callable cannot be shipped (:class:`SpecError`).
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np
import sympy as sp

from ._errors import VPFormsError

__all__ = ["SpecError", "method_from_spec", "field_from_spec", "field_spec", "method_spec",
           "records_spec", "SPEC_VERSION"]

SPEC_VERSION = 1


class SpecError(VPFormsError, ValueError):
    """A method or field cannot be written as (or rebuilt from) a spec."""


# ---------------------------------------------------------------------------------------------
# fields
# ---------------------------------------------------------------------------------------------
def field_spec(field: Any) -> dict:
    """The JSON-able spec of a :class:`vpforms.Field` (symbolic or linear)."""
    from .fields import Field

    if not isinstance(field, Field):
        raise SpecError(f"cannot ship {type(field).__name__} {field!r}: only a vpforms.Field has a spec")
    if field.linear_matrix is not None:
        return {"kind": "linear", "A": np.asarray(field.linear_matrix, float).tolist(),
                "name": field.name, "box": [list(b) for b in field.box]}
    if field.exprs is None:
        raise SpecError(
            f"field {field.name!r} was given only as a JAX callable: it cannot be shipped to another "
            "process or written to a file; build it with Field.from_sympy (or a vpforms.problems problem)"
        )
    pots = {k: [sp.srepr(p) for p in v[1]] for k, v in field._potentials.items()
            if v[2] == "user-supplied" and v[1] is not None}
    return {
        "kind": "sympy",
        "exprs": [sp.srepr(e) for e in field.exprs],
        "symbols": [sp.srepr(s) for s in field.symbols],
        "params": {str(k): float(v) for k, v in field.params.items()},
        "name": field.name,
        "box": [list(b) for b in field.box],
        "origin": list(field.origin),
        "quadrature_n": field.quadrature_n,
        "closed_form": field.closed_form,
        "tol": field.tol,
        **({"potentials": pots} if pots else {}),
    }


@functools.lru_cache(maxsize=64)
def _field_from_json(text: str):
    from .fields import Field

    spec = json.loads(text)
    kind = spec.get("kind")
    box = tuple(tuple(b) for b in spec["box"])
    if kind == "linear":
        return Field.linear(np.asarray(spec["A"], float), name=spec["name"], box=box)
    if kind != "sympy":
        raise SpecError(f"unknown field spec kind {kind!r}")
    exprs = [sp.sympify(e) for e in spec["exprs"]]
    symbols = [sp.sympify(s) for s in spec["symbols"]]
    pots = {k: tuple(sp.sympify(p) for p in v) for k, v in spec.get("potentials", {}).items()} or None
    f = Field.from_sympy(exprs, symbols, name=spec["name"], potentials=pots, box=box,
                         origin=tuple(spec["origin"]), quadrature_n=spec["quadrature_n"],
                         closed_form=spec["closed_form"], tol=spec["tol"])
    f.params = dict(spec.get("params", {}))
    return f


def field_from_spec(spec: dict) -> Any:
    """Rebuild a :class:`vpforms.Field` from :func:`field_spec` (cached per process)."""
    if not isinstance(spec, dict):
        raise SpecError(f"a field spec is a dict, got {type(spec).__name__}")
    try:
        return _field_from_json(json.dumps(spec, sort_keys=True))
    except (KeyError, TypeError) as err:
        raise SpecError(f"malformed field spec: {err!r}") from None


# ---------------------------------------------------------------------------------------------
# methods
# ---------------------------------------------------------------------------------------------
def _case_json(case: Any) -> Any:
    from ._case import Case

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
    """The JSON-able spec of a method built by scheme/compose/adjoint, or of RK4."""
    from . import __version__
    from ._integrate import RK4

    rec = getattr(method, "_spec_record", None)
    if rec is None:
        if isinstance(method, RK4):
            return {"kind": "rk4", "field": field_spec(method.field), "version": __version__}
        from ._methods._base import Adjoint

        base = method.base if isinstance(method, Adjoint) else getattr(method, "adjoint_of", None)
        if base is not None:  # an Adjoint, or the adjoint of a recovering method
            return {"kind": "adjoint", "base": method_spec(base), "version": __version__}
        raise SpecError(
            f"{type(method).__name__} was not built by vpforms.scheme/compose/adjoint: it has no spec "
            "(build it with vpforms.scheme(field, case, **options) to ship it)"
        )
    kind, args, kwargs = rec
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


def method_from_spec(spec: dict | str) -> Any:
    """Rebuild the method of :func:`method_spec` (a dict or its JSON text)."""
    from . import _methods
    from ._integrate import RK4
    from ._case import Case

    if isinstance(spec, str):
        try:
            spec = json.loads(spec)
        except json.JSONDecodeError as err:
            raise SpecError(f"a method spec must be JSON: {err}") from None
    if not isinstance(spec, dict) or "kind" not in spec:
        raise SpecError(f"a method spec is a dict with a 'kind', got {spec!r:.80}")
    kind = spec["kind"]
    if kind == "scheme":
        case = spec["case"]
        if not isinstance(case, str):
            case = Case(*(tuple(c) for c in case))
        return _methods.scheme(field_from_spec(spec["field"]), case, **spec.get("options", {}))
    if kind == "compose":
        return _methods.compose(method_from_spec(spec["base"]), spec["order"], spec.get("scheme"))
    if kind == "adjoint":
        return method_from_spec(spec["base"]).adjoint()
    if kind == "rk4":
        return RK4(field_from_spec(spec["field"]))
    raise SpecError(f"unknown method spec kind {kind!r} (scheme, compose, adjoint, rk4)")

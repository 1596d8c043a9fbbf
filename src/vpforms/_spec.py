"""Methods as data: a JSON spec that rebuilds a method bit for bit (issue #10).

A method is shipped to another process (a Dask worker, a file's attributes) as the arguments it
was BUILT from, never as pickled jitted functions:

* ``scheme(field, case, **options)`` → ``{"kind": "scheme", "field": …, "case": …, "options": …}``
  (options are recorded generically: any JSON-able value flows through, so new scheme options
  need no change here);
* ``compose(m, order, scheme)`` → ``{"kind": "compose", "base": …, "order": …, "scheme": …}``;
* ``m.adjoint()`` → ``{"kind": "adjoint", "base": …}``; ``m.relabel(π)`` →
  ``{"kind": "relabel", "base": …, "pi": [π(1), π(2), π(3)]}``; ``RK4(field)`` →
  ``{"kind": "rk4", …}``.

A field is its SymPy expressions (``sympy.srepr``, exact for Floats), symbols, box, name and the
construction settings (plus user-supplied symbolic potentials), or the matrix of a linear field.
A field given only as a JAX callable cannot be shipped (:class:`SpecError`).
"""

from __future__ import annotations

import json
from typing import Any

from . import _methods
from ._case import Case
from ._errors import SpecError
from ._methods._base import Adjoint
from ._methods.rk4 import RK4
from ._perm import as_perm
from ._spec_record import SPEC_VERSION, _case_json, _jsonable, records_spec
from ._version import __version__
from .fields import field_from_spec, field_spec

__all__ = ["SpecError", "method_from_spec", "field_from_spec", "field_spec", "method_spec",
           "records_spec", "SPEC_VERSION"]

# The layers (issue #19): SpecError is in _errors, the field specs in fields, the construction
# record (records_spec, _case_json, _jsonable) in _spec_record, below the methods that record it;
# this module, above the methods, turns a record into JSON and JSON back into a method.


# ---------------------------------------------------------------------------------------------
# methods
# ---------------------------------------------------------------------------------------------
def method_spec(method: Any) -> dict:
    """The JSON-able spec of a method built by scheme/compose/adjoint, or of RK4."""
    rec = getattr(method, "_spec_record", None)
    if rec is None:
        if isinstance(method, RK4):
            return {"kind": "rk4", "field": field_spec(method.field), "version": __version__}
        base = method.base if isinstance(method, Adjoint) else getattr(method, "adjoint_of", None)
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
    if kind == "relabel":
        return method_from_spec(spec["base"]).relabel(tuple(spec["pi"]))
    if kind == "rk4":
        return RK4(field_from_spec(spec["field"]))
    raise SpecError(f"unknown method spec kind {kind!r} (scheme, compose, adjoint, relabel, rk4)")

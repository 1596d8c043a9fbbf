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
from ._methods.rk4 import RK4
from ._spec_record import SPEC_VERSION, method_spec, records_spec
from .fields import field_from_spec, field_spec

__all__ = ["SpecError", "method_from_spec", "field_from_spec", "field_spec", "method_spec",
           "records_spec", "SPEC_VERSION"]

# The layers (issue #19, #40): SpecError is in _errors, the field specs in fields, the construction
# record (records_spec) and its JSON (method_spec) in _spec_record, below the methods that record
# it and whose spec() it is; this module, above the methods, turns JSON back into a method.


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

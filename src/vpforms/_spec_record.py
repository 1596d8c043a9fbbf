"""The construction record of a method (issue #10), below the methods that record it.

``records_spec(kind)`` decorates a method factory (``scheme``, ``compose``): the method it returns
remembers its construction arguments; :func:`vpforms._spec.method_spec` turns them into JSON on
demand (``_case_json``, ``_jsonable``).  Split from ``_spec.py`` (issue #19: imports flow one way).
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np

from ._case import Case
from ._errors import SpecError

__all__ = ["SPEC_VERSION", "records_spec"]

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

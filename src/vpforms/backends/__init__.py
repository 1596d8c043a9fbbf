"""Backend selection for :func:`vpforms.integrate`: ``"jax"`` (XLA) or ``"native"`` (generated C).

``select_backend(method, backend) -> (name, reason)``: ``"auto"`` picks native when the method can
be generated (symbolic or spline field, supported class) and a C compiler is present, JAX otherwise;
``"native"`` raises :class:`NativeUnavailableError` saying why it cannot.
"""

from __future__ import annotations

import weakref
from typing import Any

from .._errors import VPFormsError
from .native import available
from .native.codegen import unsupported_reason
from .native import biot_savart  # noqa: F401  (registers the native path of CoilSet.evaluate)

__all__ = ["BACKENDS", "NativeUnavailableError", "select_backend"]

BACKENDS = ("auto", "jax", "native")


class NativeUnavailableError(VPFormsError, RuntimeError):
    """The native backend was requested but cannot run this method here (the message says why)."""


def select_backend(method: Any, backend: str = "auto") -> tuple[str, str]:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}; got {backend!r}")
    if backend == "jax":
        return "jax", "requested"
    ok, why = available()
    reason = None if ok else why
    if reason is None:
        reason = _unsupported(method)
    if reason is None:
        return "native", "requested" if backend == "native" else "auto: native available"
    if backend == "native":
        raise NativeUnavailableError(f"native backend cannot run {getattr(method, 'name', method)!s}: {reason}")
    return "jax", f"auto: native not used ({reason})"


#: id(method) → (weak reference to the method, unsupported_reason(method)): the plan of a method
#: (SymPy printing, ~ms) is fixed once it is built, so each method is planned once; an entry is
#: used only while its reference still resolves to that very object (ids are reused), and dropped
#: when the method is collected
_reasons: dict[int, tuple[Any, str | None]] = {}


def _unsupported(method: Any) -> str | None:
    """:func:`unsupported_reason`, remembered per method object (not for objects without weak
    references: those are planned on every call)."""
    key = id(method)
    hit = _reasons.get(key)
    if hit is not None and hit[0]() is method:
        return hit[1]
    reason = unsupported_reason(method)
    try:
        ref = weakref.ref(method, lambda r, key=key: _reasons.pop(key) if _reasons.get(key, (None,))[0] is r
                          else None)
    except TypeError:
        return reason
    _reasons[key] = (ref, reason)
    return reason

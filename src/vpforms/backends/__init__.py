"""Backend selection for :func:`vpforms.integrate`: ``"jax"`` (XLA) or ``"native"`` (generated C).

``select_backend(method, backend) -> (name, reason)``: ``"auto"`` picks native when the method can
be generated (symbolic or spline field, supported class) and a C compiler is present, JAX otherwise;
``"native"`` raises :class:`NativeUnavailableError` saying why it cannot.
"""

from __future__ import annotations

from typing import Any

from .._errors import VPFormsError
from .native import available
from .native.codegen import unsupported_reason

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
        reason = unsupported_reason(method)
    if reason is None:
        return "native", "requested" if backend == "native" else "auto: native available"
    if backend == "native":
        raise NativeUnavailableError(f"native backend cannot run {getattr(method, 'name', method)!s}: {reason}")
    return "jax", f"auto: native not used ({reason})"

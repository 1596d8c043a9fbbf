"""The native CPU backend: method → C source (codegen) → cached .so (build) → run (runner)."""

from .build import available

__all__ = ["available"]

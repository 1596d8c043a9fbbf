"""The CLI's one error type, below every CLI module (issue #19: imports flow one way)."""

from __future__ import annotations

__all__ = ["CLIError"]


class CLIError(Exception):
    """A bad argument or an unavailable feature: reported as one line, exit code 2."""

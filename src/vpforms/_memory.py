"""The memory budget of vectorised evaluations (issue #40, item 2).

Evaluations over points × segments × quadrature nodes (coil fields, their potential checks,
samples on grids, diagnostics) are cut into pieces whose intermediates fit one budget:
:func:`memory_budget` bytes, 1 GiB by default, set by :func:`set_memory_budget` or the environment
variable ``VPFORMS_MEMORY_BUDGET`` (bytes; suffixes K, M, G accepted: ``512M``). The budget is read
when a computation is traced: set it before the first evaluation of a field (a jitted function
keeps the pieces it was compiled with).
"""

from __future__ import annotations

import os

__all__ = ["DEFAULT_BUDGET", "ENV", "memory_budget", "rows_within", "set_memory_budget"]

#: the default budget, bytes
DEFAULT_BUDGET = 1 << 30
#: the environment variable that sets the budget (bytes, or with a suffix K/M/G)
ENV = "VPFORMS_MEMORY_BUDGET"
#: the smallest budget accepted (a budget below it cannot hold one piece of any evaluation)
MIN_BUDGET = 1 << 20

_SET: list[int | None] = [None]
_SUFFIX = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}


def _parse(value: object, what: str) -> int:
    text = str(value).strip().upper().removesuffix("B")
    scale = _SUFFIX.get(text[-1:], 1)
    if scale != 1:
        text = text[:-1]
    try:
        n = float(text) * scale
    except ValueError:
        raise ValueError(f"{what} must be a number of bytes (optionally with K, M or G); got {value!r}") from None
    if not n >= MIN_BUDGET or n != n or n == float("inf"):
        raise ValueError(f"{what} must be at least {MIN_BUDGET} bytes (1M); got {value!r}")
    return int(n)


def set_memory_budget(nbytes: int | str | None) -> None:
    """Set the budget (bytes, or a string such as ``"512M"``); None returns to the environment
    variable or the default. Takes effect for computations traced afterwards."""
    _SET[0] = None if nbytes is None else _parse(nbytes, "the memory budget")


def memory_budget() -> int:
    """The budget in bytes: :func:`set_memory_budget`, else ``$VPFORMS_MEMORY_BUDGET``, else 1 GiB."""
    if _SET[0] is not None:
        return _SET[0]
    env = os.environ.get(ENV)
    return DEFAULT_BUDGET if env in (None, "") else _parse(env, f"${ENV}")


def rows_within(bytes_per_row: float, lo: int = 1, hi: int | None = None) -> int:
    """How many rows of ``bytes_per_row`` fit the budget, clamped to [lo, hi]."""
    n = int(memory_budget() // max(float(bytes_per_row), 1.0))
    n = max(lo, n)
    return n if hi is None else min(n, hi)

"""Permutations of {1, 2, 3} in the paper's one-line, 1-based notation.

A permutation ``sigma`` is written ``(sigma(1), sigma(2), sigma(3))``, exactly as the paper does
(e.g. ``Perm((3, 2, 1))`` is the flip ``p`` of eq:defpfl).  Composition ``p * q`` is ``p ∘ q``
(apply ``q`` first), and permutations act on points *from the right*:

    (x · sigma)_i = x_{sigma(i)},    so that    (x · pi) · sigma = x · (pi ∘ sigma).

This is the action used in ((sigma, Sigma) · f)(x) = f(x · sigma) · Sigma^{-1} (MATH.md §2).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import numpy as np

__all__ = ["Perm", "as_perm", "FLIP"]


class Perm:
    """An element of S₃ in one-line 1-based notation, e.g. ``Perm((3, 2, 1))``.

    Parameters
    ----------
    images:
        The tuple ``(sigma(1), sigma(2), sigma(3))``.  Anything that is not a permutation of
        ``(1, 2, 3)`` (wrong length, repeated or out-of-range entries, non-integers, booleans)
        raises ``ValueError`` naming the input.
    """

    __slots__ = ("_images",)

    def __init__(self, images: Iterable[int] | "Perm"):
        if isinstance(images, Perm):
            self._images = images._images
            return
        self._images = _validate(images)

    # -- the group structure ------------------------------------------------------------------
    def __call__(self, i: int) -> int:
        """sigma(i) for i in {1, 2, 3}."""
        if i not in (1, 2, 3) or isinstance(i, bool):
            raise ValueError(f"a permutation of {{1, 2, 3}} is evaluated at 1, 2 or 3, not {i!r}")
        return self._images[i - 1]

    def __mul__(self, other: "Perm | tuple[int, int, int]") -> "Perm":
        """Composition ``self ∘ other`` (apply ``other`` first)."""
        other = as_perm(other)
        return Perm(tuple(self(other(i)) for i in (1, 2, 3)))

    def __rmul__(self, other: tuple[int, int, int]) -> "Perm":
        return as_perm(other) * self

    def inverse(self) -> "Perm":
        inv = [0, 0, 0]
        for i, si in enumerate(self._images, start=1):
            inv[si - 1] = i
        return Perm(tuple(inv))

    @property
    def sign(self) -> int:
        """+1 for even, -1 for odd permutations (parity of the number of inversions)."""
        p = self._images
        inversions = sum(1 for i in range(3) for j in range(i + 1, 3) if p[i] > p[j])
        return -1 if inversions % 2 else 1

    def cycles(self) -> tuple[tuple[int, ...], ...]:
        """The non-trivial cycles, each starting at its smallest element."""
        seen: set[int] = set()
        out = []
        for start in (1, 2, 3):
            if start in seen:
                continue
            cycle = [start]
            seen.add(start)
            j = self(start)
            while j != start:
                cycle.append(j)
                seen.add(j)
                j = self(j)
            if len(cycle) > 1:
                out.append(tuple(cycle))
        return tuple(out)

    @property
    def is_identity(self) -> bool:
        return self._images == (1, 2, 3)

    def fixed_points(self) -> tuple[int, ...]:
        return tuple(i for i in (1, 2, 3) if self(i) == i)

    # -- the right action on points and on functions of three arguments -----------------------
    @property
    def index(self) -> tuple[int, int, int]:
        """0-based gather indices: ``x[..., perm.index] == x · perm``."""
        return tuple(i - 1 for i in self._images)  # type: ignore[return-value]

    def act(self, x: Any) -> Any:
        """The right action (x · sigma)_i = x_{sigma(i)} on arrays of shape (3,) or (..., 3)."""
        shape = getattr(x, "shape", None)
        if shape is None or len(shape) == 0 or shape[-1] != 3:
            raise ValueError(
                f"Perm.act expects an array of shape (3,) or (N, 3); got shape {shape!r}"
            )
        return x[..., list(self.index)]

    def act_args(self, f: Callable[[Any, Any, Any], Any]) -> Callable[[Any, Any, Any], Any]:
        """The permuted function (f · sigma)(y) = f(y · sigma) of three scalar arguments.

        For the flip p = (3, 2, 1) this is (f · p)(y1, y2, y3) = f(y3, y2, y1) (prop:volpotinv).
        The result is cached per (sigma, f), so that maps built from it (e.g. an inverse map) reuse
        compiled kernels; and (f · p) · p returns f itself.
        """
        return _permuted_function(self._images, f)

    # -- enumeration and display ---------------------------------------------------------------
    @staticmethod
    def all() -> tuple["Perm", ...]:
        """The six elements of S₃ in lexicographic one-line order."""
        return tuple(Perm(p) for p in itertools.permutations((1, 2, 3)))

    def one_line(self) -> str:
        return "({},{},{})".format(*self._images)

    def cycle_notation(self) -> str:
        cyc = self.cycles()
        return "".join("(" + " ".join(map(str, c)) + ")" for c in cyc) if cyc else "id"

    def __iter__(self) -> Iterator[int]:
        return iter(self._images)

    def __len__(self) -> int:
        return 3

    def __getitem__(self, k: int) -> int:
        return self._images[k]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Perm):
            return self._images == other._images
        if isinstance(other, tuple):
            return self._images == other
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self._images)

    def __repr__(self) -> str:
        return f"Perm({self._images!r}) = {self.cycle_notation()}"

    def __str__(self) -> str:
        return self.one_line()


def _validate(images: Any) -> tuple[int, int, int]:
    try:
        t = tuple(images)
    except TypeError:
        raise ValueError(
            f"{images!r} is not a permutation of (1, 2, 3) in one-line notation"
        ) from None
    ok = len(t) == 3 and all(
        isinstance(v, int) and not isinstance(v, bool) or _is_integral(v) for v in t
    )
    if ok:
        t = tuple(int(v) for v in t)
        ok = sorted(t) == [1, 2, 3]
    if not ok:
        raise ValueError(
            f"{images!r} is not a permutation of (1, 2, 3) in one-line 1-based notation "
            "(expected e.g. (3, 2, 1))"
        )
    return t  # type: ignore[return-value]


def _is_integral(v: Any) -> bool:
    # numpy integers are accepted; floats, bools and strings are not.
    try:
        return isinstance(v, np.integer)
    except ImportError:  # pragma: no cover
        return False


@functools.lru_cache(maxsize=4096)
def _permuted_function(images: tuple[int, int, int], f: Callable) -> Callable:
    if images == (1, 2, 3):
        return f
    base = getattr(f, "_vpforms_base", None)
    if base is not None:  # (f·q)·s = f·(s∘q), since (y·s)·q = y·(s∘q)
        q, g = base
        return _permuted_function((Perm(images) * Perm(q))._images, g)
    i, j, k = (v - 1 for v in images)

    def permuted(*y: Any) -> Any:
        return f(y[i], y[j], y[k])

    permuted.__name__ = f"{getattr(f, '__name__', 'f')}·({images[0]},{images[1]},{images[2]})"
    permuted._vpforms_base = (images, f)  # type: ignore[attr-defined]
    return permuted


def as_perm(p: "Perm | Iterable[int]") -> Perm:
    """Coerce a tuple (or Perm) to a :class:`Perm`, validating it."""
    return p if isinstance(p, Perm) else Perm(p)


#: The flip p = (1,2,3) ↦ (3,2,1) of eq:defpfl: (φ·p)(y1, y2, y3) = φ(y3, y2, y1).
FLIP = Perm((3, 2, 1))

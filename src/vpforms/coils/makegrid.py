"""Reader and writer of the MAKEGRID / STELLOPT ``coils.*`` filament format.

The format::

    periods 5
    begin filament
    mirror NIL
        x y z I
        ...
        x y z 0.0  1  CoilName
    end

After the header (``periods N``, ``begin filament``, an optional ``mirror`` line), each coil is a
run of lines ``x y z I`` (m, A; the same current on every line of the coil) closed by a line
``x y z 0.0 group [name]`` whose point repeats the first one (MAKEGRID's segment from the closing
point carries no current). A closing point equal to the first is dropped by :class:`Coil`, which
closes its polyline itself; one that differs is kept as a vertex (the coil is closed from it back to
the first point). Fortran exponents (``1.0D+00``) are read.

:func:`write_makegrid` writes the floats with ``repr`` (the shortest string that reads back to the
same float64), so write → read reproduces coordinates and currents exactly.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from .._errors import VPFormsError
from ._coilset import Coil, CoilSet

__all__ = ["CoilFileError", "MAX_COORDINATE", "MAX_CURRENT", "read_makegrid", "write_makegrid"]

#: the largest |x|, |y|, |z| (m) a coils file may hold: 10 km, far beyond any device (ITER's coils
#: lie within ~15 m of its axis); a larger value is a unit error (mm, µm) or a corrupt number, and
#: near 1e308 the segments' field overflows
MAX_COORDINATE = 1.0e4
#: the largest |I| (A) a coil may carry: 1 GA, above any coil (the largest superconducting coils
#: carry ~1e7–1e8 ampere-turns); a larger current is an error, which made a trace recover every step
MAX_CURRENT = 1.0e9


class CoilFileError(VPFormsError, ValueError):
    """A malformed coils file; the message names the file, the line (1-based) and what is wrong."""

    def __init__(self, path: str | os.PathLike, line: int | None, reason: str):
        self.path, self.line, self.reason = str(path), line, reason
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {reason}")


def _float(tok: str, path: Path, lineno: int, what: str) -> float:
    try:
        v = float(tok.replace("D", "e").replace("d", "e"))
    except ValueError:
        raise CoilFileError(path, lineno, f"{what} is not a number: {tok!r}") from None
    if not math.isfinite(v):
        raise CoilFileError(path, lineno, f"{what} is not finite: {tok!r}")
    return v


def _check_bounds(path: Path, lineno: int, xyz: tuple, current: float) -> None:
    """Refuse coordinates beyond :data:`MAX_COORDINATE` and a current beyond :data:`MAX_CURRENT`."""
    for name, v in zip("xyz", xyz):
        if abs(v) > MAX_COORDINATE:
            raise CoilFileError(path, lineno, f"{name} = {v:g} m is beyond ±{MAX_COORDINATE:g} m (MAX_COORDINATE): "
                                              "not a coordinate of a coil (a unit error or a corrupt number?)")
    if abs(current) > MAX_CURRENT:
        raise CoilFileError(path, lineno, f"the current {current:g} A is beyond ±{MAX_CURRENT:g} A (MAX_CURRENT): "
                                          "not a coil current (a unit error or a corrupt number?)")


def read_makegrid(path: str | os.PathLike) -> CoilSet:
    """Read a MAKEGRID ``coils.*`` file (module docstring) into a :class:`CoilSet`.

    ``nfp`` is the file's ``periods``; ``stellsym`` is False (the format does not say).

    Raises
    ------
    CoilFileError
        (a ``ValueError``) naming the file, the line and what is wrong: an empty file, a missing
        ``periods`` / ``begin filament`` / ``end``, a line with the wrong number of fields,
        a non-numeric or non-finite value, a coordinate beyond :data:`MAX_COORDINATE` or a current
        beyond :data:`MAX_CURRENT`, a file whose every current is 0, a current that changes within a coil, a closing line
        with a non-zero current, a coil not closed by a zero-current line (a truncated file),
        a degenerate coil (too few distinct points, a zero-length segment).
    """
    path = Path(path)
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise CoilFileError(path, None, f"not a text file ({exc.reason})") from None
    lines = [(k + 1, ln.split()) for k, ln in enumerate(text.splitlines())]
    lines = [(k, f) for k, f in lines if f]  # blank lines are skipped
    if not lines:
        raise CoilFileError(path, None, "empty file (expected 'periods N', 'begin filament', coils, 'end')")
    it = iter(lines)

    lineno, f = next(it)
    if f[0].lower() != "periods":
        raise CoilFileError(path, lineno, f"expected 'periods N' as the first line; got {' '.join(f)!r}")
    if len(f) != 2:
        raise CoilFileError(path, lineno, f"'periods' takes one integer; got {' '.join(f)!r}")
    try:
        nfp = int(f[1])
    except ValueError:
        raise CoilFileError(path, lineno, f"periods must be an integer; got {f[1]!r}") from None
    if nfp < 1:
        raise CoilFileError(path, lineno, f"periods must be a positive integer; got {nfp}")

    nxt = next(it, None)
    if nxt is None or [t.lower() for t in nxt[1]] != ["begin", "filament"]:
        k = nxt[0] if nxt else lineno
        got = f"got {' '.join(nxt[1])!r}" if nxt else "the file ends"
        raise CoilFileError(path, k, f"expected 'begin filament' after 'periods'; {got}")

    coils: list[Coil] = []
    pts: list[list[float]] = []
    current: float | None = None
    first_line = None
    ended = False
    for lineno, f in it:
        key = f[0].lower()
        if key == "mirror" and not coils and not pts:
            if len(f) != 2:
                raise CoilFileError(path, lineno, f"'mirror' takes one word (e.g. NIL); got {' '.join(f)!r}")
            continue
        if key == "end":
            if pts:
                raise CoilFileError(path, lineno, f"'end' inside the coil begun on line {first_line}: "
                                                  "the coil is not closed by a zero-current line 'x y z 0.0 group name'")
            if len(f) != 1:
                raise CoilFileError(path, lineno, f"unexpected text after 'end': {' '.join(f[1:])!r}")
            ended = True
            break
        if len(f) not in (4, 5, 6):
            raise CoilFileError(path, lineno, f"expected 'x y z I' (4 fields) or 'x y z 0.0 group [name]' (5–6); "
                                              f"got {len(f)} fields: {' '.join(f)!r}")
        x, y, z, cur = (_float(t, path, lineno, w) for t, w in zip(f[:4], ("x", "y", "z", "the current")))
        _check_bounds(path, lineno, (x, y, z), cur)
        if not pts:
            first_line = lineno
        if len(f) == 4:
            if current is not None and cur != current:
                raise CoilFileError(path, lineno, f"the current changes within the coil begun on line {first_line}: "
                                                  f"{cur!r} after {current!r}")
            current = cur
            pts.append([x, y, z])
            continue
        # the closing line: x y z 0.0 group [name]
        if cur != 0.0:
            raise CoilFileError(path, lineno, f"a closing line (with a group number) must carry current 0; got {cur!r}")
        if current is None:
            raise CoilFileError(path, lineno, "a closing line without any point of a coil before it")
        try:
            group = int(f[4])
        except ValueError:
            raise CoilFileError(path, lineno, f"the group number must be an integer; got {f[4]!r}") from None
        name = f[5] if len(f) == 6 else ""
        pts.append([x, y, z])
        try:
            coils.append(Coil(np.array(pts), current, group, name))
        except ValueError as exc:
            raise CoilFileError(path, lineno, f"coil begun on line {first_line}: {exc}") from None
        pts, current = [], None
    if not ended:
        last = lines[-1][0]
        if pts:
            raise CoilFileError(path, last, f"the file ends inside the coil begun on line {first_line} "
                                            "(truncated? no closing zero-current line and no 'end')")
        raise CoilFileError(path, last, "missing 'end' (truncated file?)")
    rest = next(it, None)
    if rest is not None:
        raise CoilFileError(path, rest[0], f"unexpected text after 'end': {' '.join(rest[1])!r}")
    if not coils:
        raise CoilFileError(path, lineno, "no coils between 'begin filament' and 'end'")
    if all(c.current == 0 for c in coils):
        raise CoilFileError(path, None, f"every coil carries current 0 ({len(coils)} coil(s)): the file has no "
                                        "field (a coils file gives each coil's current on its point lines: x y z I)")
    return CoilSet(coils, nfp=nfp)


def write_makegrid(coilset: CoilSet, path: str | os.PathLike) -> None:
    """Write ``coilset`` as a MAKEGRID ``coils.*`` file (module docstring), ``periods`` = nfp.

    Every coil is written in full (no symmetry is used), its points with its current, then the first
    point again with current 0, its group and name. Floats are written with ``repr``: exact.
    """
    if not isinstance(coilset, CoilSet):
        raise ValueError(f"write_makegrid needs a CoilSet; got {type(coilset).__name__}")  # noqa: TRY004
    out = [f"periods {coilset.nfp}", "begin filament", "mirror NIL"]
    for c in coilset:
        cur = repr(c.current)
        for p in c.points:
            out.append(f"  {float(p[0])!r:>24} {float(p[1])!r:>24} {float(p[2])!r:>24} {cur:>24}")
        p = c.points[0]
        tail = f" {c.group} {c.name}" if c.name else f" {c.group}"
        out.append(f"  {float(p[0])!r:>24} {float(p[1])!r:>24} {float(p[2])!r:>24} {'0.0':>24}{tail}")
    out.append("end")
    Path(path).write_text("\n".join(out) + "\n")

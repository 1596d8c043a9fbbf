"""Benchmark numbers in README.md and docs/*.md are quoted from the results files, never copied.

A document asks for a part of a committed results file with a pair of marker lines::

    <!-- quote: benchmarks/native/results_native.md#table:1 -->
    (generated: the first table of results_native.md)
    <!-- /quote -->

and this script writes what lies between them. The path is relative to the repository root; what
follows ``#`` selects a part of the file (no ``#``: the whole file):

* nothing — the whole file less its ``# title`` line;
* ``table:N`` — the N-th Markdown table (1-based: a run of lines that start with ``|``);
* ``section:SLUG`` — the text under the heading whose slug is SLUG (lower case, punctuation
  dropped, spaces → ``-``, as GitHub and MkDocs make anchors: ``## 1. Accuracy and cost`` is
  ``1-accuracy-and-cost``), up to the next heading of the same or a higher level, heading excluded;
* selectors compose left to right with ``/``: ``section:pick-per-accuracy-target/table:2`` is the
  second table of that section.

The text is quoted verbatim (stripped of blank lines at both ends), with one blank line after the
opening marker and one before the closing one, so that every Markdown renderer sees a table there.

    python benchmarks/quote.py            # check: exit 1 and a diff per stale block
    python benchmarks/quote.py --write    # rewrite every block of README.md and docs/**/*.md
    python benchmarks/quote.py --list     # the blocks and what they quote

``tests/test_docs_quotes.py`` (fast tier) fails when a block differs from its results file or when
a table row of a results file is copied into a document outside a block; ``docs/hooks.py`` warns
about stale blocks at site build (an error under ``mkdocs build --strict``) and expands
``<!-- vpforms:include FILE#SELECTOR -->`` with the same selectors. Only the standard library is
used, so the test and the hooks import this file by path.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parent.parent

START = re.compile(r"^<!--\s*quote:\s*(\S+)\s*-->\s*$")
END = re.compile(r"^<!--\s*/quote\s*-->\s*$")
_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
_FENCE = re.compile(r"^\s*(```|~~~)")


class QuoteError(ValueError):
    """A marker that cannot be resolved: unclosed block, missing file, selector that selects nothing."""


def slug(heading: str) -> str:
    """The anchor of a heading as GitHub and MkDocs' toc make it (for ASCII and most Unicode text)."""
    s = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"\s+", "-", s)


def _strip_blank(lines: list[str]) -> list[str]:
    while lines and not lines[0].strip():
        lines = lines[1:]
    while lines and not lines[-1].strip():
        lines = lines[:-1]
    return lines


def _headings(lines: list[str]) -> list[tuple[int, int, str]]:
    """(line index, level, text) of the ATX headings outside code fences."""
    out, fenced = [], False
    for i, line in enumerate(lines):
        if _FENCE.match(line):
            fenced = not fenced
            continue
        m = None if fenced else _HEADING.match(line)
        if m:
            out.append((i, len(m.group(1)), m.group(2)))
    return out


def _tables(lines: list[str]) -> list[list[str]]:
    tables, cur = [], []
    for line in lines + [""]:
        if line.lstrip().startswith("|"):
            cur.append(line)
        elif cur:
            tables.append(cur)
            cur = []
    return tables


def _select(lines: list[str], step: str, where: str) -> list[str]:
    kind, _, arg = step.partition(":")
    if kind == "table":
        tables = _tables(lines)
        if not arg.isdigit() or not 1 <= int(arg) <= len(tables):
            raise QuoteError(f"{where}: {step!r}: there are {len(tables)} tables (table:1 … table:{len(tables)})")
        return tables[int(arg) - 1]
    if kind == "section":
        heads = _headings(lines)
        found = [(i, lev) for i, lev, text in heads if slug(text) == arg]
        if len(found) != 1:
            known = ", ".join(slug(text) for _, _, text in heads)
            raise QuoteError(f"{where}: {step!r}: {'no' if not found else len(found)} headings with this "
                             f"slug (there are: {known})")
        i, lev = found[0]
        end = next((j for j, level, _ in heads if j > i and level <= lev), len(lines))
        return _strip_blank(lines[i + 1:end])
    raise QuoteError(f"{where}: unknown selector {step!r} (table:N, section:SLUG, joined by '/')")


def extract(text: str, selector: str = "", where: str = "") -> str:
    """The part of ``text`` (a results file) that ``selector`` names, without blank lines at its ends."""
    lines = text.splitlines()
    if not selector:
        if lines and _HEADING.match(lines[0]) and lines[0].startswith("# "):
            lines = lines[1:]
    else:
        for step in selector.split("/"):
            lines = _select(lines, step, where or selector)
    lines = _strip_blank(lines)
    if not lines:
        raise QuoteError(f"{where or selector}: selects nothing")
    return "\n".join(lines) + "\n"


def source(ref: str, root: Path = ROOT) -> str:
    """The quoted text of ``ref`` = ``path[#selector]``, path relative to ``root``."""
    path, _, selector = ref.partition("#")
    file = root / path
    if not file.is_file():
        raise QuoteError(f"{ref}: no file {path} in {root}")
    return extract(file.read_text(encoding="utf-8"), selector, ref)


class Block(NamedTuple):
    """One marked block of a document: its source ``ref`` and the lines between the markers
    (a NamedTuple, not a dataclass: this file is loaded by path, outside ``sys.modules``)."""

    ref: str
    start: int  # 1-based line of the opening marker
    end: int  # 1-based line of the closing marker
    body: str  # the text between the two marker lines, as it is now


def blocks(text: str, where: str = "") -> list[Block]:
    """The quote blocks of a document (nested, unclosed or unopened markers are errors; markers in
    a code fence are text)."""
    out, lines, open_at, fenced = [], text.splitlines(), None, False
    for k, line in enumerate(lines, 1):
        if _FENCE.match(line) and open_at is None:
            fenced = not fenced
        if fenced:
            continue
        m, e = START.match(line), END.match(line)
        if m:
            if open_at is not None:
                raise QuoteError(f"{where}:{k}: quote block opened inside the block of line {open_at[0]}")
            open_at = (k, m.group(1))
        elif e:
            if open_at is None:
                raise QuoteError(f"{where}:{k}: <!-- /quote --> without an opening marker")
            body = lines[open_at[0]:k - 1]
            out.append(Block(open_at[1], open_at[0], k, "\n".join(body) + ("\n" if body else "")))
            open_at = None
    if open_at is not None:
        raise QuoteError(f"{where}:{open_at[0]}: quote block of {open_at[1]} is never closed (<!-- /quote -->)")
    return out


def body_for(ref: str, root: Path = ROOT) -> str:
    """What a block quoting ``ref`` must contain between its markers."""
    return "\n" + source(ref, root) + "\n"


def render(text: str, root: Path = ROOT, where: str = "") -> str:
    """``text`` with every quote block regenerated from its results file."""
    bl = blocks(text, where)
    if not bl:
        return text
    lines = text.splitlines(keepends=True)
    out, pos = [], 0
    for b in bl:
        out += lines[pos:b.start]  # up to and including the opening marker
        out.append(body_for(b.ref, root))
        pos = b.end - 1  # the closing marker
    out += lines[pos:]
    return "".join(out)


def stale(text: str, root: Path = ROOT, where: str = "") -> list[str]:
    """One message (marker, line, unified diff) per block of ``text`` that differs from its source."""
    msgs = []
    for b in blocks(text, where):
        want = body_for(b.ref, root)
        if b.body != want:
            diff = "".join(difflib.unified_diff(
                b.body.splitlines(keepends=True), want.splitlines(keepends=True),
                fromfile=f"{where}:{b.start + 1} (in the document)", tofile=f"{b.ref.split('#')[0]} (generated)"))
            msgs.append(f"{where}:{b.start}: <!-- quote: {b.ref} --> differs from the results file "
                        f"(run `python benchmarks/quote.py --write`):\n{diff}")
    return msgs


def results_rows(root: Path = ROOT) -> dict[str, str]:
    """Every table row (header and body, not the ``|---|`` rule) of benchmarks/<topic>/results*.md → its file."""
    rows: dict[str, str] = {}
    for f in sorted((root / "benchmarks").rglob("results*.md")):
        for line in f.read_text(encoding="utf-8").splitlines():
            line = line.strip()
            if line.startswith("|") and not re.fullmatch(r"[|\s:-]+", line):
                rows.setdefault(line, f.relative_to(root).as_posix())
    return rows


def copies(text: str, root: Path = ROOT, where: str = "", rows: dict[str, str] | None = None) -> list[str]:
    """Table rows of a results file that ``text`` holds outside quote blocks (hand-copied numbers)."""
    rows = results_rows(root) if rows is None else rows
    inside = set()
    for b in blocks(text, where):
        inside.update(range(b.start, b.end + 1))
    return [f"{where}:{k}: row of {rows[line.strip()]} copied by hand (quote it instead): {line.strip()}"
            for k, line in enumerate(text.splitlines(), 1)
            if k not in inside and line.strip() in rows]


def documents(root: Path = ROOT) -> list[Path]:
    """README.md and every page of docs/ (recursively)."""
    docs = sorted((root / "docs").rglob("*.md"))
    return [p for p in [root / "README.md", *docs] if p.is_file()]


def _rel(path: Path, root: Path) -> str:
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path, help="documents (default: README.md and docs/**/*.md)")
    ap.add_argument("--write", action="store_true", help="rewrite the stale blocks")
    ap.add_argument("--list", action="store_true", help="list the blocks and what they quote")
    ap.add_argument("--root", type=Path, default=ROOT, help="repository root (paths in markers are relative to it)")
    args = ap.parse_args(argv)
    files = args.files or documents(args.root)
    problems, rows = [], results_rows(args.root)
    for path in files:
        name = _rel(path, args.root)
        text = path.read_text(encoding="utf-8")
        try:
            if args.list:
                for b in blocks(text, name):
                    print(f"{name}:{b.start}: {b.ref}")
                continue
            if args.write:
                new = render(text, args.root, name)
                if new != text:
                    path.write_text(new, encoding="utf-8")
                    print(f"rewritten: {name}")
            else:
                problems += stale(text, args.root, name)
            problems += copies(path.read_text(encoding="utf-8"), args.root, name, rows)
        except QuoteError as exc:
            problems.append(str(exc))
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

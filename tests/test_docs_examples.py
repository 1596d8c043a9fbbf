"""The documentation's examples run as written (issue #41 item 5): every fenced code block of
README.md and docs/**/*.md that claims to run is executed (verification tier), and every block
is classified as run, data or exempt with a reason (fast tier).

What runs (docs/testing.md, "Code blocks of the documentation"):

* every ```python block; the python blocks of one page run in order in one namespace, in a fresh
  Python process per page whose working directory is an empty temporary directory, with this
  checkout's ``src`` first on ``PYTHONPATH`` and ``MPLBACKEND=Agg``;
* every ```bash / ```sh / ```shell / ```console block (in a console block, the lines after ``$ ``):
  each command must be ``vpforms …`` (run with the environment's ``vpforms`` entry point) or
  ``python …`` / ``python3 …`` (this interpreter), no pipes, redirections or ``&&``; commands and
  python blocks run in the page's order, in the same directory;
* a block preceded by ``<!-- file: NAME -->`` is data: it is written to NAME in that directory
  before anything of the page runs (a TOML field file that a command reads);
* a block preceded by ``<!-- same as: PAGE -->`` is not run again: the same text runs on PAGE
  (checked, fast tier: README.md's examples repeated on the site);
* a block preceded by ``<!-- not run: REASON -->`` is not run; the reason is required.

Other blocks (```text, ```toml, …) are output or data and do not run, but ``vpforms`` commands
in them are an error: a CLI example is tagged as shell so that it runs, or exempted with a reason.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PYTHON = ("python", "py")
SHELL = ("bash", "sh", "shell", "console")

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`]*?)[ \t]*$")
_MARKER = re.compile(r"^\s*<!--\s*(?P<kind>not run|file|same as)\s*(?::(?P<arg>.*?))?\s*-->\s*$")
_OPERATOR = re.compile(r"^[();<>|&]+$")
_PROGRAMS = {"vpforms": "vpforms", "python": "python", "python3": "python"}


class DocsBlockError(ValueError):
    """A code block the docs test cannot classify (unterminated, unmarked, marker without reason)."""


@dataclass
class Block:
    """One fenced code block of a page: its language, first line (1-based, the fence's line + 1),
    text (dedented by the fence's indentation) and how it is treated."""

    page: str
    line: int
    lang: str
    text: str
    kind: str = "other"  # "python", "shell", "file", "exempt", "same", "other"
    reason: str = ""  # the exemption's reason, a data block's file name, the page of the same block
    commands: list = field(default_factory=list)  # shell blocks: [(line, argv)]

    @property
    def where(self) -> str:
        first = next((ln for ln in self.text.splitlines() if ln.strip()), "")
        return f"{self.page}:{self.line}: ```{self.lang} block starting {first.strip()!r}"


def _commands(block: Block) -> list:
    """The commands of a shell block as (line, argv), continuation lines joined, comments dropped;
    a DocsBlockError for anything but a plain ``vpforms``/``python`` command."""
    out, pending, start = [], "", None
    for k, raw in enumerate(block.text.splitlines()):
        line = raw.rstrip()
        if block.lang == "console" and not pending:
            if not line.lstrip().startswith("$ "):
                continue  # printed output
            line = line.lstrip()[2:]
        start = block.line + k if not pending else start
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        line, pending = pending + line, ""
        lex = shlex.shlex(line, posix=True, punctuation_chars=True)
        lex.whitespace_split, lex.commenters = True, "#"
        try:
            argv = list(lex)
        except ValueError as e:
            raise DocsBlockError(f"{block.page}:{start}: cannot split the command ({e}): {line!r}") from None
        if not argv:
            continue
        if argv[0] not in _PROGRAMS or any(_OPERATOR.match(t) for t in argv):
            raise DocsBlockError(
                f"{block.page}:{start}: {line.strip()!r} is not a plain `vpforms …` or `python …` command; "
                "rewrite it, or mark the block <!-- not run: REASON -->")
        out.append((start, argv))
    if pending:
        raise DocsBlockError(f"{block.page}:{start}: the block ends inside a continued line")
    return out


def extract(text: str, page: str = "<text>") -> list[Block]:
    """The fenced code blocks of a Markdown text, classified (see the module docstring).

    Raises DocsBlockError for an unterminated fence, a marker without a reason or file name, a
    marker not followed by a block, a shell block with other commands and no exemption, and
    ``vpforms`` commands in a block that is neither shell nor exempt."""
    lines, blocks, k, marker = text.splitlines(), [], 0, None
    while k < len(lines):
        m, mk = _FENCE.match(lines[k]), _MARKER.match(lines[k])
        if mk:
            if marker:
                raise DocsBlockError(f"{page}:{marker[0]}: <!-- {marker[1]} --> is not followed by a code block")
            arg = (mk["arg"] or "").strip()
            if not arg:
                what = {"not run": "a reason", "file": "a file name", "same as": "a page"}[mk["kind"]]
                raise DocsBlockError(f"{page}:{k + 1}: <!-- {mk['kind']}: … --> needs {what}")
            if mk["kind"] == "file" and (Path(arg).name != arg or arg in (".", "..")):
                raise DocsBlockError(f"{page}:{k + 1}: <!-- file: {arg} -->: a plain file name, no directory")
            marker = (k + 1, mk["kind"], arg)
        elif m:
            indent, fence = m["indent"], m["fence"]
            close = re.compile(rf"^[ \t]*{re.escape(fence[0])}{{{len(fence)},}}[ \t]*$")
            end = next((j for j in range(k + 1, len(lines)) if close.match(lines[j])), None)
            if end is None:
                raise DocsBlockError(f"{page}:{k + 1}: the fence {lines[k].strip()!r} is never closed")
            # the block's text without the fence's own indentation (a block in a list item)
            body = [ln[len(indent):] if ln.startswith(indent) else ln.lstrip() for ln in lines[k + 1:end]]
            b = Block(page, k + 2, (m["info"].split() or [""])[0].lower(), "\n".join(body) + "\n")
            if marker:
                b.kind = {"not run": "exempt", "file": "file", "same as": "same"}[marker[1]]
                b.reason = marker[2]
            elif b.lang in PYTHON:
                b.kind = "python"
            elif b.lang in SHELL:
                b.kind, b.commands = "shell", _commands(b)
            elif any(re.match(r"(\$ )?vpforms\s", ln.strip()) for ln in body):
                raise DocsBlockError(f"{b.where}: vpforms commands in a ```{b.lang or 'plain'} block; "
                                     "tag it ```bash so that it runs, or mark it <!-- not run: REASON -->")
            blocks.append(b)
            marker, k = None, end
        elif marker and lines[k].strip():
            raise DocsBlockError(f"{page}:{marker[0]}: <!-- {marker[1]} --> is not followed by a code block")
        k += 1
    if marker:
        raise DocsBlockError(f"{page}:{marker[0]}: <!-- {marker[1]} --> is not followed by a code block")
    return blocks


def check_pages(pages: dict[str, list[Block]]) -> None:
    """DocsBlockError where an exemption's reason says nothing (under 10 characters) or a
    ``same as`` block has no block that runs with the same text on the page it names."""
    for blocks in pages.values():
        for b in blocks:
            if b.kind == "exempt" and len(b.reason) < 10:
                raise DocsBlockError(f"{b.where}: <!-- not run: {b.reason} -->: say why it is not run")
            if b.kind == "same" and not any(o.text == b.text and o.kind in ("python", "shell")
                                            for o in pages.get(b.reason, ())):
                raise DocsBlockError(f"{b.where}: no block that runs on {b.reason!r} has this text")


def _page_id(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def page_blocks(path: Path) -> list[Block]:
    return extract(path.read_text(encoding="utf-8"), _page_id(path))


# ------------------------------------------------------------------------------------ fast tier
def test_every_block_of_the_docs_is_classified():
    """Every page parses; every block is run, data or exempt with a reason; and the pages that
    carry examples do run some (the extractor finds them)."""
    pages = {_page_id(p): page_blocks(p) for p in PAGES}  # raises on an unclassified block
    check_pages(pages)
    kinds = {}
    for b in (b for blocks in pages.values() for b in blocks):
        kinds.setdefault(b.kind, []).append(b)
    for path in PAGES:  # every fence line opens or closes a block found (no nested fences in the docs)
        fences = sum(1 for ln in path.read_text(encoding="utf-8").splitlines() if ln.lstrip().startswith("```"))
        assert fences == 2 * len(pages[_page_id(path)]), f"{_page_id(path)}: {fences} fence lines"
    runs = {b.page for b in kinds.get("python", []) + kinds.get("shell", [])}
    for page in ("README.md", "docs/getting-started.md", "docs/fieldlines.md", "docs/cli-fields.md"):
        assert page in runs, f"{page}: no block runs"


_SYNTHETIC = """\
# Title

1. A step in a list:

    ```python
    x = 1
    ```

2. A command:

    ```console
    $ vpforms cases --format json \\
        --quiet   # a comment
    output line
    ```

<!-- not run: needs a cluster -->

```python
import dask_jobqueue
```

<!-- file: f.toml -->
```toml
name = "f"
```

```text
[vpforms] printed output
```
"""


def test_extractor_on_a_synthetic_page():
    blocks = extract(_SYNTHETIC, "t.md")
    assert [(b.kind, b.line) for b in blocks] == [("python", 6), ("shell", 12), ("exempt", 20),
                                                   ("file", 25), ("other", 29)]
    assert blocks[0].text == "x = 1\n"  # found in the list item, its indentation removed
    assert blocks[1].commands == [(12, ["vpforms", "cases", "--format", "json", "--quiet"])]
    assert blocks[2].reason == "needs a cluster" and blocks[3].reason == "f.toml"


@pytest.mark.parametrize("other, match", [
    ("```bash\nvpforms cases\n```\n", None),
    ("```bash\nvpforms cases  \n```\n", "no block that runs on 'a.md' has this text"),  # not the same text
    ("<!-- not run: installs a package -->\n```bash\nvpforms cases\n```\n", "no block that runs on 'a.md'"),
])
def test_same_as_names_a_block_that_runs(other, match):
    same = "<!-- same as: a.md -->\n```bash\nvpforms cases\n```\n"
    pages = {"a.md": extract(other, "a.md"), "b.md": extract(same, "b.md")}
    assert pages["b.md"][0].kind == "same"
    if match is None:
        check_pages(pages)
    else:
        with pytest.raises(DocsBlockError, match=match):
            check_pages(pages)
    with pytest.raises(DocsBlockError, match="say why"):
        check_pages({"c.md": extract("<!-- not run: slow -->\n```python\nx\n```\n", "c.md")})


@pytest.mark.parametrize("text, match", [
    ("```python\nx = 1\n", "t.md:1: the fence '```python' is never closed"),
    ("````python\nx = 1\n```\n", "never closed"),  # a shorter closing fence does not close
    ("<!-- not run -->\n```python\nx\n```\n", "t.md:1: .* needs a reason"),
    ("<!-- not run:   -->\n```python\nx\n```\n", "needs a reason"),
    ("<!-- file: ../x -->\n```toml\nx\n```\n", "a plain file name"),
    ("<!-- not run: slow -->\nsome text\n```python\nx\n```\n", "t.md:1: .* is not followed by a code block"),
    ("text\n<!-- not run: slow -->\n", "is not followed by a code block"),
    ("```bash\npip install vpforms\n```\n", "t.md:2: 'pip install vpforms' is not a plain"),
    ("```bash\nvpforms run | tail -1\n```\n", "is not a plain"),
    ("```sh\nvpforms run \\\n", "never closed"),
    ("```sh\nvpforms run \\\n```\n", "ends inside a continued line"),
    ("```text\nvpforms cases\n```\n", "vpforms commands in a ```text block"),
])
def test_extractor_refuses(text, match):
    with pytest.raises(DocsBlockError, match=match):
        extract(text, "t.md")


# ---------------------------------------------------------------------------- verification tier
# The page runner: executes a page's items in order in one process (python blocks in one namespace,
# compiled as the page's file at its line numbers, so a traceback shows the Markdown line; commands
# as subprocesses) and says which block it is in before each.
_RUNNER = textwrap.dedent(
    """
    import json, subprocess, sys, time
    items = json.load(open(sys.argv[1]))
    ns = {"__name__": "__main__"}
    for it in items:
        print("@@block " + json.dumps([it["where"], it["line"]]), flush=True)
        t = time.perf_counter()
        if it["kind"] == "python":
            exec(compile("\\n" * (it["line"] - 1) + it["text"], it["file"], "exec"), ns)
        else:
            p = subprocess.run(it["argv"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            print(p.stdout[-4000:], flush=True)
            if p.returncode:
                sys.exit(f"exit code {p.returncode}: {' '.join(it['argv'])}")
        print("@@time " + json.dumps([it["where"], time.perf_counter() - t]), flush=True)
    """
)


def _program(name: str) -> list[str]:
    if name == "python":
        return [sys.executable]
    exe = shutil.which("vpforms", path=str(Path(sys.executable).parent))  # the environment's entry point
    return [exe] if exe else [sys.executable, "-m", "vpforms.cli"]


def _runnable_pages():
    out = []
    for path in PAGES:
        try:
            runs = any(b.kind in ("python", "shell") for b in page_blocks(path))
        except DocsBlockError:
            runs = True  # the test then reports the error (collection goes on)
        if runs:
            out.append(pytest.param(path, id=_page_id(path)))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("path", _runnable_pages())
def test_docs_examples_run(path, tmp_path):
    """The page's python blocks and commands run without an error, in order, in an empty
    directory (its data blocks written there first)."""
    items = []
    for b in page_blocks(path):
        if b.kind == "file":
            (tmp_path / b.reason).write_text(b.text, encoding="utf-8")
        elif b.kind == "python":
            items.append({"kind": "python", "file": str(path), "line": b.line, "text": b.text, "where": b.where})
        elif b.kind == "shell":
            items += [{"kind": "shell", "line": line, "where": f"{b.page}:{line}: the command {shlex.join(argv)!r}",
                       "argv": _program(_PROGRAMS[argv[0]]) + argv[1:]} for line, argv in b.commands]
    (tmp_path / "items.json").write_text(json.dumps(items), encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _RUNNER, str(tmp_path / "items.json")], cwd=tmp_path, env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=900)
    times = [json.loads(ln[7:]) for ln in p.stdout.splitlines() if ln.startswith("@@time ")]
    print(f"{_page_id(path)}: {time.perf_counter() - t0:.1f} s")
    for where, sec in times:
        print(f"  {sec:7.1f} s  {where}")
    if p.returncode:
        started = [json.loads(ln[8:]) for ln in p.stdout.splitlines() if ln.startswith("@@block ")]
        where = started[-1][0] if started else _page_id(path)
        out = "\n".join(ln for ln in p.stdout.splitlines() if not ln.startswith("@@"))
        pytest.fail(f"{where} failed:\n{out[-6000:]}", pytrace=False)

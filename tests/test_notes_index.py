"""notes/README.md, the index of the closing notes (``python notes/index.py``), lists every note, and
its module column is what the notes' text names."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "notes" / "index.py"
if not SCRIPT.exists():
    pytest.skip("notes/ is not shipped with this install", allow_module_level=True)

_spec = importlib.util.spec_from_file_location("vpforms_notes_index", SCRIPT)
index = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(index)


def test_the_index_lists_every_note():
    assert index.main(["--check"]) == 0, "run `python notes/index.py`"
    text = (ROOT / "notes" / "README.md").read_text(encoding="utf-8")
    notes = sorted((ROOT / "notes").glob("*.md"))
    assert len(notes) > 1 and all(f"[{p.name}]({p.name})" in text for p in notes if p.name != "README.md")


def test_modules_named_by_path_or_dotted_name_are_grouped_by_package():
    known = ["_integrate.py", "fieldlines/_sections.py", "fieldlines/__init__.py",
             "backends/native/runner.py", "backends/jax/runner.py", "symbolic/forms.py"]
    text = ("We changed `src/vpforms/_integrate.py`, `_sections.py` and `vpforms.symbolic.forms.thing`; "
            "runner.py is ambiguous, tests/test_x.py and benchmarks/bench_y.py are not modules, "
            "gone.py no longer exists; see vpforms.fieldlines.")
    assert index.modules(text, known) == ["_integrate.py", "fieldlines", "symbolic"]
    assert index.modules("backends/native/runner.py", known) == ["backends/native"]


def test_issues_and_session_come_from_the_title_and_the_file_name():
    assert index.issues("issue-12-fixes.md", "Issue #12 item 3, see #9") == [9, 12]
    assert index.issues("closing-note-session31.md", "peers (#21), coils (#20)") == [20, 21]
    assert (index.session("closing-note-session31.md"), index.session("issue-2.md")) == ("31", "—")

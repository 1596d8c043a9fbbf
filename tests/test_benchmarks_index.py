"""docs/benchmarks.md lists every benchmark script, and is what ``benchmarks/index.py`` makes of the
scripts and their results files today (a new script without an entry, or a results file rerun
without the page, fails here: ``python benchmarks/index.py`` rewrites the page)."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
INDEX = ROOT / "benchmarks" / "index.py"
if not INDEX.exists():
    pytest.skip("benchmarks/ is not shipped with this install", allow_module_level=True)

_spec = importlib.util.spec_from_file_location("vpforms_bench_index", INDEX)
index = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(index)


def _page() -> str:
    return (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")


def test_the_page_lists_every_script_with_its_command():
    """Every .py file under benchmarks/ (found on disk, not by the index) has a row naming it; the
    row of a topic script gives a command that names the script's own path."""
    page = _page()
    rows = {line.split("|")[1].strip(" `"): line for line in page.splitlines() if line.startswith("| `benchmarks/")}
    on_disk = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "benchmarks").rglob("*.py")
                     if "__pycache__" not in p.parts)
    assert on_disk and not [p for p in on_disk if p not in rows], "run `python benchmarks/index.py`"
    for path in on_disk:
        if path.count("/") >= 2 and not pathlib.PurePath(path).name.startswith("_"):
            command = rows[path].split("|")[3]
            assert path in command, (path, command)


def test_every_results_file_is_on_the_page():
    page = _page()
    results = [p.relative_to(ROOT).as_posix() for ext in ("md", "json")
               for p in (ROOT / "benchmarks").rglob(f"results*.{ext}")]
    assert results and not [r for r in results if f"`{r}`" not in page]


def test_the_page_is_current():
    assert _page() == index.render(), "docs/benchmarks.md is stale: run `python benchmarks/index.py`"


def test_the_page_is_in_the_site_nav():
    assert "benchmarks.md" in (ROOT / "mkdocs.yml").read_text(encoding="utf-8")


def _tree(tmp_path: pathlib.Path, results_name: str, results_text: str) -> pathlib.Path:
    """A repository with one topic script (docstring, command) and one results file beside it."""
    topic = tmp_path / "benchmarks" / "topic"
    topic.mkdir(parents=True)
    (topic / "bench_x.py").write_text('"""Cost of x.\n\n    python benchmarks/topic/bench_x.py [--smoke]\n"""\n')
    (topic / results_name).write_text(results_text)
    return tmp_path


def test_entry_reads_summary_command_result_and_load(tmp_path):
    root = _tree(tmp_path, "results_x.md", "# x\n\n| a | b \\| c |\n|---|---|\n| 1 | 2 |\n\n"
                                            "Load average (1, 5, 15 min) at the end: 1.5, 1.8, 2.8.\n")
    (entry,) = index.entries(root)
    assert (entry["topic"], entry["summary"], entry["command"]) == (
        "topic", "Cost of x.", "python benchmarks/topic/bench_x.py [--smoke]")
    result, load = index.result_cells(entry, root)
    assert result == "`benchmarks/topic/results_x.md`: a: 1; b \\| c: 2"
    assert load == "Load average (1, 5, 15 min) at the end: 1.5, 1.8, 2.8."


def test_a_load_not_recorded_is_said(tmp_path):
    root = _tree(tmp_path, "results_x.md", "# x\n\n| a |\n|---|\n| 1 |\n")
    (entry,) = index.entries(root)
    assert index.result_cells(entry, root)[1] == "not recorded"


def test_a_results_file_without_its_script_is_an_error(tmp_path):
    root = _tree(tmp_path, "results_y.md", "# y\n")
    with pytest.raises(ValueError, match="results_y.md: no script"):
        index.entries(root)


def test_a_script_without_a_command_is_an_error(tmp_path):
    root = _tree(tmp_path, "results_x.md", "# x\n")
    (root / "benchmarks" / "topic" / "bench_z.py").write_text('"""Cost of z, no command."""\n')
    with pytest.raises(ValueError, match="bench_z.py: its docstring gives no command"):
        index.entries(root)


def test_two_scripts_of_one_name_are_an_error(tmp_path):
    root = _tree(tmp_path, "results_x.md", "# x\n")
    (root / "benchmarks" / "other").mkdir()
    (root / "benchmarks" / "other" / "bench_x.py").write_text('"""x again.\n\n    python benchmarks/other/bench_x.py\n"""\n')
    with pytest.raises(ValueError, match="two benchmark scripts named bench_x.py"):
        index.entries(root)

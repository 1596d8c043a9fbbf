"""The documentation site builds with ``mkdocs build --strict`` (warnings are errors), its CLI
reference lists every subcommand of the parser, and the gallery and SymPy tables were generated
by running the code (issue #11 item 3)."""

from __future__ import annotations

import argparse
import html
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mkdocs")
pytest.importorskip("mkdocstrings")
pytest.importorskip("material")

import vpforms
from vpforms.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ)
    env.pop("VPFORMS_DOCS_NO_RUN", None)  # the generated parts must run
    # document (and run the gallery of) this checkout, whatever vpforms is installed
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    p = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=1200)
    assert p.returncode == 0, f"mkdocs build --strict failed:\n{p.stdout[-3000:]}\n{p.stderr[-6000:]}"
    return out


def _text(path: Path) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", path.read_text(encoding="utf-8")))


def test_cli_reference_lists_every_subcommand(site):
    parser = build_parser()
    subs = [a for a in parser._subparsers._group_actions if isinstance(a, argparse._SubParsersAction)]
    names = list(subs[0].choices)
    assert names, "the parser has subcommands"
    page = _text(site / "cli" / "index.html")
    assert "usage: vpforms" in page
    missing = [n for n in names if f"usage: vpforms {n}" not in page]
    assert not missing, f"CLI reference lacks {missing}"
    # and each subcommand's own options (its help text, not only its name)
    for n, sub in subs[0].choices.items():
        for action in sub._actions:
            for opt in action.option_strings:
                assert opt in page, f"vpforms {n}: option {opt} missing from the CLI reference"


def test_gallery_ran_and_drew(site):
    scripts = sorted((ROOT / "docs" / "gallery").glob("*.py"))
    assert len(scripts) >= 3
    for s in scripts:
        figs = sorted((site / "gallery").glob(f"{s.stem}-*.png"))
        assert figs and all(f.stat().st_size > 10_000 for f in figs), f"{s.name} drew no figure"
    pages = [p for p in (site / "gallery").glob("*/index.html")]
    texts = "\n".join(_text(p) for p in pages)
    assert texts.count("Output (printed when this site was built") == len(scripts)
    assert "not run" not in texts
    assert re.search(r"\d+ crossings of x3 = 0", texts)  # what abc_poincare.py printed


def test_mathematics_tables_were_computed(site):
    page = _text(site / "mathematics" / "index.html")
    # the proof column of table36_markdown(prove=True): one ✓ per case, computed by SymPy
    assert page.count("✓") == len(vpforms.cases())
    assert re.search(r"\d+ rows; \d+ disagree with the spec's verdict", page)  # the errata report ran


def test_api_reference_has_the_entry_points(site):
    page = (site / "api" / "vpforms" / "index.html").read_text(encoding="utf-8")
    # scheme/compose are documented explicitly (griffe resolves vpforms.scheme to the submodule)
    for name in ("scheme", "compose", "integrate", "GeneratingMap", "Solution", "RK4"):
        assert re.search(rf'id="vpforms\.[\w.]*\b{name}"', page), f"API reference lacks {name}"
    text = _text(site / "api" / "diagnostics" / "index.html")
    assert "poincare_section" in text and ":func:" not in text  # Sphinx roles rendered as code


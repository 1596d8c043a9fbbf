"""Rendering of the 36-case table and the nine LM tables; cross-checks against the spec's table
and the paper's Table tab:123123 (skipped when ../shared is absent)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from vpforms import cases

sym = pytest.importorskip("vpforms.symbolic")

REPO = Path(__file__).resolve().parents[1]
TABLE36 = REPO.parent / "shared" / "spec" / "table36.md"
PAPER = REPO.parent / "shared" / "paper" / "seed-paper.tex"


@pytest.fixture(scope="module")
def rows():
    return sym.table36_rows(prove=True)


def test_table36_has_every_case_once_and_all_proved(rows):
    assert len(rows) == 36
    assert len({(r["σ"], r["Σ"]) for r in rows}) == 36
    assert all(r["proof"] == "✓" for r in rows)
    md = sym.table36_markdown(prove=False)
    assert md.count("\n") == 38  # header, rule, 36 rows
    tex = sym.table36_latex(prove=False)
    assert tex.count(r"\\") >= 37 and r"\end{longtable}" in tex


def test_nine_lm_tables_partition_the_36_cases():
    seen = []
    for k in range(3):
        for K in range(3):
            cells = sym.lm_table_cases(k, K)
            assert sorted(cells) == ["AC", "AD", "BC", "BD"]
            seen += cells.values()
    assert sorted(map(str, seen)) == sorted(map(str, cases()))
    assert sym.lm_tables_markdown().count("###") == 9
    assert sym.lm_tables_latex().count(r"\begin{tabular}") == 9


def _norm(s: str) -> str:
    s = s.replace("−", "-")
    return re.sub(r"\s+", "", s)


@pytest.mark.skipif(not TABLE36.exists(), reason="../shared/spec/table36.md not available")
def test_table36_matches_the_spec_cross_check(rows):
    spec = {}
    for line in TABLE36.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 12 and cells[0].isdigit():
            spec[(cells[2], cells[3])] = cells
    assert len(spec) == 36
    for r in rows:
        s = spec[(r["σ"], r["Σ"])]
        assert s[1].split()[0] == r["class"].split()[0]
        assert _norm(s[4]) == _norm(r["τ"])
        assert int(s[5]) == int(r["sgn τ"])
        assert _norm(s[6]) == _norm(r["ν (k)"])
        assert _norm(s[7]) == _norm(r["ν̃ (K)"])
        assert s[8] == r["LM cell"]
        assert _norm(s[9]) == _norm(r["λ"])
        assert _norm(s[10]) == _norm(r["equations"])


def _paper_cells() -> list[str]:
    tex = PAPER.read_text(encoding="utf-8")
    table = tex[tex.index(r"\begin{table}[t]"): tex.index(r"\label{tab:123123}")]
    return re.findall(r"\\begin\{array\}\{ccc\}(.*?)\\end\{array\}", table, flags=re.S)


def _norm_tex(s: str) -> str:
    s = re.sub(r"\\begin\{array\}\{ccc\}|\\end\{array\}", "", s)
    for junk in (r"\qquad", r"\quad", r"\mbox{}", "[5pt]"):
        s = s.replace(junk, "")
    return re.sub(r"\s+", "", s)


@pytest.mark.skipif(not PAPER.exists(), reason="../shared/paper/seed-paper.tex not available")
def test_k0_K0_block_reproduces_the_papers_table_cell_by_cell():
    paper = _paper_cells()
    assert len(paper) == 4
    cells = sym.lm_table_cases(0, 0)
    # the paper's reading order: row C (AC, BC), then row D (AD, BD)
    for printed, key in zip(paper, ("AC", "BC", "AD", "BD")):
        assert _norm_tex(printed) == _norm_tex(sym.lm_cell_latex(cells[key])), key

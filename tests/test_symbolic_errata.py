"""The errata report: every printed formula is measured live, and the verdicts of the spec (MATH.md
§4, §6) are re-derived: what fails for the printed formula and that the correction passes."""

from __future__ import annotations

import pytest

sym = pytest.importorskip("vpforms.symbolic")
from vpforms.symbolic import errata as E  # noqa: E402


@pytest.fixture(scope="module")
def rows():
    return E.errata_rows()


def _find(rows, label, version, what=None):
    out = [r for r in rows if r.label == label and r.version == version
           and (what is None or what in r.what)]
    assert out, (label, version, what)
    return out


def test_every_printed_formula_is_listed(rows):
    labels = {r.label for r in rows}
    for label in ("eq:S1_quispel", "eq:S1_AZ", "eq:S2_quispel", "eq:case5", "eq:case4",
                  "eq:case3", "eq:notpzm", "sign rule", "prop:fivecases", "th:S2", "§4.1"):
        assert label in labels
    assert all(r.ok for r in rows), [r for r in rows if not r.ok]


def test_s1_printed_fail_and_corrections_pass(rows):
    for label in ("eq:S1_quispel", "eq:S1_AZ"):
        (p,) = _find(rows, label, "printed")
        assert not p.consistent and any("inconsistent" in d for d in p.defects)
        (c,) = _find(rows, label, "corrected", "potentials")
        assert c.consistent and c.order == 1 and c.det == "1" and not c.defects
        partial = [r for r in rows if r.label == label and r.version.startswith("corrected except")]
        assert len(partial) == (2 if label == "eq:S1_quispel" else 4)
        assert all(not r.consistent for r in partial)  # every single fix is necessary


def test_s2_correct_as_printed_but_needs_a13(rows):
    (p,) = _find(rows, "eq:S2_quispel", "printed", "potentials")
    assert p.consistent and p.order == 1 and p.det == "1"
    (a,) = _find(rows, "th:S2", "printed: 'a12 ≠ 0'")
    assert a.defects == ("divides by a12, a13",)
    for r in rows:
        if "correction map" in r.what:
            assert r.passes


def test_lagrangian_recipes_printed_signs_are_inconsistent_but_volume_preserving(rows):
    for label in ("eq:case4", "eq:case3"):
        (p,) = _find(rows, label, "printed")
        assert not p.consistent and p.order == 0 and p.det == "1"
        (c,) = _find(rows, label, "corrected")
        assert c.consistent and c.order == 1 and c.det == "1"
    (se,) = _find(rows, "eq:case5", "printed")
    assert se.consistent and se.det == "1"


def test_convention_errata(rows):
    for r in _find(rows, "sign rule", "opposite sign"):
        assert r.det == "-1" and not r.consistent
    failing = {r.what for r in _find(rows, "eq:notpzm", "printed (σ⁻¹)") if r.defects}
    assert failing == {"roles of printed eq:case3 (DL+DL)", "roles of printed eq:S2 (S2)"}
    assert all(r.passes for r in _find(rows, "eq:notpzm", "corrected (σ)"))
    single = _find(rows, "prop:fivecases", "printed claim: one τ gives all 36")
    assert all(r.defects for r in single)  # no single τ reaches all 36 cases
    (five,) = _find(rows, "prop:fivecases", "corrected")
    assert five.passes


def test_rendering(rows):
    md = E.render_errata(rows, "markdown")
    txt = E.render_errata(rows, "text")
    assert md.count("\n") == len(rows) + 2 and txt.count("\n") == len(rows) + 2
    assert "FAILS: inconsistent" in md and "passes" in txt
    with pytest.raises(ValueError, match="fmt"):
        E.render_errata(rows, "html")


def test_errata_rows_reject_a_non_traceless_matrix():
    with pytest.raises(ValueError, match="traceless"):
        E.errata_rows([[1, 0, 0], [0, 0, 0], [0, 0, 0]])

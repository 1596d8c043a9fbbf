"""Cases (σ, Σ): τ, the sign rule and the five classes (MATH.md §2, fig:triangle)."""

import re
from collections import Counter

import numpy as np
import pytest

from vpforms import CLASSES, Case, Perm, cases

from .conftest import SHARED


def perm_matrix(p):
    P = np.zeros((3, 3))
    for i in range(3):
        P[i, p[i] - 1] = 1.0
    return P


def independent_tau(sigma, Sigma):
    inv = {sigma[i]: i + 1 for i in range(3)}
    return tuple(inv[Sigma[i]] for i in range(3))  # τ(i) = σ⁻¹(Σ(i))


def test_thirty_six_distinct_cases():
    cs = cases()
    assert len(cs) == 36 and len(set(cs)) == 36
    assert cs == cases()  # stable order


@pytest.mark.parametrize("case", cases(), ids=str)
def test_tau_and_sign_independently(case):
    s, S = tuple(case.sigma), tuple(case.Sigma)
    assert tuple(case.tau) == independent_tau(s, S)
    det_tau = round(np.linalg.det(perm_matrix(independent_tau(s, S))))
    assert case.sign == det_tau
    # sign rule: sgn τ = sgn σ · sgn Σ
    assert case.sign == round(np.linalg.det(perm_matrix(s)) * np.linalg.det(perm_matrix(S)))


def test_class_counts_computed():
    counts = Counter(c.cls for c in cases())
    assert set(counts) == set(CLASSES)
    assert sorted(counts.values()) == [6, 6, 6, 6, 12]
    assert counts["SE+DL"] == 12


def test_class_is_invariant_under_relabelling_and_switching():
    # prop:trivperm: τ unchanged by (π,π); prop:switchperm: τ -> τ⁻¹, same class and sign.
    for c in cases():
        for pi in Perm.all():
            r = c.relabel(pi)
            assert r.tau == c.tau and r.cls == c.cls
        sw = c.switched()
        assert sw.tau == c.tau.inverse() and sw.cls == c.cls and sw.sign == c.sign
    # each class is one orbit of the relabelling + switching group
    for cls in CLASSES:
        members = {c for c in cases() if c.cls == cls}
        seed = next(iter(members))
        orbit = {seed.relabel(pi) for pi in Perm.all()}
        orbit |= {o.switched() for o in orbit}
        assert orbit == members


def test_paper_section4_examples_land_in_named_classes():
    # Section 4 uses σ(−)=1, σ(∘)=2, σ(+)=3, i.e. σ = (3,2,1), and states Σ by its roles.
    sigma = {"+": 3, "∘": 2, "-": 1}
    printed = {
        "SE+SE": {"+": 1, "∘": 2, "-": 3},  # §4.1 (eq:case5)
        "SE+DL": {"+": 1, "-": 2, "∘": 3},  # §4.2 "DL+SE" (eq:case4)
        "DL+DL": {"-": 2, "∘": 1, "+": 3},  # §4.3 (eq:case3)
        "S1": {"-": 1, "∘": 2, "+": 3},  # §4.4.1 (eq:S1)
        "S2": {"-": 1, "∘": 3, "+": 2},  # §4.4.2 (eq:S2)
    }
    s = tuple(sigma[r] for r in ("+", "∘", "-"))
    for name, roles in printed.items():
        S = tuple(roles[r] for r in ("+", "∘", "-"))
        assert Case(s, S).cls == name, (name, s, S)


def test_roles():
    c = Case((3, 2, 1), (1, 3, 2))
    assert (c.x_plus, c.x_circ, c.x_minus) == (3, 2, 1)
    assert (c.X_plus, c.X_circ, c.X_minus) == (1, 3, 2)
    assert c.roles == {"x+": 3, "x∘": 2, "x-": 1, "X+": 1, "X∘": 3, "X-": 2}


def test_case_rejects_malformed():
    with pytest.raises(ValueError, match="permutation"):
        Case((1, 2, 2), (1, 2, 3))
    with pytest.raises(ValueError, match="permutation"):
        Case((1, 2, 3), (4, 2, 1))


def test_cross_check_with_shared_table36():
    path = SHARED / "spec" / "table36.md"
    if not path.exists():
        pytest.skip("../shared/spec/table36.md not present (users' clones do not have it)")
    rows = [r for r in path.read_text().splitlines() if re.match(r"\| \d+ \|", r)]
    assert len(rows) == 36
    seen = set()
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        cls = cells[1].split()[0]
        s = tuple(int(v) for v in re.findall(r"\d", cells[2]))
        S = tuple(int(v) for v in re.findall(r"\d", cells[3]))
        sgn = int(cells[5])
        c = Case(s, S)
        assert (c.cls, c.sign) == (cls, sgn), row
        seen.add(c)
    assert seen == set(cases())

"""Explaining failures (issue #12 item 2): twist_map, explain_failures, Solution.summary/explain and
the CLI breakdown + hint, each checked against counts the test computes itself from step statuses."""

from __future__ import annotations

import re

import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, Case, Field, problems
from vpforms.diagnostics import explain_failures, failure_breakdown, twist_map

H = 0.5  # the DL+DL engine form's twist fails on ABC at a good fraction of points at this step


@pytest.fixture(scope="module")
def abc_dl():
    f = problems.get("abc").field
    bare = vpforms.scheme(f, "DL+DL", recover=False, fast=False)  # the engine form (not the default)
    x = np.random.default_rng(3).uniform(0.0, 2 * np.pi, (48, 3))
    return f, bare, x


def _codes(method, x, h):
    X, st = method.step_with_status(x, h)
    return np.asarray(st)


# --------------------------------------------------------------------------------------------
# twist_map
# --------------------------------------------------------------------------------------------
@pytest.mark.slow  # compilation of several schemes (~25-60 s on a shared 2-core machine)
def test_twist_map_fractions_are_the_step_status_counts(abc_dl):
    f, bare, x = abc_dl
    tm = twist_map(bare, x, h=H, cases=["DL+DL", "SE+SE"])
    own = tm.rows[0]
    assert own.own and own.label.startswith("this method")
    st = _codes(bare, x, H)
    assert np.any(st == RESULTS.twist_failure), "the test needs twist failures"
    assert own.twist == pytest.approx(np.mean(st != RESULTS.twist_failure), abs=0)
    assert own.step_ok == pytest.approx(np.mean(st == RESULTS.successful), abs=0)
    assert own.counts == {int(c): int(np.sum(st == c)) for c in np.unique(st)}
    # the DL+DL row is the class's default, the same map by its θ-stages (issue #19): counted from
    # its own bare step, and it fails at none of the points where the engine form (this method) does
    dl = _codes(vpforms.scheme(f, "DL+DL", recover=False), x, H)
    assert tm.row("DL+DL").counts == {int(c): int(np.sum(dl == c)) for c in np.unique(dl)}
    assert not np.any((dl != RESULTS.successful) & (st == RESULTS.twist_failure))
    # SE+SE counted independently from its own bare step
    se = _codes(vpforms.scheme(f, "SE+SE", recover=False), x, H)
    assert tm.row("SE+SE").twist == np.mean(se != RESULTS.twist_failure)
    assert tm.row("SE+SE").step_ok == np.mean(se == RESULTS.successful)
    assert np.array_equal(tm.status["SE+SE"], se)
    # best(): the applicable candidate with the largest success fraction, never the method itself
    best = tm.best(exclude=("DL+DL",))
    assert best.label == "SE+SE"
    text = str(tm)
    assert "twist holds" in text and "SE+SE" in text
    assert f"{100 * tm.row('SE+SE').twist:.1f}%" in text
    with pytest.raises(KeyError, match="no candidate"):
        tm.row("S7")


@pytest.mark.slow  # compilation of several schemes (~25-60 s on a shared 2-core machine)
def test_twist_map_cases_and_a_composition(abc_dl):
    f, bare, x = abc_dl
    other = next(c for c in vpforms.cases() if c.cls == "DL+DL" and c != bare.case)
    comp = vpforms.compose(bare, 2)
    tm = twist_map(comp, x[:16], h=H, cases=[other])
    # a composition's own row counts a failure in any stage: its own bare step_with_status
    st = _codes(comp, x[:16], H)
    assert tm.rows[0].twist == np.mean(st != RESULTS.twist_failure)
    row = tm.rows[1]
    assert row.case == other and row.cls == "DL+DL"
    st2 = _codes(vpforms.scheme(f, other, recover=False), x[:16], H)
    assert row.twist == np.mean(st2 != RESULTS.twist_failure)


def test_twist_map_recipe_that_does_not_apply_and_errors():
    A = np.array([[0.5, 1.0, 0.0], [0.3, -0.2, 0.7], [0.1, 0.4, -0.3]])  # a13 = 0: no S1, S2 recipe
    f = Field.linear(A)
    x = np.random.default_rng(0).normal(size=(8, 3))
    tm = twist_map(f, x, h=0.1, cases=["S1", "SE+SE"])
    assert tm.row("S1").error is not None and "a13" in tm.row("S1").error
    assert np.isnan(tm.row("S1").twist)
    se = _codes(vpforms.scheme(f, "SE+SE", recover=False), x, 0.1)
    assert tm.row("SE+SE").twist == np.mean(se != RESULTS.twist_failure)
    assert tm.best().label == "SE+SE"  # the S1 row is not applicable
    assert "recipe does not apply" in tm.table()
    with pytest.raises(ValueError, match="shape"):
        twist_map(f, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="NaN"):
        twist_map(f, np.array([np.nan, 0, 0]))
    with pytest.raises(ValueError, match="h must"):
        twist_map(f, x, h=0.0)
    with pytest.raises(ValueError, match="cases must"):
        twist_map(f, x, cases="some")
    with pytest.raises(TypeError, match="twist_map needs"):
        twist_map(object(), x)
    with pytest.raises(ValueError, match="recover"):
        twist_map(f, x, recover=True)


# --------------------------------------------------------------------------------------------
# explain_failures (host side only)
# --------------------------------------------------------------------------------------------
def test_explain_failures_breakdown_and_first():
    st = np.array([0, 1, 3, 1, 0, 2, 1])
    fs = np.array([-1, 9, 2, 4, -1, 7, 1])
    rep = explain_failures(st, fs, hint=False)
    assert rep.n_failed == 5 and rep.n_particles == 7
    assert rep.by_reason == {"twist condition failed": 3, "Newton not converged": 1, "non-finite": 1}
    assert rep.breakdown == "3 twist condition failed, 1 Newton not converged, 1 non-finite"
    # earliest failures first, with their steps and reasons
    assert rep.first[:3] == ((6, 1, "twist condition failed"), (2, 2, "non-finite"),
                             (3, 4, "twist condition failed"))
    lines = rep.lines()
    assert lines[0].startswith("5 of 7 particle(s) failed") and "particle 6 at step 1" in lines[1]
    assert rep.hint is None
    # without the method the hint says only what applies to any run
    rep2 = explain_failures(st, fs, h=0.1)
    assert "h = 0.02" in rep2.hint
    assert explain_failures(np.zeros(3, int)).lines() == ["all 3 particle(s) succeeded"]
    assert failure_breakdown(np.array([0, 3, 3])) == {"non-finite": 2}
    with pytest.raises(ValueError, match="unknown status"):
        failure_breakdown(np.array([0, 7]))
    with pytest.raises(ValueError, match="failed_step"):
        explain_failures(st, fs[:3])
    with pytest.raises(ValueError, match="particles"):
        explain_failures(st, particles=[1, 2])


# --------------------------------------------------------------------------------------------
# Solution.summary / explain on a run that really fails
# --------------------------------------------------------------------------------------------
@pytest.mark.slow  # compilation of several schemes (~25-60 s on a shared 2-core machine)
def test_summary_breakdown_and_hint_on_failing_run(abc_dl):
    f, bare, x = abc_dl
    sol = vpforms.integrate(bare, x, H, 12, backend="jax", progress=False)
    assert sol.n_failed > 0, "the test needs failures"
    s = sol.summary()
    n1 = int(np.sum(sol.status == RESULTS.twist_failure))
    assert s["failure breakdown"].startswith(f"{n1} twist condition failed")
    bad = np.flatnonzero(sol.status)
    p, n, why = s["first failed"][0]
    assert p in bad and n == sol.failed_step[p] == np.min(sol.failed_step[bad])
    assert why == RESULTS.short[int(sol.status[p])]
    assert "hint" in s and "recover=True" in s["hint"]
    rep = sol.explain()
    assert rep is sol.explain()  # computed once
    # the smaller step of the hint: the largest halving at which every failed step succeeds
    # (recomputed here from the frozen states), or the success fraction at h/64 if none does
    frozen = sol.x_final[bad]
    ladder = [np.mean(_codes(bare, frozen, H / 2**j) == 0) for j in range(1, 7)]
    if rep.smaller_h is not None:
        j = ladder.index(1.0) + 1
        assert rep.smaller_h == H / 2**j and f"h = {H / 2**j:g}" in rep.hint
    else:
        assert max(ladder) < 1.0 and rep.smaller_h_ok == ladder[-1]
        assert f"{100 * ladder[-1]:.0f} %" in rep.hint
    # the class named by the hint: its twist fraction at the failure states, counted here
    best = rep.twist.best(exclude=("DL+DL",))
    assert best.label in rep.hint
    st_best = _codes(vpforms.scheme(f, best.label, recover=False), frozen, H)
    assert best.twist == np.mean(st_best != RESULTS.twist_failure)
    assert f"{100 * best.twist:.0f} %" in rep.hint
    # the nested θ-stage evaluation of the same DL+DL map (fast=True) at the failure states, counted here
    fast = vpforms.scheme(f, "DL+DL", recover=False, fast=True)
    fast_ok = np.mean(_codes(fast, frozen, H) == RESULTS.successful)
    assert rep.fast_ok == fast_ok
    assert ("fast=True" in rep.hint) == (fast_ok > 0)
    assert sol.summary(hint=False).get("hint") is None


def test_fast_hint_applies_to_generic_dl_schemes_only():
    """The stage-form hint rebuilds the method from its spec with fast=True on every DL-class scheme
    built in the engine form (fast=False); other classes, the printed variant and the default
    (stage form) DL schemes have none."""
    from vpforms.diagnostics.failures import _with_fast

    f = problems.get("abc").field
    dl = vpforms.compose(vpforms.scheme(f, "DL+DL", theta=0.5, recover=False, fast=False), 4)
    spec = _with_fast(dl.spec())
    assert spec["kind"] == "compose" and spec["base"]["options"] == {"theta": 0.5, "fast": True, "recover": False}
    rebuilt = vpforms.method_from_spec(spec)
    psi = rebuilt.stages[0].method  # suzuki4[Ψ*∘Ψ]: its stages are Ψ and Ψ*
    assert rebuilt.order == 4 and psi.fast and psi.theta == 0.5
    assert _with_fast(vpforms.scheme(f, Case((2, 3, 1), (1, 3, 2)), recover=False).spec()) is None  # SE+SE
    assert _with_fast(vpforms.scheme(f, "SE+DL", recover=False, fast=False).spec())["options"]["fast"] is True
    assert _with_fast(vpforms.scheme(f, "SE+DL", recover=False).spec()) is None  # the default: stages
    assert _with_fast(vpforms.scheme(f, "DL+DL", recover=False, printed=True).spec()) is None
    assert _with_fast(vpforms.scheme(f, "DL+DL", recover=False, fast=True).spec()) is None


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
@pytest.mark.slow  # compilation of several schemes (~25-60 s on a shared 2-core machine)
def test_cli_run_explains_failures(tmp_path, capsys):
    from vpforms.cli import main

    out = tmp_path / "r.npz"
    argv = ["run", "--problem", "abc", "--method", "DL+DL", "--engine", "--no-recover", "--h", str(H), "--steps", "12",
            "--particles", "24", "--backend", "jax", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    with np.load(out) as d:
        st, fs = d["status"], d["failed_step"]
    nf = int(np.count_nonzero(st))
    assert nf > 0, "the test needs failures"
    m = re.search(r"(\d+) of (\d+) particle\(s\) failed and were frozen: (.*)", text)
    assert m and int(m.group(1)) == nf and int(m.group(2)) == 24
    for code in np.unique(st[st != 0]):
        assert f"{int(np.sum(st == code))} {RESULTS.short[int(code)]}" in m.group(3)
    first = re.search(r"first: particle (\d+) at step (\d+)", text)
    p, n = int(first.group(1)), int(first.group(2))
    assert st[p] != 0 and fs[p] == n == fs[st != 0].min()
    hint = re.search(r"hint: (.*)", text).group(1)
    assert "drop --no-recover" in hint and "--case" in hint
    assert re.search(r"--method (S1|S2|SE\+SE|SE\+DL)", hint)


@pytest.mark.slow
def test_cli_poincare_explains_failed_orbits(tmp_path, capsys):
    from vpforms.cli import main

    argv = ["poincare", "--problem", "abc", "--method", "DL+DL", "--engine", "--no-recover", "--order", "1",
            "--h", str(H), "--steps", "12", "--particles", "12", "--png", str(tmp_path / "p.png"),
            "--csv", str(tmp_path / "p.csv")]
    assert main(argv) == 0
    text = capsys.readouterr().out
    # the same orbits with integrate: the failed ones and their steps
    prob = problems.get("abc")
    x0 = prob.initial_conditions(12, seed=0)
    sol = vpforms.integrate(vpforms.scheme(prob.field, "DL+DL", recover=False, fast=False), x0, H, 12, progress=False,
                            backend="jax")
    assert sol.n_failed > 0
    assert "failed orbits:" in text
    assert f"{sol.n_failed} of 12 particle(s) failed" in text
    p0 = int(np.flatnonzero(sol.status)[np.argmin(sol.failed_step[sol.status != 0])])
    assert f"particle {p0} at step {int(sol.failed_step[p0])}" in text

"""Display fixes of issue #12 item 3: non-wrapping tables in pipes, Poincaré title counts, RK4
markers on top in the order plot, one clean bad-permutation line."""

from __future__ import annotations

import numpy as np

from vpforms import plots
from vpforms.cli import main
from vpforms.diagnostics import OrderFit, PoincareSection


def test_cases_table_does_not_wrap_in_a_pipe(capsys, monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)  # the rule: wide when piped unless COLUMNS is set
    assert main(["cases"]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("│")]
    assert len(rows) == 36  # one line per case: no wrapped continuation lines
    assert all(line.split("│")[1].strip() for line in rows)


def test_bad_permutation_message_says_it_once(capsys):
    assert main(["classify", "1,1,2", "1,2,3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].count("is not a permutation") == 1, err


def test_poincare_title_counts_all_orbits():
    M = 3
    sec = PoincareSection(
        points=np.array([[0.0, 0.1, 0.2], [0.0, 0.3, 0.4], [0.0, 0.5, 0.6]]),
        particle=np.array([0, 0, 2]), step=np.zeros(M, int), theta=np.zeros(M), t=np.zeros(M),
        counts=np.array([2, 0, 1, 0]), dropped=0, axis=0, value=0.0, direction=1, period=None,
        interpolation="chord", interpolation_order="1", method="m",
        status=np.zeros(4, int), fallback=np.zeros(M, bool),
    )
    fig = plots.poincare_figure(sec)
    assert "2 of 4 orbits crossed" in fig.axes[0].get_title()


def test_rk4_markers_drawn_on_top():
    hs = np.array([0.05, 0.1, 0.2])
    err = 1e-3 * hs**4
    fit = OrderFit(order=4.0, log10_c=-3.0, hs=hs, errors=err, used=np.ones(3, bool),
                   local_slopes=np.array([4.0, 4.0]))
    fig = plots.order_figure({"RK4": fit, "suzuki4[SE+SE]": fit})
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    rk = next(v for k, v in lines.items() if k.startswith("RK4"))
    s4 = next(v for k, v in lines.items() if k.startswith("suzuki4"))
    assert rk.get_marker() == "x" and rk.get_zorder() > s4.get_zorder()


def test_drift_never_cuts_the_method_name(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("COLUMNS", "60")  # a narrow terminal
    argv = ["drift", "--problem", "abc", "--order", "4", "--fast", "--steps", "2", "--particles", "2",
            "--png", str(tmp_path / "d.png")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "suzuki4[SE+SE(fast)*∘SE+SE(fast)]" in out, out

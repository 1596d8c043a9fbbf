"""Figures a physicist would put on a slide, and φ modulo the period in the CSV (issue #41 item 6).

The figure functions are tested directly on synthetic sections (circles about an axis at R = 1),
rendered with the Agg canvas: titles inside the figure, units on the axes, a legend naming the axis,
O- and X-points and the wall, a colour bar, readable ι labels. Fast: no field is traced."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace as NS

import numpy as np
import pytest

from vpforms import plots
from vpforms._errors import RESULTS
from vpforms.fieldlines import Wall
from vpforms.fieldlines._iota import Iota
from vpforms.fieldlines._sections import ToroidalSection

#: a method name as long as the CLI's: the title it makes is ~90 characters
LONG_TITLE = "tokamak: SE+SE*∘SE+SE, case (σ=(3,2,1), Σ=(1,2,3)), order 2, h = 0.05, 100 transits"


def _section(n_lines=4, per=50, nfp=1, phi=None):
    """Crossings on circles of radius 0.03·(i+1) about (R, Z) = (1, 0), line i turning by 0.55 − 0.05 i."""
    R, Z, line, tr = [], [], [], []
    for i in range(n_lines):
        r, th = 0.03 * (i + 1), np.arange(per) * 2 * math.pi * (0.55 - 0.05 * i)
        R.append(1.0 + r * np.cos(th))
        Z.append(r * np.sin(th))
        line.append(np.full(per, i))
        tr.append(np.arange(per))
    R, Z, line, tr = map(np.concatenate, (R, Z, line, tr))
    phi = np.zeros(R.size) if phi is None else np.asarray(phi, float)
    return ToroidalSection(R=R, Z=Z, line=line, transit=tr, phi=phi, t=np.arange(R.size, dtype=float),
                           status=np.zeros(n_lines, int), phi0=0.0, nfp=nfp, section=None)


AXIS = NS(R=1.0, Z=0.0, iota=0.5544914923, kind="O", m=1)
CHAIN = [NS(kind="O", m=2, orbit=np.array([[1.2, 0.0], [0.8, 0.0]])),
         NS(kind="X", m=2, orbit=np.array([[1.0, 0.2], [1.0, -0.2]]))]
WALL = Wall(np.array([0.7, 1.3, 1.3, 0.7, 0.7]), np.array([-0.3, -0.3, 0.3, 0.3, -0.3]))


def _inside(fig, artist) -> bool:
    r = fig.canvas.get_renderer()
    b, f = artist.get_window_extent(r), fig.bbox
    return f.x0 - 0.5 <= b.x0 and b.x1 <= f.x1 + 0.5 and f.y0 - 0.5 <= b.y0 and b.y1 <= f.y1 + 0.5


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


def test_section_figure_title_fits_and_would_not_unwrapped():
    fig = plots.fieldline_figure(_section(), AXIS, CHAIN, WALL, title=LONG_TITLE)
    fig.canvas.draw()
    title = fig._suptitle
    assert _inside(fig, title) and "\n" in title.get_text()
    assert title.get_text().replace("\n", " ").replace("\u00a0", " ") == LONG_TITLE  # wrapped, not cut
    title.set_text(LONG_TITLE)  # the same title on one line runs off the figure: the wrap is needed
    assert not _inside(fig, title)
    ax = fig.axes[0]
    assert _inside(fig, ax.title) and "φ = 0" in ax.title.get_text()


def test_section_figure_units_legend_colorbar_axis_wall_and_fixed_points(tmp_path):
    path = tmp_path / "s.png"
    fig = plots.fieldline_figure(_section(), AXIS, CHAIN, WALL, title="t", path=str(path))
    assert path.stat().st_size > 10_000
    ax, cbar_ax = fig.axes  # the section and its colour bar
    assert ax.get_xlabel() == "R (m)" and ax.get_ylabel() == "Z (m)"
    assert ax.xaxis.label.get_fontsize() >= 10
    texts = _legend_texts(fig)
    assert any(t.startswith("magnetic axis, ι = 0.55449") for t in texts)
    assert any(t.startswith("O-points") and "m = 2" in t for t in texts)
    assert any(t.startswith("X-points") and "m = 2" in t for t in texts)
    assert "wall" in texts and any("200 crossings of 4 lines" in t for t in texts)
    fig.canvas.draw()
    assert all(_inside(fig, lg) for lg in fig.legends)
    assert cbar_ax.get_ylabel() == "field line (index)"
    assert list(cbar_ax.get_yticks()) == [0, 1, 2, 3]  # one tick per line index
    # the axis (+), the O-points (o) and X-points (x) are drawn where they are
    marks = {ln.get_marker(): np.column_stack(ln.get_data()) for ln in ax.lines}
    np.testing.assert_array_equal(marks["+"], [[1.0, 0.0]])
    np.testing.assert_array_equal(marks["o"], CHAIN[0].orbit)
    np.testing.assert_array_equal(marks["x"], CHAIN[1].orbit)
    wall_line = [ln for ln in ax.lines if ln.get_label() == "wall"][0]
    np.testing.assert_array_equal(wall_line.get_xdata(), WALL.R)


def test_section_figure_colour_by_a_quantity_and_unknown_units():
    R0 = np.array([1.03, 1.06, 1.09, 1.12])
    fig = plots.fieldline_figure(_section(), title="t", units="", color_by=R0, color_label="starting R")
    ax, cbar_ax = fig.axes
    assert ax.get_xlabel() == "R" and ax.get_ylabel() == "Z"
    assert cbar_ax.get_ylabel() == "starting R"
    sc = ax.collections[0]
    np.testing.assert_allclose(sc.get_array(), np.repeat(R0, 50))  # each point has its line's value
    assert sc.norm.vmin == 1.03 and sc.norm.vmax == 1.12
    with pytest.raises(ValueError, match="color_by has 2 values"):
        plots.fieldline_figure(_section(), color_by=R0[:2])


def test_section_figure_of_no_crossings_still_draws():
    empty = _section(n_lines=3, per=0)
    fig = plots.fieldline_figure(empty, AXIS, title="nothing crossed")
    assert any("0 crossings of 3 lines" in t for t in _legend_texts(fig))


def _iota(values, errors):
    n = len(values)
    R0 = 1.0 + 0.03 * np.arange(1, n + 1)
    return Iota(iota=np.asarray(values, float), error=np.asarray(errors, float), plain=np.zeros(n),
                transits=np.full(n, 100.0), status=np.where(np.isfinite(values), 0, 2), R0=R0,
                Z0=np.zeros(n), n_steps=100)


def test_iota_figure_labels_are_readable_with_units_and_the_title_fits():
    it = _iota([0.55, 0.5, np.nan, 0.4], [1e-3, 2e-3, np.nan, 1e-3])
    fig = plots.iota_figure(it, title="ι profile — " + LONG_TITLE, axis=AXIS)
    a1, a2 = fig.axes
    assert a1.get_ylabel() == "rotational transform ι" and a2.get_ylabel() == "safety factor q = 1/ι"
    for a in (a1, a2):
        assert a.get_xlabel() == "starting R on Z = Z_axis (m)"
        assert a.xaxis.label.get_fontsize() >= 10 and a.yaxis.label.get_fontsize() >= 10
        assert all(t.get_fontsize() >= 10 for t in a.get_yticklabels())
    fig.canvas.draw()
    assert _inside(fig, fig._suptitle) and all(_inside(fig, lg) for lg in fig.legends)
    assert any("magnetic axis (tangent map), ι = 0.55449" in t for t in _legend_texts(fig))
    # the failed line is left out and counted; the others are drawn at their R with their ι
    assert any("1 of 4 lines failed" in t.get_text() for t in a1.texts)
    line = a1.lines[0]
    np.testing.assert_array_equal(line.get_ydata(), [0.55, 0.5, 0.4])
    np.testing.assert_allclose(a2.lines[0].get_ydata(), [1 / 0.55, 1 / 0.5, 1 / 0.4])
    assert plots.iota_figure(it, units="").axes[0].get_xlabel() == "starting R on Z = Z_axis"


# ------------------------------------------------------------------------------ CSV: φ mod period
@pytest.mark.parametrize("nfp", [1, 5])
def test_csv_writes_phi_modulo_the_period_with_the_period_itself_as_zero(tmp_path, nfp):
    """A crossing of φ = 0 located a rounding error below 2π (or below k·2π/nfp) is φ = 0 in the
    CSV, never 6.283185; other angles are reduced modulo P = 2π/nfp into [0, P)."""
    P = 2 * math.pi / nfp
    raw = np.array([0.0, 2 * math.pi - 1e-15, 2 * math.pi, -1e-17, 3 * P + 0.25, P * (1 - 1e-11), 0.25])
    expected = np.array([0.0, 0.0, 0.0, 0.0, 0.25, 0.0, 0.25])
    sec = _section(n_lines=1, per=raw.size, nfp=nfp, phi=raw)
    out = tmp_path / "s.csv"
    sec.to_csv(str(out))
    assert out.read_text().splitlines()[0] == "line,transit,phi,t,R,Z"
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 2], expected, rtol=0, atol=1e-14)
    assert np.all((data[:, 2] >= 0) & (data[:, 2] < P))
    np.testing.assert_array_equal(data[:, 4], sec.R)  # the other columns as they were


def test_iota_figure_says_which_lines_left_the_domain_and_which_failed():
    """A line stopped at the field's edge (``left_domain``) is not a failure: the note says both apart."""
    it = _iota([0.55, np.nan, np.nan, np.nan], [1e-3, np.nan, np.nan, np.nan])
    left = RESULTS.left_domain
    it = replace(it, status=np.array([0, left, left, RESULTS.not_converged], np.int32))
    notes = [t.get_text() for t in plots.iota_figure(it, axis=AXIS).axes[0].texts]
    assert any("1 of 4 lines failed, 2 left the domain" in t for t in notes), notes
    it = replace(it, status=np.array([0, left, left, left], np.int32))
    notes = [t.get_text() for t in plots.iota_figure(it, axis=AXIS).axes[0].texts]
    assert any("3 of 4 lines left the domain" in t for t in notes) and not any("failed" in t for t in notes), notes

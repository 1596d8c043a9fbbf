"""What ``vpforms fieldlines`` says and writes (issue #41 items 2 and 6): default output names and
replacement in ``--help``, "(replaced an existing file)", the phase lines on stderr and the
timing table listing every phase (the island search included), φ modulo the period in the CSV."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from vpforms.cli import build_parser, main
from vpforms.cli._common import CSV_SUFFIXES, FIGURE_SUFFIXES, _check_out, _written

OUTS = (("png", FIGURE_SUFFIXES), ("iota_png", FIGURE_SUFFIXES), ("csv", CSV_SUFFIXES))


def test_help_names_the_default_outputs_says_they_are_replaced_and_offers_quiet(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["fieldlines", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for name in ("vpforms-fieldlines.png", "vpforms-iota.png", "vpforms-fieldlines.csv"):
        assert f"default {name}" in text
    assert "an existing file is replaced, and the summary says so" in text
    assert "--quiet" in text and "VPFORMS_QUIET=1" in text and "phi modulo the field period" in text


def test_an_output_that_exists_is_reported_as_replaced(tmp_path):
    paths = {k: str(tmp_path / f"o{i}{s[0]}") for i, (k, s) in enumerate(OUTS)}
    argv = ["fieldlines", "--png", paths["png"], "--iota-png", paths["iota_png"], "--csv", paths["csv"]]
    (tmp_path / "o0.png").write_bytes(b"old")  # only the section figure is there before the run
    existing = _check_out(build_parser().parse_args(argv), *OUTS)
    assert existing == {paths["png"]}
    assert _written(paths["png"], existing) == f"{paths['png']} (replaced an existing file)"
    assert _written(paths["csv"], existing) == paths["csv"]


@pytest.mark.slow
def test_cli_study_says_each_phase_times_every_one_and_writes_phi_mod_the_period(tmp_path, capsys, monkeypatch):
    """The tokamak, 2 lines × 3 transits, a 3-point island scan and the default wall (~60–100 s
    here, most of it compiling the return map in JAX for the axis and island searches)."""
    monkeypatch.delenv("VPFORMS_QUIET", raising=False)
    out = {k: tmp_path / n for k, n in (("png", "s.png"), ("iota", "i.png"), ("csv", "s.csv"))}
    for p in out.values():
        p.write_bytes(b"an older run")
    lc_png, lc_csv = tmp_path / "lc.png", tmp_path / "lc.csv"
    assert main(["fieldlines", "--lines", "2", "--transits", "3", "--islands", "2", "--island-range", "1.2,1.36",
                 "--island-scan", "3", "--wall", "default", "--png", str(out["png"]), "--iota-png", str(out["iota"]),
                 "--csv", str(out["csv"]), "--connection-length", "40", "--lc-depth", "0.1", "--lc-transits", "2",
                 "--lc-png", str(lc_png), "--lc-csv", str(lc_csv)]) == 0
    cap = capsys.readouterr()
    stdout = cap.out
    assert stdout.count("(replaced an existing file)") == 3
    phases = ["building the method (SE+SE, order 2)", "searching for the magnetic axis",
              "tracing the section (2 lines, 3 transits)", "computing ι of the lines",
              "searching for m = 2 island chains (3 scan points)", "tracing the lines to the wall (2 lines)",
              "connection lengths (", "writing the CSV and the figures"]
    err = cap.err.splitlines()
    assert err and all(line.startswith("[vpforms] ") for line in err), err
    for name in phases:  # one line when it starts, one with its time when it ends
        assert sum(line.startswith(f"[vpforms] {name}") and line.endswith(" …") for line in err) == 1, name
        assert sum(line.startswith(f"[vpforms] {name}") and ": done in " in line for line in err) == 1, name
    # the timing table: every phase (and the silent field read) with its seconds, the rest, the total
    rows = {}
    for line in stdout.splitlines():
        m = re.match(r"^│ (.+?)\s+│\s+([0-9.]+) │\s+(\d+) % │$", line)
        if m:
            rows[m.group(1)] = float(m.group(2))
    for name in ["reading the field", *phases]:
        assert any(k.startswith(name) for k in rows), (name, rows)
    timed = sum(v for k, v in rows.items() if k not in ("total",))
    assert abs(timed - rows["total"]) <= 0.05 * len(rows)  # the rows add up to the total (to their rounding)
    # the CSV: φ of the section φ₀ = 0 is 0, never 2π
    data = np.loadtxt(out["csv"], delimiter=",", skiprows=1)
    assert data.shape[0] > 0 and np.all((data[:, 2] >= 0) & (data[:, 2] < 1e-9 * 2 * math.pi))
    assert all(out[k].stat().st_size > 20_000 for k in ("png", "iota"))
    # the connection-length map: every line of the CSV inside the default wall, within 0.1 of it; the
    # lengths both ways add up where the wall was reached; the summary row counts them
    from vpforms import problems

    wall = problems.get("tokamak").wall
    rows = np.genfromtxt(lc_csv, delimiter=",", names=True)
    d = np.asarray(wall.signed_distance(rows["R0"], rows["Z0"]))
    assert rows.size > 20 and np.all((d < 0) & (d >= -0.1))
    both = (rows["status_fwd"] == 0) & (rows["status_bwd"] == 0)
    np.testing.assert_allclose(rows["L"][both], rows["L_fwd"][both] + rows["L_bwd"][both], rtol=1e-15)
    assert np.isnan(rows["L"][~both]).all()
    lines = stdout.splitlines()
    i = next(k for k, ln in enumerate(lines) if "connection lengths" in ln)
    cells = [lines[i].split("│")[2]]
    for ln in lines[i + 1:]:  # the row's cell wrapped onto continuation lines (first cell blank)
        parts = ln.split("│")
        if len(parts) < 4 or parts[1].strip():
            break
        cells.append(parts[2])
    row = " ".join(c.strip() for c in cells)
    assert f"{rows.size} lines × 2 ways" in row and f"{int(both.sum())} reached the wall" in row, row
    assert lc_png.stat().st_size > 20_000 and "connection-length map: " in stdout

"""Issue #41 item 4 ("errors where answers would be wrong") and issue #40 item 5 (the CLI writes what
was asked): hostile inputs get one clear error, never a silent NaN, a wrong number or a file of
another name.  The CLI tests run ``vpforms.cli.main`` with argv and read its real output; the
field-line tests use the exactly solvable twist method of ``tests/test_fieldlines.py`` (fast)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vpforms.cli import build_parser, main


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error: "), err
    return err[0]


# ------------------------------------------------------------------ negative numbers (issue #41)
def test_negative_numbers_in_comma_lists_parse():
    """argparse reads a token that starts with '-' as an option unless it is one plain number:
    ``--Z -0.2,0.2`` used to stop with "expected one argument"."""
    p = build_parser()
    a = p.parse_args(["fieldlines", "--coils", "c", "--R", "0.8,1.2", "--Z", "-0.2,0.2",
                      "--axis-guess", "0.98,-0.01", "--radii", "-0.05,0.05", "--island-range", "-1,1",
                      "--phi", "-1e-3", "--wall", "-1,-1,1,-1,1,1,-1,1,-1,-1"])
    assert a.Z == [-0.2, 0.2] and a.axis_guess == [0.98, -0.01] and a.radii == [-0.05, 0.05]
    assert a.island_range == [-1.0, 1.0] and a.phi == -1e-3 and a.wall[:3] == [-1.0, -1.0, 1.0]
    a = p.parse_args(["poincare", "--value", "-.5", "--box", "-3,3", "--param", "C=-1"])
    assert a.value == -0.5 and a.box == "-3,3"
    assert p.parse_args(["errata", "--matrix", "-1,0,0;0,1,0;0,0,0"]).matrix == "-1,0,0;0,1,0;0,0,0"
    assert p.parse_args(["run", "--field", "-y,x,0"]).field == "-y,x,0"  # any value, not only numbers
    assert p.parse_args(["run", "-v", "--h", "0.1"]).verbose  # options stay options
    # an option that is not one stays an error, in one line
    with pytest.raises(Exception, match="unrecognized arguments: --nope"):
        p.parse_args(["poincare", "--nope"])


def test_fieldlines_coils_command_of_the_docs_gets_past_the_parser(tmp_path, capsys):
    """The doc's command, verbatim but for the file: the error is about the file, not --Z."""
    missing = tmp_path / "coils.mine"
    rc = main(["fieldlines", "--coils", str(missing), "--R", "0.8,1.2", "--Z", "-0.2,0.2",
               "--axis-guess", "0.98,0"])
    line = _error_line(capsys)
    assert rc == 2 and "expected one argument" not in line and str(missing) in line


# ------------------------------------------------------------ outputs are what was asked (issue #40)
@pytest.mark.parametrize("argv, option, accepted", [
    (["run", "--out", "{d}/plain.txt"], "--out", ".npz, .zarr"),
    (["run", "--out", "{d}/noext"], "--out", ".npz, .zarr"),
    (["poincare", "--png", "{d}/p.jpg"], "--png", ".png, .pdf, .svg"),
    (["poincare", "--csv", "{d}/p.txt"], "--csv", ".csv"),
    (["fieldlines", "--iota-png", "{d}/i"], "--iota-png", ".png, .pdf, .svg"),
    (["fieldlines", "--csv", "{d}/s.dat"], "--csv", ".csv"),
    (["drift", "--png", "{d}/d.gif"], "--png", ".png, .pdf, .svg"),
])
def test_an_output_name_of_another_kind_is_refused_before_the_run(tmp_path, capsys, argv, option, accepted):
    """The file is written exactly where asked, or the name is refused (nothing written, nothing
    computed) with the suffixes that are accepted."""
    argv = [a.format(d=tmp_path) for a in argv]
    assert main(argv) == 2
    line = _error_line(capsys)
    assert option in line and accepted in line and argv[-1] in line
    assert list(tmp_path.iterdir()) == []


def test_two_outputs_on_one_file_are_refused(tmp_path, capsys):
    same = str(tmp_path / "s.png")
    assert main(["fieldlines", "--png", same, "--iota-png", same]) == 2
    line = _error_line(capsys)
    assert "--png" in line and "--iota-png" in line and same in line


@pytest.mark.parametrize("command", ["run", "poincare", "fieldlines", "order", "drift"])
def test_help_gives_the_default_output_names(command, capsys, monkeypatch):
    """Each output option's help states its default file name (the file a bare command writes)."""
    monkeypatch.setenv("COLUMNS", "250")  # argparse would break a name at its hyphen
    sub = build_parser()._subparsers._group_actions[0].choices[command]
    outs = [a for a in sub._actions if any(s in ("--out", "--png", "--iota-png", "--csv") for s in a.option_strings)]
    assert outs
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for a in outs:
        assert a.default and a.default in a.help and a.default in text, a.option_strings


def test_run_writes_exactly_the_file_asked_and_says_when_it_replaced_one(tmp_path, capsys):
    out = tmp_path / "r.npz"
    argv = ["run", "--steps", "2", "--particles", "2", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert f"written: {out}" in text and "replaced" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]
    before = out.stat().st_mtime_ns
    assert main(argv) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"written: {out} (replaced an existing file)" in text and out.stat().st_mtime_ns >= before

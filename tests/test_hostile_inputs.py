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

"""Small new-user fixes of issue #12 item 3: bad --param values are one-line exit-2 errors."""

from __future__ import annotations

import pytest

from vpforms.cli import main


@pytest.mark.parametrize(
    "param, needle",
    [
        ("C=foo", "'foo' is not a number"),
        ("D=3", "has no parameter(s) D; its parameters are A, B, C"),
        ("A=", "has no value"),
        ("A=sqrt(", "cannot read parameter value: 'sqrt(' is not a number"),
    ],
)
def test_bad_param_is_one_clean_line(param, needle, capsys):
    assert main(["drift", "--problem", "abc", "--param", param, "--steps", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error: ") and needle in err[0], err
    assert "SyntaxError" not in err[0] and "unexpected keyword" not in err[0]

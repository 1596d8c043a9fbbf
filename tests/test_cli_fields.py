"""Users' own fields from the CLI (issue #11 item 1) and ``cases --format`` (item 5), in-process."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest

from vpforms._parse import FieldSyntaxError, field_from_text, parse_expression, parse_number
from vpforms.cli import main
from .test_cli import _one_line_error

ABC = "A*sin(z)+C*cos(y), B*sin(x)+A*cos(z), C*sin(y)+B*cos(x)"
PARAMS = ["--param", "A=1", "--param", "B=0.8", "--param", "C=0.5"]




def test_abc_as_text_reproduces_the_problem(tmp_path, capsys):
    """Same method, same x0: the string field and --problem abc agree to 1e-13."""
    x0 = np.array([[0.1, 0.2, 0.3], [1.0, 2.0, 3.0], [3.0, 1.0, 4.0]])
    np.save(tmp_path / "x0.npy", x0)
    common = [*PARAMS, "--x0", str(tmp_path / "x0.npy"), "--h", "0.1", "--steps", "25", "--save-every", "5"]
    assert main(["run", "--field", ABC, *common, "--out", str(tmp_path / "a.npz")]) == 0
    assert main(["run", "--problem", "abc", *common, "--out", str(tmp_path / "b.npz")]) == 0
    a, b = np.load(tmp_path / "a.npz"), np.load(tmp_path / "b.npz")
    assert a["xs"].shape == b["xs"].shape and a["xs"].shape[-1] == 3
    np.testing.assert_array_equal(a["xs"][..., 0, :] if a["xs"].shape[0] == 3 else a["xs"][0], x0)
    assert np.max(np.abs(a["xs"] - b["xs"])) <= 1e-13
    assert np.max(np.abs(a["xs"][..., -1, :] - a["xs"][..., 0, :])) > 0.1  # it moved
    capsys.readouterr()


def test_field_file_and_csv_x0(tmp_path, capsys):
    (tmp_path / "f.toml").write_text(
        'name = "rot"\ncomponents = ["-w*y", "w*x", "0"]\nbox = [[-1, 1], [-1, 1], [0, "pi"]]\n'
        "[params]\nw = 2\n")
    (tmp_path / "x0.csv").write_text("1,0,0.5\n0,1,0.25\n")
    out = tmp_path / "r.npz"
    assert main(["run", "--field-file", str(tmp_path / "f.toml"), "--x0", str(tmp_path / "x0.csv"),
                 "--h", "0.05", "--steps", "20", "--out", str(out)]) == 0
    xs = np.load(out)["xs"]
    # exact flow: rotation by w·T = 2·1 about the x3 axis; a first-order method is O(h) close
    x0 = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.25]])
    c, s = np.cos(2.0), np.sin(2.0)
    exact = np.stack([c * x0[:, 0] - s * x0[:, 1], s * x0[:, 0] + c * x0[:, 1], x0[:, 2]], axis=1)
    np.testing.assert_array_equal(xs[..., 0, :], x0)
    assert 1e-6 < np.max(np.abs(xs[..., -1, :] - exact)) < 0.1
    assert np.max(np.abs(xs[..., -1, 2] - np.array([0.5, 0.25]))) < 1e-14
    # --param overrides the file's value: w = 0 is the zero field
    assert main(["run", "--field-file", str(tmp_path / "f.toml"), "--param", "w=0", "--x0",
                 str(tmp_path / "x0.csv"), "--steps", "3", "--out", str(out)]) == 0
    xs = np.load(out)["xs"]
    np.testing.assert_allclose(xs[..., -1, :], xs[..., 0, :], atol=1e-14)
    capsys.readouterr()


BAD_FIELDS = [
    ("__import__('os').system('echo hi'), y, z", "not allowed"),
    ("lambda x: x, y, z", "not allowed"),
    ("().__class__, y, z", "not allowed"),
    ("x.real, y, z", "'.' is not allowed"),
    ("x1.func(x), y, z", "not allowed"),
    ("open(x), y, z", "unknown name 'open'"),
    ("foo(x), y, z", "unknown name 'foo'"),
    ("x, y, z", "not divergence free: div a = 3"),
    ("y, z", "3 components"),
    ("y, z, x, x", "3 components"),
    ("", "3 components"),
    ("x**9**9**9, y, z", "too large"),
    ("2**(10**10), y, z", "too large"),
    ("1e999*y, z, x", "too large"),
    ("t*y, z, x", "autonomous"),
    ("y, z, x+Q", "unknown name 'Q'"),
    ("y, z, 1/(x-x)", "not finite"),
    ("sin(y, z, x", "unclosed '(' at column 4"),
    ("y; z, x, y", "';'"),
    ("[y], z, x", "'['"),
    ("{y}, z, x", "'{'"),
    ("y if x else z, z, x", "keyword 'if'"),
]


@pytest.mark.parametrize("text,why", BAD_FIELDS)
def test_bad_fields_one_line(text, why, tmp_path, capsys):
    t = time.perf_counter()
    assert main(["run", "--field", text, "--steps", "1", "--out", str(tmp_path / "o.npz")]) == 2
    err = _one_line_error(capsys)
    assert why in err, err
    assert time.perf_counter() - t < 30
    assert not (tmp_path / "o.npz").exists()


@pytest.mark.parametrize("argv,why", [
    (["--field", "y,z,x", "--problem", "abc"], "mutually exclusive"),
    (["--field", "y,z,x", "--field-file", "f.toml"], "mutually exclusive"),
    (["--field-file", "missing.toml"], "cannot read"),
    (["--problem", "abc", "--box", "0,1"], "--box applies"),
    (["--field", "y,z,x", "--box", "1,0"], "lo < hi"),
    (["--field", "y,z,x", "--param", "A=__import__('os')"], "parameter value"),
    (["--field", "y,z,x", "--param", "A=1"], "do not occur"),
    (["--field", "y,z,A*x", "--param", "A=x"], "unknown name 'x'"),
    (["--field", "y,z,A*x", "--param", "A=inf"], "unknown name 'inf'"),
    (["--x0", "nope.txt"], "cannot read"),
    (["--x0", "x0.json"], ".npy or .csv"),
])
def test_bad_arguments_one_line(argv, why, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", *argv, "--steps", "1", "--out", str(tmp_path / "o.npz")]) == 2
    assert why in _one_line_error(capsys)


@pytest.mark.parametrize("content,why", [
    (np.array([[0.0, 1.0]]), "shape"),
    (np.zeros((0, 3)), "shape"),
    (np.zeros((2, 3, 1)), "shape"),
    (np.array([[0.0, np.nan, 1.0]]), "not finite"),
    (np.array([[0.0, np.inf, 1.0]]), "not finite"),
    (np.array(["a", "b", "c"]), "real numbers"),
])
def test_bad_x0_one_line(content, why, tmp_path, capsys):
    np.save(tmp_path / "x0.npy", content)
    for cmd in (["run", "--out", str(tmp_path / "o.npz")], ["drift", "--png", str(tmp_path / "d.png")],
                ["poincare", "--png", str(tmp_path / "p.png"), "--csv", str(tmp_path / "p.csv")]):
        assert main([*cmd, "--x0", str(tmp_path / "x0.npy"), "--steps", "1"]) == 2
        assert why in _one_line_error(capsys)


def test_bad_field_file(tmp_path, capsys):
    for text, why in [("components = [", "not valid TOML"), ('components = "x"', "list of 3 strings"),
                      ('components = ["y","z","x"]\ncolour = 1', "unknown key"),
                      ('components = ["y","z","x"]\nbox = [[0, 1]]', "3 pairs"),
                      ('components = ["y","z","x*a"]\n[params]\na = "sqrt(-1)"', "real")]:
        (tmp_path / "f.toml").write_text(text)
        assert main(["run", "--field-file", str(tmp_path / "f.toml"), "--steps", "1",
                     "--out", str(tmp_path / "o.npz")]) == 2
        assert why in _one_line_error(capsys)


def test_every_trace_command_takes_a_field(tmp_path, capsys):
    """--field is accepted by poincare, order and drift (they share the problem arguments)."""
    f = ["--field", "-y, x, 0*z"]  # rotation: divergence free, exact
    assert main(["poincare", *f, "--particles", "2", "--steps", "20", "--order", "1", "--axis", "2",
                 "--png", str(tmp_path / "p.png"), "--csv", str(tmp_path / "p.csv")]) == 0
    assert main(["order", *f, "--methods", "SE+SE", "--levels", "3", "--particles", "2", "--T", "0.4",
                 "--png", str(tmp_path / "o.png")]) == 0
    assert main(["drift", *f, "--particles", "2", "--steps", "10", "--png", str(tmp_path / "d.png")]) == 0
    out = capsys.readouterr().out
    assert "user field" in out


def test_parser_units():
    assert parse_expression("x^2 + y", ()) == parse_expression("x1**2 + x2", ())
    assert parse_number("sqrt(2/3)") ** 2 == parse_number("2/3")
    for bad in ("x", "1/0", "sqrt(-1)", "__import__", "os.system", "'1'"):
        with pytest.raises(FieldSyntaxError):
            parse_number(bad)
    with pytest.raises(FieldSyntaxError, match="reserved"):
        field_from_text("y, z, x", {"sin": 1})
    with pytest.raises(ValueError):  # a ValueError too (FieldSyntaxError is one)
        field_from_text("y, z", {})


def _markdown_rows(text):
    lines = [ln for ln in text.splitlines() if ln.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    assert set(lines[1].replace("|", "").replace("-", "")) == set()  # the separator row
    return head, [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines[2:]]


def test_cases_markdown_agrees_with_cases(capsys):
    from vpforms import cases

    assert main(["cases", "--format", "markdown"]) == 0
    head, rows = _markdown_rows(capsys.readouterr().out)
    assert len(rows) == 36 and all(len(r) == len(head) for r in rows)
    col = {h.split("=")[0]: i for i, h in enumerate(head)}

    def perm(s):
        return tuple(int(d) for d in re.findall(r"\d", s))

    listed = {(perm(r[col["σ"]]), perm(r[col["Σ"]])): r for r in rows}
    assert len(listed) == 36
    for c in cases():
        r = listed[(perm(c.sigma.one_line()), perm(c.Sigma.one_line()))]
        assert r[col["class"]].split()[0] == c.cls
        assert int(r[col["sgn τ"]]) == c.sign
        assert perm(r[col["τ"]].split("=")[0]) == perm(c.tau.one_line())


def test_cases_latex(capsys):
    assert main(["cases", "--format", "latex"]) == 0
    out = capsys.readouterr().out
    assert out.lstrip().startswith(r"\begin{longtable}") and r"\end{longtable}" in out
    assert sum(1 for ln in out.splitlines() if re.match(r"^\d+ & ", ln)) == 36
    assert main(["cases", "--format", "html"]) == 2
    _one_line_error(capsys)


@pytest.mark.parametrize("name,params", [("abc", {"A": [1]}), ("abc", {"C": object()}),
                                         ("rigid_body", {"I1": (1,)}), ("stokes_sphere", {"eps": {}}),
                                         ("tokamak", {"R0": [2]}), ("abc", {"A": "__import__('os')"})])
def test_problem_parameters_regression(name, params):
    """Found by tests/test_fuzz.py: a non-number parameter was an AttributeError inside make();
    text was handed to sympify (eval).  Now a TypeError naming the parameter, text read safely."""
    import vpforms.problems as problems

    with pytest.raises((TypeError, ValueError), match="parameter"):
        problems.get(name, **params)
    assert problems.get("abc", A="1/2").params["A"] == 0.5

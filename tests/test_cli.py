"""The ``vpforms`` CLI end to end, in-process (``vpforms.cli.main``) in a temporary folder.

Every subcommand runs with tiny sizes; figures must be real PNGs with visible content; bad
arguments give exit code ≠ 0 and a one-line error.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from vpforms.cli import build_parser, main

SUBCOMMANDS = ("cases", "classify", "run", "poincare", "verify", "order", "drift", "errata", "demo", "fieldlines")


def _png_ok(path, min_bytes=8_000):
    """A PNG that exists, is not tiny, and is not a blank canvas."""
    from matplotlib.image import imread

    assert path.exists(), path
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > min_bytes, (path, path.stat().st_size)
    img = imread(str(path))
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    dark = (img[..., :3].mean(axis=-1) < 0.5).mean()
    assert dark > 0.002  # axes, labels and data: not an empty canvas


def _one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert err.startswith("vpforms: error:"), err
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err
    return err


def test_help_everywhere(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for cmd in SUBCOMMANDS:
        assert cmd in out
        assert main([cmd, "--help"]) == 0
        assert "usage: vpforms " + cmd in capsys.readouterr().out
    assert set(build_parser()._subparsers._group_actions[0].choices) == set(SUBCOMMANDS)


def test_help_as_a_program():
    r = subprocess.run([sys.executable, "-m", "vpforms.cli", "--help"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "poincare" in r.stdout


def test_cases_and_classify(capsys):
    assert main(["cases"]) == 0
    out = capsys.readouterr().out
    assert "SE+SE 6" in out and "SE+DL 12" in out
    assert main(["classify", "3,2,1", "1,2,3"]) == 0
    assert "SE+SE" in capsys.readouterr().out
    assert main(["classify", "321", "231"]) == 0  # τ = σ⁻¹∘Σ computed by Case
    from vpforms import Case

    assert Case((3, 2, 1), (2, 3, 1)).cls in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["nonsense"],
        ["classify", "3,2,2", "1,2,3"],
        ["classify", "3,2,1"],
        ["run", "--h", "-0.1"],
        ["run", "--steps", "ten"],
        ["run", "--problem", "no_such_problem", "--steps", "2", "--particles", "2"],
        ["run", "--param", "C", "--steps", "2"],
        ["run", "--method", "rk4", "--order", "2", "--steps", "2"],
        ["run", "--order", "4", "--composition", "nonsense", "--steps", "2", "--particles", "2"],
        ["run", "--order", "2", "--composition", "suzuki", "--steps", "2", "--particles", "2"],
        ["run", "--composition", "blanes_moan", "--steps", "2", "--particles", "2"],
        ["run", "--method", "XY+Z", "--steps", "2", "--particles", "2"],
        ["order", "--T", "1", "--hs", "0.3"],
        ["poincare", "--axis", "4"],
        ["errata", "--matrix", "1,2,3;4,5,6;7,8,9"],
    ],
)
def test_bad_arguments_give_one_line_errors(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) != 0
    _one_line_error(capsys)


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "--method", "XY+Z", "--steps", "2", "--particles", "2"],  # scheme's ValueError
        ["run", "--method", "SE+SE", "--theta", "0.5", "--steps", "2", "--particles", "2"],
        ["run", "--method", "DL+DL", "--theta", "nan", "--steps", "2", "--particles", "2"],
        ["run", "--out", "no_such_folder/x.npz", "--steps", "2", "--particles", "2"],
        ["poincare", "--period", "-1", "--steps", "2", "--particles", "2"],
        ["poincare", "--png", "no_such_folder/p.png", "--steps", "2", "--particles", "2"],
        ["drift", "--png", "no_such_folder/d.png", "--steps", "2", "--particles", "2"],
        ["order", "--png", "no_such_folder/o.png", "--levels", "4"],
    ],
)
def test_bad_method_options_are_usage_errors(argv, capsys, tmp_path, monkeypatch):
    # exit 2 (bad arguments), before any integration, never a run of frozen NaN particles
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    _one_line_error(capsys)
    assert not (tmp_path / "vpforms-run.npz").exists()


def test_run_writes_npz(tmp_path, capsys):
    out = tmp_path / "r.npz"
    argv = ["run", "--problem", "abc", "--param", "C=0", "--steps", "12", "--particles", "5",
            "--h", "0.1", "--save-every", "4", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "failed particles" in text and str(out) in text
    with np.load(out) as d:
        assert d["xs"].shape == (5, 4, 3) and np.all(d["status"] == 0)
        np.testing.assert_allclose(d["ts"], [0.0, 0.4, 0.8, 1.2])
    # RK4 baseline and an invariant-carrying problem
    out2 = tmp_path / "rb.npz"
    assert main(["run", "--problem", "rigid_body", "--method", "rk4", "--steps", "5", "--particles", "3",
                 "--out", str(out2)]) == 0
    assert "max |Δ energy|" in capsys.readouterr().out


def test_poincare_png_and_csv(tmp_path, capsys):
    png, csv = tmp_path / "p.png", tmp_path / "p.csv"
    assert main(["poincare", "--particles", "8", "--steps", "600", "--order", "1", "--fast",
                 "--png", str(png), "--csv", str(csv)]) == 0
    _png_ok(png)
    data = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    assert data.shape[1] == 9 and data.shape[0] > 5
    # x₃ ≡ 0 (mod 2π) on the section
    r = np.mod(data[:, 6] + 1.0, 2 * np.pi) - 1.0
    assert np.max(np.abs(r)) < 1e-10
    assert "crossings" in capsys.readouterr().out


def test_order_png_and_table(tmp_path, capsys):
    png = tmp_path / "o.png"
    assert main(["order", "--methods", "SE+SE", "rk4", "--hs", "0.2,0.1,0.05", "--T", "0.4",
                 "--particles", "2", "--fast", "--png", str(png)]) == 0
    _png_ok(png)
    out = capsys.readouterr().out
    assert "order" in out and "RK4" in out


def test_drift_png(tmp_path, capsys):
    png = tmp_path / "d.png"
    assert main(["drift", "--problem", "rigid_body", "--steps", "60", "--particles", "3", "--order", "1",
                 "--png", str(png)]) == 0
    _png_ok(png)
    out = capsys.readouterr().out
    assert "RK4" in out and "max |log det|" in out and "failed orbits" in out


def test_errata(capsys):
    # a rational traceless matrix with every entry non-zero keeps this fast; the generic symbolic
    # matrix (the default) is exercised by the symbolic layer's own tests
    code = main(["errata", "--markdown", "--matrix", "1,2,3;-1,2,1;2,-2,-3"])
    cap = capsys.readouterr()
    if code == 0:
        assert len(cap.out) > 200
    else:  # the symbolic report (issue #3) is absent from this build: a clear one-line error
        assert code == 2 and cap.err.startswith("vpforms: error:") and len(cap.err.strip().splitlines()) == 1


def test_demo_quick(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    for name in ("poincare_abc.png", "order_abc.png", "drift_rigid_body.png"):
        _png_ok(out / name)
    assert (out / "poincare_abc.csv").exists()
    printed = capsys.readouterr().out
    assert str(out) in printed.replace("\n", "")
    flat = "".join(ch for ch in printed if not ch.isspace() and ch != "│")  # undo rich's wrapping
    assert "crossingsCSV:" + str(out / "poincare_abc.csv") in flat  # the closing box lists it


def test_composition_chooses_the_order_4_coefficients(capsys, tmp_path):
    """--composition blanes_moan: the method and its adjoint in alternation (12 stages), named in
    the summary; the same run as the library's compose(..., 4, "blanes_moan")."""
    import numpy as np

    import vpforms as vp

    out = tmp_path / "bm.npz"
    assert main(["run", "--order", "4", "--composition", "blanes_moan", "--steps", "3",
                 "--particles", "2", "--backend", "jax", "--out", str(out)]) == 0
    assert "blanes_moan4" in capsys.readouterr().out
    with np.load(out) as z:
        xs = z["xs"]
    prob = vp.problems.get("abc")
    x0 = xs[:, 0]
    ref = vp.integrate(vp.compose(vp.scheme(prob.field, "SE+SE"), 4, "blanes_moan"), x0, 0.1, 3,
                       backend="jax")
    assert np.max(np.abs(ref.xs[:, -1] - xs[:, -1])) <= 1e-13

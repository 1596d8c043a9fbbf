"""Issue #22 item 5, "say what happened": the CLI's summary and .npz carry the recovered steps; the
counts printed are those of the real inputs (--x0); the file name printed is the file written; the
C compiler's notes are silent (shown with -v); --version; --theta validated; options that do
nothing in a mode are refused; no leaked warning.  Each test runs the CLI (``vpforms.cli.main``)
and reads its real output or files."""

from __future__ import annotations

import importlib.metadata
import json
import warnings

import numpy as np
import pytest

from vpforms.cli import build_parser, main

from .test_cli import _one_line_error


@pytest.fixture(autouse=True)
def _unwrapped_tables(monkeypatch):
    """Summary rows on one line: the CLI sizes its tables from COLUMNS, which an xdist worker may
    set to 80 (a long row then wraps and a row-by-row comparison fails)."""
    monkeypatch.setenv("COLUMNS", "250")


@pytest.fixture
def points(tmp_path):
    """5 initial conditions in a .npy file (fewer than every --particles default)."""
    path = tmp_path / "x0.npy"
    np.save(path, np.random.default_rng(3).uniform(0.0, 2 * np.pi, (5, 3)))
    return str(path)


def _row(text: str, key: str) -> str:
    """The value of a summary-table row (rich's box drawing removed)."""
    line = next(ln for ln in text.splitlines() if ln.strip("│ ").startswith(key))
    return line.strip("│ ").split("│")[1].strip()


# ------------------------------------------------------------------------- recovered steps
def test_run_summary_and_npz_carry_the_recovered_steps(tmp_path, capsys):
    out = tmp_path / "r.npz"
    assert main(["run", "--steps", "4", "--particles", "3", "--out", str(out)]) == 0
    assert _row(capsys.readouterr().out, "recovered steps") == "0"
    with np.load(out) as z:  # the per-particle counts (Solution.recovered) and how, as JSON
        assert z["recovered"].shape == (3,) and not z["recovered"].any()
        assert json.loads(str(z["recovered_how"])) == {}
    assert main(["run", "--steps", "4", "--particles", "3", "--no-recover", "--out", str(out)]) == 0
    assert _row(capsys.readouterr().out, "recovered steps").startswith("off (bare method")


@pytest.mark.slow
def test_dldl_engine_recovered_steps_are_printed_and_saved(tmp_path, capsys):
    """The issue's case: DL+DL in the engine form recovers steps by its nested θ-stages; the
    summary says how many, in how many particles and how, and the .npz holds the same counts."""
    x0 = tmp_path / "x0.npy"
    np.save(x0, np.random.default_rng(1).uniform(0.0, 2 * np.pi, (64, 3)))
    out = tmp_path / "dl.npz"
    assert main(["run", "--method", "DL+DL", "--engine", "--x0", str(x0), "--h", "0.5", "--steps", "2",
                 "--out", str(out)]) == 0
    row = _row(capsys.readouterr().out, "recovered steps")
    with np.load(out) as z:
        rec, how = z["recovered"], json.loads(str(z["recovered_how"]))
    total, n = int(rec.sum()), int(np.count_nonzero(rec))
    assert total > 0 and sum(how.values()) == total
    assert how == {"the same DL map by its nested θ-stages": total}
    assert row == f"{total} in {n} particles ({total} with the same DL map by its nested θ-stages)"


# ------------------------------------------------------------------ counts from the real inputs
@pytest.mark.parametrize("argv, needle", [
    # poincare and drift compile more (3–5 s each): the verification tier
    pytest.param(["poincare", "--problem", "linear", "--method", "rk4", "--order", "1", "--steps", "10"],
                 "5 × 10 (h = 0.1)", marks=pytest.mark.slow, id="poincare"),
    pytest.param(["order", "--problem", "linear", "--methods", "rk4", "--hs", "0.5,0.25", "--T", "0.5"],
                 "(5 particles;", id="order"),
    pytest.param(["drift", "--problem", "linear", "--method", "rk4", "--order", "1", "--steps", "4"],
                 "4 steps, 5 orbits", marks=pytest.mark.slow, id="drift"),
])
def test_counts_are_those_of_x0(argv, needle, points, tmp_path, capsys, monkeypatch):
    """5 points in --x0: the tables count 5 (not the --particles defaults 60, 4 and 16)."""
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--x0", points]) == 0
    assert needle in " ".join(capsys.readouterr().out.split())  # titles wrap to the table's width


def test_the_file_name_printed_is_the_file_written(tmp_path, capsys):
    out = tmp_path / "foo.txt"  # NumPy would write foo.txt.npz: refused (issue #40), nothing written
    assert main(["run", "--steps", "2", "--particles", "2", "--out", str(out)]) == 2
    assert "must end in .npz, .zarr" in capsys.readouterr().err and not any(tmp_path.iterdir())
    out = tmp_path / "foo.npz"
    assert main(["run", "--steps", "2", "--particles", "2", "--out", str(out)]) == 0
    assert f"written: {out}" in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir()] == ["foo.npz"]


# ------------------------------------------------------------------------ the compiler's notes
@pytest.fixture
def fresh_native_cache(tmp_path, monkeypatch):
    from vpforms.backends.native import build, runner

    if not build.available()[0]:
        pytest.skip("no C compiler here")
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "native"))
    monkeypatch.setattr(build, "_loaded", {})  # nothing loaded: every kernel is compiled anew
    monkeypatch.setattr(runner, "_kernels", {})
    return build


def _gcc(build) -> bool:  # gcc notes each -fdisable-tree-… pass ("cc1: note: disable pass …")
    return "gcc" in build.available()[1].lower()


def test_a_new_kernel_compiles_silently(fresh_native_cache, capfd, caplog):
    before = fresh_native_cache.COUNTERS["compiled"]
    with caplog.at_level("INFO", logger="vpforms.native"):
        lib = fresh_native_cache.build("int vp_thrice(int a) { return 3 * a; }", "int vp_thrice(int a);")
    assert lib.lib.vp_thrice(14) == 42 and fresh_native_cache.COUNTERS["compiled"] == before + 1
    cap = capfd.readouterr()  # the process's file descriptors: what the compiler itself printed
    assert cap.out == "" and cap.err == "", cap
    if _gcc(fresh_native_cache):  # the notes went to the logger instead
        assert "cc1: note: disable pass tree-sincos" in caplog.text


def test_v_shows_the_compiler_output(fresh_native_cache, tmp_path, capfd):
    argv = ["run", "--steps", "2", "--particles", "2", "--backend", "native", "--out", str(tmp_path / "r.npz")]
    before = fresh_native_cache.COUNTERS["compiled"]
    assert main(["-v", *argv]) == 0
    assert fresh_native_cache.COUNTERS["compiled"] == before + 1  # it did compile a kernel
    err = capfd.readouterr().err
    assert "vpforms: the C compiler's output for native kernel _vpk_" in err
    if _gcc(fresh_native_cache):
        assert err.count("cc1: note: disable pass") == 3, err


def test_a_compiler_error_is_one_line_with_the_output_logged(fresh_native_cache, caplog):
    with caplog.at_level("INFO", logger="vpforms.native"), pytest.raises(OSError) as info:
        fresh_native_cache.build("this is not C;", "int vp_nothing(void);")
    msg = str(info.value)
    assert "failed on native kernel _vpk_" in msg and "error" in msg and "\n" not in msg
    assert any("this is not C" in r.getMessage() or "error" in r.getMessage() for r in caplog.records)


# --------------------------------------------------------------------------- version, θ, input
def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"vpforms {importlib.metadata.version('vpforms')}\n"


def test_theta_is_0_or_one_half(capsys):
    for ok in ("0", "0.5", ".5"):
        assert build_parser().parse_args(["run", "--theta", ok]).theta == float(ok)
    assert main(["run", "--method", "DL+DL", "--theta", "0.3", "--steps", "2"]) == 2
    assert "'0.3' must be 0 or 0.5" in _one_line_error(capsys)


def test_an_empty_x0_csv_is_one_line_and_no_warning(tmp_path, capsys):
    empty = tmp_path / "x0.csv"
    empty.write_text("")
    with warnings.catch_warnings(record=True) as leaked:
        warnings.simplefilter("always")
        assert main(["run", "--x0", str(empty), "--steps", "2"]) == 2
    assert "--x0" in _one_line_error(capsys)
    assert not leaked, [str(w.message) for w in leaked]
    # -v shows the warning too, as one line before the error
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["run", "-v", "--x0", str(empty), "--steps", "2"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("vpforms: warning: UserWarning: loadtxt")
    assert err[1].startswith("vpforms: error: --x0")


# ------------------------------------------------------------- options that do nothing are refused
@pytest.mark.parametrize("argv, named", [
    (["run", "--workers", "2"], "--workers does nothing without a .zarr store"),
    (["run", "--scheduler", "local", "--no-resume"], "--scheduler, --no-resume do nothing without a .zarr"),
    (["run", "--chunk-particles", "8", "--checkpoint-every", "2"], "--chunk-particles, --checkpoint-every"),
    (["run", "--out", "r.zarr", "--chunk-size", "8"], "--chunk-size does nothing with a .zarr store"),
    (["run", "--out", "r.zarr", "--workers", "2"], "--workers does nothing without --scheduler local"),
    (["run", "--x0", "{x0}", "--particles", "100"], "--particles does nothing with --x0"),
    (["poincare", "--x0", "{x0}", "--seed", "3"], "--seed does nothing with --x0"),
    (["run", "--method", "rk4", "--fast", "--no-recover"], "rk4 is the explicit baseline: --fast, --no-recover"),
    (["order", "--hs", "0.2,0.1", "--levels", "3"], "--levels does nothing with --hs"),
    (["order", "--methods", "rk4", "--fast"], "--fast does nothing without an SE+SE spec"),
    (["fieldlines", "--radii", "0.05,0.1", "--lines", "4"], "--lines does nothing with --radii"),
    (["fieldlines", "--island-scan", "9"], "--island-scan does nothing without --islands"),
    (["fieldlines", "--R", "0.8,1.2"], "--R does nothing without --coils"),
    (["fieldlines", "--mgrid", "m.nc", "--problem", "tokamak"], "--problem does nothing with --coils/--mgrid"),
])
def test_options_that_do_nothing_are_refused(argv, named, points, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("{x0}", points) for a in argv]
    assert main([*argv, "--steps", "2"] if argv[0] in ("run", "poincare") else argv) == 2
    assert named in _one_line_error(capsys)
    assert not list(tmp_path.glob("vpforms-*")) and not list(tmp_path.glob("*.zarr"))  # refused before any
    # computation or output

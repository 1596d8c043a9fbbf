"""Every benchmark script in benchmarks/<topic>/ runs end to end in smoke mode (tiny sizes) and writes its
results file; no timing is asserted.  Where a script checks that its baseline is the same map as
vpforms (the ``Check:`` line, computed by the script), that difference must be at round-off."""

from __future__ import annotations

import importlib.util
import pathlib
import re

import pytest

import vpforms as vp

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
_NATIVE_OK, _NATIVE_WHY = vp.native.available()


def _script(name: str) -> pathlib.Path:
    """``benchmarks/<topic>/<name>.py`` (names are unique across the topic folders), or skip when
    benchmarks/ is not shipped with this install."""
    found = sorted(BENCHMARKS.rglob(f"{name}.py")) if BENCHMARKS.exists() else []
    if not found:
        pytest.skip("benchmarks/ is not shipped with this install")
    assert len(found) == 1, found
    return found[0]


def _smoke(script: str, tmp_path: pathlib.Path, *extra: str) -> str:
    """Run ``benchmarks/<topic>/<script>.py --smoke [extra…]`` in this process; the text of the results file it wrote."""
    path = _script(script)
    spec = importlib.util.spec_from_file_location(script, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / f"results_{script.replace('/', '_')}.md"
    assert mod.main(["--smoke", "--out", str(out), *extra]) == 0
    text = out.read_text()
    assert "smoke mode" in text
    return text


def _check_value(text: str) -> float:
    """The first number on the script's ``Check: … = <value> (…)`` line."""
    check = [line for line in text.splitlines() if line.startswith("Check:")][0]
    return float(check.split("=")[1].split("(")[0])


def _row_labels(text: str) -> list[str]:
    rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    return [r.split("|")[1].strip() for r in rows[1:]]


def test_bench_abc_smoke(tmp_path):
    text = _smoke("bench_abc", tmp_path)
    labels = _row_labels(text)
    for needle in ("generic engine", "fast path", "order 2", "order 4", "three-shear", "RK4", "DOP853"):
        assert any(needle in lab for lab in labels), needle
    assert _check_value(text) < 1e-12  # the hand-written three-shear kernel is vpforms' SE+SE map


def test_bench_compose_smoke(tmp_path):
    text = _smoke("bench_compose", tmp_path)
    assert _row_labels(text) == ["fast", "generic"]
    assert _check_value(text) < 1e-12  # the fast compositions are the generic ones


@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_native_smoke(tmp_path, monkeypatch):
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "cache"))
    text = _smoke("bench_native", tmp_path)
    assert _check_value(text) < 1e-12  # the hand-written C reference is the same map
    for needle in ("reference", "native SE+SE", "native order 4", "Blanes–Moan", "native DL+DL",
                   "native RK4", "speed-up"):
        assert needle in text, needle


@pytest.mark.slow  # compiles the recovering tokamak DL+DL compositions (~1-3 min on a shared machine)
def test_bench_recovery_smoke(tmp_path):
    text = _smoke("bench_recovery", tmp_path)
    for needle in ("## (a)", "## (b)", "## (c)", "Ratio recovering / bare"):
        assert needle in text, needle
    lines = text.splitlines()
    assert sum(line.startswith("| 0.1 |") for line in lines) == 3  # tokamak h = 0.1: bare, recovering, fast
    assert sum(line.startswith("| DL+DL") for line in lines) == 12  # 3 methods × 4 rows


def test_bench_guard_smoke(tmp_path):
    text = _smoke("bench_guard", tmp_path)
    rows = [r.split("|") for r in text.splitlines() if r.startswith("| jax") or r.startswith("| native")]
    assert rows and rows[0][1].strip() == "jax"
    for r in rows:  # where nothing fails the guard changes no step: rounding-level differences only
        assert float(r[7]) < 1e-12 and int(r[8]) == 0


@pytest.mark.slow
def test_bench_fieldlines_smoke(tmp_path):
    text = _smoke("bench_fieldlines", tmp_path)
    labels = _row_labels(text)
    for needle in ("integrate, JAX", "toroidal_section", "rotational_transform", "trace_to_wall"):
        assert any(needle in lab for lab in labels), needle
    assert "Magnetic axis" in text


@pytest.mark.slow
def test_bench_orders_smoke(tmp_path):
    text = _smoke("bench_orders", tmp_path)
    assert "kahan_li" in text and "order" in text


def test_bench_distributed_smoke(tmp_path):
    pytest.importorskip("dask.distributed")
    text = _smoke("bench_distributed", tmp_path)
    assert "bitwise the in-process store (every file): True" in text
    assert "| Dask 2 workers, jax, warm |" in text


def test_bench_field_prep_smoke(tmp_path):
    text = _smoke("bench_field_prep", tmp_path)
    assert "| 3 | SE+SE |" in text and "| 3 | rk4 |" in text and "killed" not in text


def test_fuzz_fields_smoke(tmp_path):
    text = _smoke("fuzz_fields", tmp_path)  # main() returns 1 (the assert in _smoke) on any problem
    assert "over 10 s: 0" in text


@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_native_saving_smoke(tmp_path):
    text = _smoke("bench_native_saving", tmp_path)
    labels = [r.split("|")[2].strip() for r in text.splitlines() if r.startswith("| N = ")]
    assert labels == ["no saves", "save_every=1 (the kernel saves)", "save_every=1, one kernel call per save"]


@pytest.mark.slow  # builds the closed-form φ-time field and compiles one native composition (~10 s)
@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_desc_solovev_smoke(tmp_path, monkeypatch):
    monkeypatch.setenv("VPFORMS_PEER_VENVS", str(tmp_path / "no-peers"))  # never run a peer in the tests
    text = _smoke("bench_desc_solovev", tmp_path)
    assert "DESC not run: no DESC environment" in text
    assert "| vpforms | SE+SE φ-time, order 6 (blanes_moan), n = 32 |" in text


@pytest.mark.slow  # compiles five JAX methods (~15 s)
def test_bench_gpu_runs_on_any_jax_device(tmp_path):
    """bench_gpu.py has no smoke flag (its sizes are arguments): tiny sizes on whatever device JAX has."""
    spec = importlib.util.spec_from_file_location("bench_gpu", _script("bench_gpu"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    md = tmp_path / "gpu.md"
    assert mod.main(["--sizes", "64", "--steps", "2", "--rounds", "1", "--out", str(tmp_path / "g.json"),
                     "--md", str(md)]) == 0
    text = md.read_text()
    assert "vpforms SE+SE (closed form)" in text and "hand-written JAX three shears" in text
    assert "max |det J − 1| = " in text


@pytest.mark.slow  # builds the coil stellarator and a tokamak spline, compiles 3 kernels and 2 JAX steps (~90 s)
@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_native_splines_smoke(tmp_path):
    text = _smoke("bench_native_splines", tmp_path)
    rows = [r.split("|")[1:3] for r in text.splitlines() if r.startswith("| ") and "---" not in r][1:]
    assert [(f.strip(), b.strip()) for f, b in rows] == [
        ("tokamak (closed form)", "native"), ("tokamak (spline of A)", "native"),
        ("coil_stellarator (spline of A)", "native"), ("tokamak (spline of A)", "jax"),
        ("coil_stellarator (spline of A)", "jax")]


@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_spline_floor_smoke(tmp_path, monkeypatch):
    """The floor reads the blocks the generated SE+SE step reads (parsed from its C: the three
    components of A at x for a(x) — the guard's and the first guess's, read once — and the splines
    of each of the two solves)."""
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "cache"))
    text = _smoke("bench_spline_floor", tmp_path)
    assert _row_labels(text) == ["tokamak (closed form), native step", "tokamak (spline of A), native step",
                                 "floor: the step's spline reads, nothing else",
                                 "floor with per-cell monomial tables"]
    m = re.search(r"the (\d+) \(spline, point\) blocks .*? (\d+) at x for a\(x\) \(the guard's B\(x\), "
                  r"also the first guess\), (\d+) in solve 1, (\d+) in solve 2", text)
    total, guard, s1, s2 = map(int, m.groups())
    # B = ∇×A at x needs every component of A; each implicit solve reads at least one spline
    assert guard == 3 and s1 >= 1 and s2 >= 1 and total == guard + s1 + s2


@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_native_sections_smoke(tmp_path, monkeypatch):
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "cache"))
    text = _smoke("bench_native_sections", tmp_path)
    labels = _row_labels(text)
    assert any("tokamak" in lab for lab in labels) and any("ABC" in lab for lab in labels)
    assert "section / trace" in text and "JAX section" in text


@pytest.mark.slow  # compiles two wall kernels and their JAX references (~30 s)
@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_native_walls_smoke(tmp_path):
    text = _smoke("bench_native_walls", tmp_path)
    rows = [[c.strip() for c in r.split("|")[1:5]] for r in text.splitlines() if r.startswith("| ") and "---" not in r][1:]
    assert [(f, w) for f, w, _, _ in rows] == [(f, w) for f in ("tokamak (u, φ, Z)", "tokamak Cartesian")
                                              for w in ("box, no hit", "128-gon, cuts")]
    assert all(int(hits) == 0 for _, w, _, hits in rows if w == "box, no hit")
    assert all(int(hits) > 0 for _, w, _, hits in rows if w == "128-gon, cuts")


@pytest.mark.slow  # builds the coil spline, compiles one native spline kernel (~40 s), a short DOP853 reference
@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_peers_issue_size_smoke(tmp_path):
    # vpforms only: the peers' environments (if this machine has them) are never run by the tests
    text = _smoke("bench_peers_issue_size", tmp_path, "--tools", "vpforms", "--work", str(tmp_path / "work"))
    rows = [r for r in text.splitlines() if r.startswith("| vpforms")]
    # one time-stepping row and one φ-time row (K splined on the (v, φ, Z) grid, native)
    assert len(rows) == 2 and all("4 × 4" in r for r in rows) and "φ as the time" in rows[1]
    assert not [r for r in text.splitlines() if r.startswith(("| DESC", "| ESSOS"))]
    err, err_phi = (float(r.split("|")[3]) for r in rows)
    assert 0 < err < 0.05  # order 2 at h = 0.05 after 2 transits on a 12×8×12 grid: ~5e-4 m
    # order 2, 4 steps per field period on an 8×16×8 K grid of that spline: ~6e-2 m
    assert 0 < err_phi < 0.2 and "0 failed" in rows[1]


def test_bench_peers_curves_smoke(tmp_path):
    # vpforms only (the peers' environments are never run by the tests)
    text = _smoke("bench_peers_curves", tmp_path, "--tools", "vpforms", "--work", str(tmp_path / "work"))
    rows = [r for r in text.splitlines() if r.startswith("| vpforms")]
    # one accuracy row, then the long line at 3 and 6 transits
    assert len(rows) == 3 and "order 2" in rows[0] and "| 0 |" in rows[0]
    assert 0 < float(rows[0].split("|")[3]) < 0.2  # 4 steps per period on an 8×16×8 K grid: ~6e-2 m
    assert [int(r.split("|")[3]) for r in rows[1:]] == [3, 6]
    assert (tmp_path / "stellarator_accuracy_time.png").stat().st_size > 0  # the plot, beside the results


@pytest.mark.skipif(not _NATIVE_OK, reason=f"native backend unavailable: {_NATIVE_WHY}")
def test_bench_compile_smoke(tmp_path):
    """Two compilations of one small spline kernel (every entry, stages called) at -O3 and -O1: the
    same lines, the same steps, the same end points to rounding."""
    text = _smoke("bench_compile", tmp_path)
    rows = [[c.strip() for c in r.split("|")[1:-1]] for r in text.splitlines()
            if r.startswith("| ") and "---" not in r][1:]
    assert [r[2] for r in rows] == ["**now: called, -O3 -march=native -g0 (FLAGS)**", "called, -O1 -march=native -g0"]
    assert all(r[1] == "every entry" and float(r[5]) > 0 and float(r[7]) > 0 for r in rows)
    assert float(rows[0][9]) == 0.0 and float(rows[1][9]) < 1e-9

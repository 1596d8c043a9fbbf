"""The benchmark script runs end to end in smoke mode (tiny N); no timing is asserted."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_abc.py"


@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not shipped with this install")
def test_benchmark_smoke(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("bench_abc", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "results.md"
    assert mod.main(["--smoke", "--out", str(out)]) == 0
    text = out.read_text()
    assert "smoke mode" in text
    rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    labels = [r.split("|")[1].strip() for r in rows[1:]]
    for needle in ("generic engine", "fast path", "order 2", "order 4", "three-shear", "RK4", "DOP853"):
        assert any(needle in lab for lab in labels), needle
    # the hand-written three-shear kernel is the same map as vpforms SE+SE (checked by the script)
    check = [line for line in text.splitlines() if line.startswith("Check:")][0]
    assert float(check.split("=")[1].split("(")[0]) < 1e-12

"""The native benchmark script runs end to end in smoke mode (tiny N); no timing is asserted."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

import vpforms as vp

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_native.py"
_OK, _WHY = vp.native.available()


@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not shipped with this install")
@pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")
def test_native_benchmark_smoke(tmp_path, monkeypatch):
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "cache"))
    spec = importlib.util.spec_from_file_location("bench_native", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "results_native.md"
    assert mod.main(["--smoke", "--out", str(out)]) == 0
    text = out.read_text()
    assert "smoke mode" in text
    check = [line for line in text.splitlines() if line.startswith("Check:")][0]
    assert float(check.split("=")[1].split("(")[0]) < 1e-12  # the reference is the same map
    for needle in ("reference", "native SE+SE", "native order 4", "native RK4", "speed-up"):
        assert needle in text, needle

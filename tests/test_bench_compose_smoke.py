"""benchmarks/bench_compose.py runs end to end in smoke mode (tiny N); no timing is asserted."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_compose.py"


@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not shipped with this install")
def test_bench_compose_smoke(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_compose", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "results_compose.md"
    assert mod.main(["--smoke", "--out", str(out)]) == 0
    text = out.read_text()
    assert "smoke mode" in text
    rows = [line.split("|")[1].strip() for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows[1:] == ["fast", "generic"]
    # the fast compositions are the same map as the generic ones (computed by the script)
    check = [line for line in text.splitlines() if line.startswith("Check:")][0]
    assert float(check.split("=")[-1].split("(")[0]) < 1e-12

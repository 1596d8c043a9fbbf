"""benchmarks/bench_recovery.py runs end to end in smoke mode (tiny sizes); no timing is asserted."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_recovery.py"


@pytest.mark.slow  # compiles the recovering tokamak DL+DL compositions (~1-3 min on a shared machine)
@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not shipped with this install")
def test_bench_recovery_smoke(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_recovery", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "results_recovery.md"
    assert mod.main(["--smoke", "--out", str(out)]) == 0
    text = out.read_text()
    assert "smoke mode" in text
    for section in ("## (a)", "## (b)", "## (c)"):
        assert section in text
    assert "Ratio recovering / bare" in text
    rows = [line for line in text.splitlines() if line.startswith("| 0.1 |")]
    assert len(rows) == 2  # tokamak h = 0.1: bare and recovering
    assert sum(line.startswith("| DL+DL") for line in text.splitlines()) == 12  # 3 methods × 4 rows

"""Phases that say what they do (issue #41 item 2): vpforms._phases.

Lines not on a terminal, the spinner on one (a forced-terminal stream), delayed announcements,
quiet, the timing log and its table, and the trace bar pausing the spinner. Fast: sleeps of
≤ 0.3 s, no field, no method."""

from __future__ import annotations

import io
import time

import pytest

from vpforms import _phases
from vpforms._phases import Phases, format_seconds, phase


@pytest.fixture(autouse=True)
def _not_quiet(monkeypatch):
    monkeypatch.delenv("VPFORMS_QUIET", raising=False)


def _lines(buf: io.StringIO) -> list[str]:
    return buf.getvalue().splitlines()


def test_a_phase_writes_a_line_when_it_starts_and_one_with_its_time_when_it_ends():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=False) as log:
        with log.phase("building the method"):
            time.sleep(0.05)
            assert _lines(buf) == ["[vpforms] building the method …"]  # said before the work ends
    out = _lines(buf)
    assert len(out) == 2 and out[1].startswith("[vpforms] building the method: done in ")
    (rec,) = log.records
    assert rec.name == "building the method" and rec.depth == 0 and rec.ok
    assert 0.05 <= rec.seconds < 5.0
    assert out[1] == f"[vpforms] building the method: done in {format_seconds(rec.seconds)}"


def test_library_phases_report_to_the_active_log_nested_and_in_order():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=False) as log:
        with log.phase("reading the field"):
            with phase("sampling A"):  # the module-level phase: as library code calls it
                pass
            with phase("fitting the spline"):
                pass
        with log.phase("tracing"):
            pass
    assert [(r.name, r.depth) for r in log.ordered()] == [
        ("reading the field", 0), ("sampling A", 1), ("fitting the spline", 1), ("tracing", 0)]
    assert _lines(buf)[1] == "[vpforms]   sampling A …"  # nested: indented
    assert _phases.current() is _phases._DEFAULT  # the log is active only inside its with
    assert abs(log.accounted() - sum(r.seconds for r in log.records if r.depth == 0)) < 1e-15


def test_under_a_silent_phase_a_nested_one_is_not_indented():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=False) as log:
        with log.phase("reading the field", announce=False), phase("sampling A"):
            pass
    assert _lines(buf)[0] == "[vpforms] sampling A …"
    assert [r.depth for r in log.ordered()] == [0, 1]  # the log keeps the nesting


def test_an_error_ends_the_phase_with_a_line_saying_so_and_propagates():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=False) as log:
        with pytest.raises(KeyError):
            with log.phase("searching for the axis"):
                raise KeyError("x")
    assert _lines(buf)[-1].startswith("[vpforms] searching for the axis: stopped by an error after ")
    assert not log.records[0].ok


def test_a_delayed_phase_is_announced_only_once_it_runs_longer_than_the_delay():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=False, delay=0.1) as log:
        with log.phase("short"):
            pass
        with log.phase("long"):
            deadline = time.perf_counter() + 10.0
            while not buf.getvalue() and time.perf_counter() < deadline:  # a loaded machine: wait for it
                time.sleep(0.01)
            assert _lines(buf) == ["[vpforms] long …"]  # the timer said it, mid-phase
            assert time.perf_counter() - log._stack[-1].t0 >= 0.1  # not before the delay
        with log.phase("silent", announce=False):
            time.sleep(0.15)
    assert _lines(buf)[0] == "[vpforms] long …" and _lines(buf)[1].startswith("[vpforms] long: done in ")
    assert len(_lines(buf)) == 2  # nothing for the short one, nor for announce=False
    assert [r.name for r in log.records] == ["short", "long", "silent"]  # all recorded


@pytest.mark.parametrize("how", ["argument", "environment"])
def test_quiet_silences_the_lines_but_keeps_the_records(how, monkeypatch):
    buf = io.StringIO()
    if how == "environment":
        monkeypatch.setenv("VPFORMS_QUIET", "1")
    log = Phases(stream=buf, terminal=False, quiet=True if how == "argument" else None)
    with log, log.phase("compiling"):
        pass
    assert buf.getvalue() == "" and [r.name for r in log.records] == ["compiling"]
    monkeypatch.setenv("VPFORMS_QUIET", "0")  # "0" is not quiet
    with Phases(stream=buf, terminal=False) as log2, log2.phase("x"):
        pass
    assert buf.getvalue() != ""


def test_on_a_terminal_a_spinner_runs_and_a_done_line_stays():
    buf = io.StringIO()
    with Phases(stream=buf, terminal=True) as log:
        with log.phase("tracing the section"):
            assert log._status is not None  # the spinner runs while the phase does
            with log.phase("compiling the native kernel (53 KB of C)", live=False):
                assert log._status is None  # no spinner thread while the output is redirected
            assert log._status is not None
        assert log._status is None
    text = buf.getvalue()
    assert "  compiling the native kernel (53 KB of C) …" in text
    assert "✓ compiling the native kernel (53 KB of C)  done in" in text and "✓ tracing the section  done in" in text


def test_a_trace_bar_pauses_the_spinner_and_gives_it_back():
    from vpforms._progress import _Bar

    buf = io.StringIO()
    with Phases(stream=buf, terminal=True) as log, log.phase("tracing"):
        bar = _Bar(True, 10, "lines")
        bar.update(1)  # mode True: the bar shows at once
        assert bar.progress is not None and log._status is None
        bar.close()
        assert log._status is not None


def test_the_table_lists_every_phase_the_rest_and_the_total():
    from rich.console import Console

    with Phases(stream=io.StringIO(), terminal=False) as log:
        for name in ("building the method", "searching for the magnetic axis", "searching for island chains"):
            with log.phase(name):
                pass
        with log.phase("tracing"), phase("compiling"):
            pass
    con = Console(file=io.StringIO(), width=120)
    con.print(log.table())
    text = con.file.getvalue()
    for name in ("building the method", "searching for the magnetic axis", "searching for island chains",
                 "tracing", "└ compiling", "other", "total"):
        assert name in text, name


def test_format_seconds():
    assert format_seconds(12.34) == "12.3 s" and format_seconds(0.423) == "0.42 s"
    assert format_seconds(0.001) == "< 0.01 s" and format_seconds(61.0) == "61.0 s"
    with pytest.raises(ValueError, match="delay"):
        Phases(delay=-1)


# ------------------------------------------------------------------- the native compile is a phase
@pytest.fixture
def fresh_native_cache(tmp_path, monkeypatch):
    from vpforms.backends.native import build, runner

    if not build.available()[0]:
        pytest.skip("no C compiler here")
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path / "native"))
    monkeypatch.setattr(build, "_loaded", {})
    monkeypatch.setattr(runner, "_kernels", {})
    return build


def test_a_large_native_compile_says_so_outside_the_compilers_captured_output(fresh_native_cache, capfd):
    """Announced before fd 2 is redirected to collect the compiler's output, ended after it is
    restored: both lines reach stderr, the compiler's notes do not. A cache hit is no phase."""
    build = fresh_native_cache
    pad = "/* " + "x" * build.ANNOUNCE_BYTES + " */\n"  # a comment: as large as announced, fast to compile
    source = pad + "int vp_seven(void) { return 7; }"
    kb = f"{len(source.encode()) / 1024:.0f}"
    with Phases(terminal=False) as log:
        lib = build.build(source, "int vp_seven(void);")
        assert lib.lib.vp_seven() == 7
        build.build(source, "int vp_seven(void);")  # loaded: no phase
    err = capfd.readouterr().err.splitlines()
    assert err[0] == f"[vpforms] compiling the native kernel ({kb} KB of C) …"
    assert err[1].startswith(f"[vpforms] compiling the native kernel ({kb} KB of C): done in ") and len(err) == 2
    assert [r.name for r in log.records] == [f"compiling the native kernel ({kb} KB of C)"]
    with Phases(terminal=False) as log2:  # a small one: recorded, not announced
        build.build("int vp_eight(void) { return 8; }", "int vp_eight(void);")
    assert capfd.readouterr().err == "" and len(log2.records) == 1


# --------------------------------------------------------- a coil set's spline grid is three phases
@pytest.mark.slow
def test_a_coil_grid_says_it_samples_fits_and_measures():
    """spline_coil_field on a 10×8×10 grid of the l = 2 stellarator (~8 s: the fit and the error
    measurement compile JAX code): three nested phases, the sampling naming its node count."""
    from vpforms.coils import l2_stellarator
    from vpforms.problems.coil_fields import spline_coil_field

    buf = io.StringIO()
    with Phases(stream=buf, terminal=False) as log, log.phase("reading the field"):
        spline_coil_field(l2_stellarator(), (0.8, 1.18), (-0.18, 0.18), n_R=10, n_phi=8, n_Z=10, name="l2")
    names = [(r.name, r.depth) for r in log.ordered()]
    assert names == [("reading the field", 0), (f"sampling the vector potential of l2 at {10 * 8 * 10:,} grid nodes", 1),
                     ("fitting the 10×8×10 spline of A", 1),
                     ("measuring the spline's error against the coils at 400 points", 1)]
    assert len(_lines(buf)) == 8  # each phase: a line when it starts, one when it ends

"""Phases of a run that say what they do (issue #41 item 2: no silent phase longer than ~2 s).

A *phase* is a named stretch of work — building a method, sampling a coil set on a grid, compiling
a native kernel, searching for the magnetic axis — timed and reported on stderr::

    with Phases() as log:                        # the timing log; library phases inside report to it
        with log.phase("building the method"):
            ...
    log.records                                  # [PhaseRecord(name, seconds, depth, ok, start), …]

Not on a terminal (pipes, log files, CI) a phase writes one line when it starts and one when it
ends, ``[vpforms] building the method …`` / ``[vpforms] building the method: done in 12.3 s``; on a
terminal a transient rich spinner shows the running phase and its elapsed time, and a line
``✓ building the method  12.3 s`` stays when it ends. Library code calls :func:`phase`, which
reports to the active :class:`Phases` (``with Phases():``) or, outside one, to the library's
default log: that one announces a phase only once it has run :data:`LIBRARY_DELAY` = 2 s, so that
short work stays silent and long work never is. A phase that is not announced prints nothing at
its end either (one line out, one line back). ``quiet=True`` or the environment variable
``VPFORMS_QUIET=1`` silences the lines; the records are kept all the same.

The delayed announcement comes from a timer thread; a phase during which the process's file
descriptors are redirected (the native compile collects the compiler's output from fd 2) must
therefore announce itself before the redirection: ``delay=0``, ``live=False`` (no spinner thread
writing into the redirected descriptor while it runs).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field

from rich.console import Console
from rich.status import Status
from rich.table import Table
from rich.text import Text

__all__ = ["ENV_QUIET", "LIBRARY_DELAY", "PhaseRecord", "Phases", "phase", "current", "format_seconds"]

#: the environment variable that silences every phase line (records are still kept)
ENV_QUIET = "VPFORMS_QUIET"
#: outside an explicit log, a phase is announced once it has run this long (seconds)
LIBRARY_DELAY = 2.0
#: the library's default log keeps at most this many records (oldest dropped)
_DEFAULT_KEEP = 256
_PREFIX = "[vpforms]"

_CURRENT: ContextVar["Phases | None"] = ContextVar("vpforms_phases", default=None)


def format_seconds(s: float) -> str:
    """12.3 s from 1 s on, 0.42 s below, "< 0.01 s" below that."""
    return f"{s:.1f} s" if s >= 1 else f"{s:.2f} s" if s >= 0.01 else "< 0.01 s"


def _env_quiet() -> bool:
    return os.environ.get(ENV_QUIET, "").strip().lower() not in ("", "0", "false", "no")


_CONSOLE = None


def stderr_console():
    """The rich console on stderr shared by the phase spinner and the trace progress bars (one
    console: rich stacks their live displays instead of two writers garbling one terminal)."""
    global _CONSOLE
    if _CONSOLE is None:
        _CONSOLE = Console(stderr=True, highlight=False)
    return _CONSOLE


@dataclass(frozen=True)
class PhaseRecord:
    """One finished phase: its ``name``, wall-clock ``seconds``, nesting ``depth`` (0: outermost),
    ``ok`` (False: it ended by an exception) and ``start`` (seconds after the log began)."""

    name: str
    seconds: float
    depth: int
    ok: bool = True
    start: float = 0.0


@dataclass(eq=False)
class _Running:
    name: str
    depth: int
    t0: float
    live: bool
    announced: bool = False
    finished: bool = False
    timer: threading.Timer | None = field(default=None, repr=False)

    def __rich__(self):  # the spinner's text, re-rendered on each refresh: the elapsed time runs
        return Text(f"{self.name} … {time.perf_counter() - self.t0:.0f} s")


class Phases:
    """A timing log of phases and their reporter (module docstring).

    ``quiet``: no lines (None: as ``VPFORMS_QUIET``); ``delay``: seconds a phase runs before it is
    announced (0: at once — the command line; :data:`LIBRARY_DELAY` for the library's default);
    ``terminal``: spinner (True) or lines (False), None: whether stderr is a terminal; ``stream``:
    where the lines go (None: ``sys.stderr`` at the time of writing); ``keep``: the most records kept.
    ``with Phases() as log:`` makes it the log that :func:`phase` reports to in this context.
    """

    def __init__(self, *, quiet: bool | None = None, delay: float = 0.0, terminal: bool | None = None,
                 stream=None, keep: int | None = None):
        if not (delay >= 0):
            raise ValueError(f"delay must be ≥ 0 seconds; got {delay!r}")
        self.quiet, self.delay, self.terminal, self.stream, self.keep = quiet, float(delay), terminal, stream, keep
        self.records: list[PhaseRecord] = []
        self.t0 = time.perf_counter()
        self._stack: list[_Running] = []
        self._lock = threading.RLock()
        self._status = None  # the rich Status of the terminal spinner, while one runs
        self._paused = 0
        self._tokens: list = []
        self._con = None

    # -- the active log ------------------------------------------------------------------------
    def __enter__(self) -> "Phases":
        self.t0 = time.perf_counter()
        self._tokens.append(_CURRENT.set(self))
        return self

    def __exit__(self, *exc) -> None:
        _CURRENT.reset(self._tokens.pop())
        with self._lock:
            self._stop_spinner()

    # -- reading the log -----------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        """Seconds since the log began (``with`` entered, else created)."""
        return time.perf_counter() - self.t0

    def ordered(self) -> list[PhaseRecord]:
        """The records in the order the phases began (a nested phase after its parent)."""
        return sorted(self.records, key=lambda r: (r.start, r.depth))

    def accounted(self) -> float:
        """Seconds inside outermost phases."""
        return sum(r.seconds for r in self.records if r.depth == 0)

    # -- reporting -----------------------------------------------------------------------------
    def _quiet(self) -> bool:
        return self.quiet if self.quiet is not None else _env_quiet()

    def _is_terminal(self) -> bool:
        if self.terminal is not None:
            return bool(self.terminal)
        return self.stream is None and stderr_console().is_terminal

    def _line(self, text: str) -> None:
        stream = self.stream if self.stream is not None else sys.stderr
        try:
            stream.write(text + "\n")
            stream.flush()
        except (OSError, ValueError, AttributeError):  # a closed or absent stderr: stay silent
            pass

    def _console(self):
        if self.stream is None:
            return stderr_console()
        if self._con is None:  # a given stream (tests): one console of its own
            self._con = Console(file=self.stream, force_terminal=bool(self.terminal), highlight=False)
        return self._con

    def _announce(self, run: _Running) -> None:
        with self._lock:
            if run.finished or run.announced or self._quiet():
                return
            run.announced = True
            indent = self._indent(run)
            if not self._is_terminal():
                self._line(f"{_PREFIX} {indent}{run.name} …")
            elif not run.live:  # the spinner is paused while this phase runs (module docstring)
                self._console().print(f"{indent}{run.name} …", markup=False)
            else:
                self._show(run)

    def _indent(self, run: _Running) -> str:
        """Two spaces per announced phase around ``run`` (a silent parent adds none)."""
        return "  " * sum(1 for r in self._stack[: run.depth] if r.announced)

    def _show(self, run: _Running | None) -> None:
        """The spinner shows ``run`` (None: the innermost announced live phase, or stops)."""
        if run is None:
            live = [r for r in self._stack if r.announced and not r.finished]
            run = live[-1] if live and all(r.live for r in live) else None
        if run is None or self._paused:
            self._stop_spinner()
            return
        if self._status is None:
            self._status = Status(run, console=self._console(), spinner="dots")
            self._status.start()
        else:
            self._status.update(run)

    def _stop_spinner(self) -> None:
        if self._status is not None:
            try:
                self._status.stop()
            finally:
                self._status = None

    def _finish(self, run: _Running, seconds: float, ok: bool) -> None:
        with self._lock:
            run.finished = True
            if run.timer is not None:
                run.timer.cancel()
            rec = PhaseRecord(run.name, seconds, run.depth, ok, run.t0 - self.t0)
            self.records.append(rec)
            if self.keep is not None and len(self.records) > self.keep:
                del self.records[: len(self.records) - self.keep]
            self._stack.remove(run)
            if not run.announced or self._quiet():
                return
            indent = self._indent(run)
            end = f"done in {format_seconds(seconds)}" if ok else f"stopped by an error after {format_seconds(seconds)}"
            if not self._is_terminal():
                self._line(f"{_PREFIX} {indent}{run.name}: {end}")
                return
            if not any(r.announced and r.live for r in self._stack):
                self._stop_spinner()  # before the line: nothing is redrawn after it
            mark = "✓" if ok else "✗"
            self._console().print(f"{indent}{mark} {run.name}  {end}", markup=False)
            self._show(None)

    @contextmanager
    def phase(self, name: str, *, delay: float | None = None, announce: bool = True,
              live: bool = True) -> Iterator[_Running]:
        """Time the ``with`` block as the phase ``name`` and record it.

        ``delay``: seconds before it is announced (None: the log's); ``announce=False``: record
        only, never a line (work whose own inner phases say what they do, or checks that end in
        an error line); ``live=False``: no spinner while it runs (it redirects the process's output)."""
        with self._lock:
            run = _Running(str(name), len(self._stack), time.perf_counter(), bool(live))
            self._stack.append(run)
        wait = self.delay if delay is None else float(delay)
        if not run.live:  # announced or not: no spinner thread writes while it runs
            self.pause()
        if announce and not self._quiet():
            if wait <= 0:
                self._announce(run)
            else:
                run.timer = threading.Timer(wait, self._announce, (run,))
                run.timer.daemon = True
                run.timer.start()
        ok = False
        try:
            yield run
            ok = True
        finally:
            self._finish(run, time.perf_counter() - run.t0, ok)
            if not run.live:
                self.resume()

    # -- the trace progress bars (rich) pause the spinner while they show -------------------------
    def pause(self) -> None:
        with self._lock:
            self._paused += 1
            self._stop_spinner()

    def resume(self) -> None:
        with self._lock:
            self._paused = max(0, self._paused - 1)
            if not self._paused and self._is_terminal():
                self._show(None)

    def table(self, title: str = "where the time went"):
        """A rich table: each phase (nested ones indented) with its seconds and share of the
        total, the time outside any phase, and the total."""
        total = self.elapsed
        t = Table(title=title)
        t.add_column("phase")
        t.add_column("s", justify="right")
        t.add_column("share", justify="right")
        for r in self.ordered():
            name = ("  " * r.depth + ("└ " if r.depth else "") + r.name) + ("" if r.ok else " (error)")
            t.add_row(name, f"{r.seconds:.1f}", f"{100 * r.seconds / total:.0f} %" if total > 0 else "")
        rest = max(total - self.accounted(), 0.0)
        t.add_row("other (arguments, checks, summary)", f"{rest:.1f}", f"{100 * rest / total:.0f} %" if total > 0 else "")
        t.add_row("total", f"{total:.1f}", "100 %", style="bold")
        return t


_DEFAULT = Phases(delay=LIBRARY_DELAY, keep=_DEFAULT_KEEP)


def current() -> Phases:
    """The log that :func:`phase` reports to here: the innermost ``with Phases()``, else the
    library's default (delayed announcements, the last 256 records)."""
    return _CURRENT.get() or _DEFAULT


def phase(name: str, *, delay: float | None = None, announce: bool = True, live: bool = True):
    """``with phase("sampling the coils' A at 51,200 nodes"):`` — a phase of the current log
    (:meth:`Phases.phase`)."""
    return current().phase(name, delay=delay, announce=announce, live=live)

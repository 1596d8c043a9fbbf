"""The progress bar of long runs (rich, on stderr), shared by every backend and the diagnostics.

Split from ``_integrate.py`` (issue #19: imports flow one way). The bar shares its console with
the phase spinner of :mod:`vpforms._phases` and pauses that spinner while it shows (one live
display on the terminal at a time).
"""

from __future__ import annotations

import time

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from ._phases import current as _current_phases
from ._phases import stderr_console

__all__ = ["_Bar"]


def _is_terminal() -> bool:
    """Whether rich would animate a bar here (not in pipes, logs or captured test output)."""
    return Console(stderr=True).is_terminal


class _Bar:
    """A rich progress bar that appears only for runs expected to take more than ~1 s."""

    def __init__(self, mode: bool | str, total: int, label: str):
        self.mode, self.total, self.label = mode, total, label
        self.done = 0
        self.t_start = time.perf_counter()
        self.progress = None
        self.task = None
        self._phases = None

    def _start(self):
        self._phases = _current_phases()
        self._phases.pause()  # the bar replaces the spinner of the running phase while it shows
        self.progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("particle-steps"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            transient=True,
            console=stderr_console(),
        )
        self.progress.start()
        self.task = self.progress.add_task(self.label, total=self.total, completed=self.done)

    def update(self, k: int):
        self.done += k
        if self.mode is False:
            return
        if self.progress is None:
            elapsed = time.perf_counter() - self.t_start
            frac = self.done / max(self.total, 1)
            expected = elapsed / max(frac, 1e-12)
            if self.mode is True or (
                elapsed > 0.25 and expected > 1.0 and frac < 0.9 and _is_terminal()
            ):
                self._start()
        if self.progress is not None:
            self.progress.update(self.task, completed=self.done)

    def close(self):
        if self.progress is not None:
            self.progress.stop()
        if self._phases is not None:
            self._phases.resume()
            self._phases = None

"""The ``vpforms`` command line (argparse + rich), one module per subcommand group.

Subcommands: ``cases``, ``classify``, ``errata`` (:mod:`.tables`); ``run``, ``poincare``
(:mod:`.trace`), ``verify`` (:mod:`._distributed`, registered by :mod:`.trace`); ``order``, ``drift`` (:mod:`.studies`); ``fieldlines`` (:mod:`.fieldlines`); ``demo``
(:mod:`.demo`) — each with
``--help``. Each group module has ``register(sub)`` adding its subparsers; shared parsing and
method construction live in :mod:`._common`. ``main(argv) -> int`` never raises for bad input: it
prints one line ``vpforms: error: …`` and returns 2 (usage) or 1 (a failed computation).  Set
``VPFORMS_DEBUG=1`` to get the traceback instead.  Python warnings raised by a command are printed
as one line each, ``vpforms: warning: …`` (none after an error, whose line says what went wrong;
all of them with ``-v``); ``-v`` also shows the C compiler's output of each new native kernel
(the ``vpforms`` loggers at level INFO).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as dist_version

from rich.console import Console

from .._cache import enable_jax_cache
from .._version import __version__
from . import demo, fieldlines, studies, tables, trace
from ._common import CLIError, _Parser

__all__ = ["main", "build_parser", "CLIError"]

#: the subcommand groups, in the order ``vpforms --help`` lists them
GROUPS = (tables, trace, studies, fieldlines, demo)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="vpforms",
        description="Volume-preserving generating forms in R³ (Verdier, Xue, Zanna, arXiv 1412.6345): "
                    "integrators, particle tracing, Poincaré sections and diagnostics.",
    )
    parser.add_argument("--version", action="version", version=f"vpforms {version()}")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="also show the C compiler's output for new native kernels, and every warning")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for group in GROUPS:
        group.register(sub)
    for p in sub.choices.values():  # -v after the subcommand too (SUPPRESS: never undoes a -v before it)
        p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                       help="show the C compiler's output for new native kernels, and every warning")
    return parser


def version() -> str:
    """The installed distribution's version (importlib.metadata), else the package's own."""
    try:
        return dist_version("vpforms")
    except PackageNotFoundError:  # a source tree that is not installed
        return __version__


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 failed computation, 2 bad arguments).

    Run as the ``vpforms`` command (``argv`` None: the process's own arguments) it first turns on
    JAX's persistent compilation cache in vpforms' cache folder (:func:`vpforms._cache.enable_jax_cache`:
    a method on a spline or coil field compiles its checks once, not in every process); called
    with ``argv`` from Python it leaves the calling process's JAX configuration alone."""
    if argv is None:
        enable_jax_cache()
    wide = not sys.stdout.isatty() and not os.environ.get("COLUMNS")
    console = Console(width=250) if wide else Console()  # tables don't wrap in pipes
    debug = bool(os.environ.get("VPFORMS_DEBUG"))
    verbose = False
    with warnings.catch_warnings(record=not debug) as caught:  # debug: warnings as Python shows them
        try:
            args = build_parser().parse_args(argv)
        except CLIError as exc:
            code, line = 2, _error_line(str(exc))
        except SystemExit as exc:  # --help, --version
            code, line = int(exc.code or 0), None
        else:
            verbose = bool(getattr(args, "verbose", False))
            with _logging_to_stderr(verbose):
                code, line = _run(args, console, debug)
    if caught and (code == 0 or verbose):  # after an error, its line says what happened
        for w in dict.fromkeys(f"{w.category.__name__}: {' '.join(str(w.message).split())}" for w in caught):
            print(f"vpforms: warning: {w}", file=sys.stderr)
    if line:
        print(line, file=sys.stderr)
    return code


def _run(args, console, debug: bool) -> tuple[int, str | None]:
    """Run the subcommand: (exit code, the one line for stderr or None)."""
    try:
        return int(args.func(args, console) or 0), None
    except CLIError as exc:
        return 2, _error_line(str(exc))
    except KeyboardInterrupt:
        return 130, "vpforms: interrupted"
    except BrokenPipeError:  # e.g. `vpforms errata | head`
        sys.stdout = open(os.devnull, "w")
        return 0, None
    except Exception as exc:  # one line, no traceback, for any failure
        if debug:
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        return 1, _error_line(f"{type(exc).__name__}: {msg}")


class _logging_to_stderr:
    """With -v: the ``vpforms`` loggers' INFO messages (e.g. the C compiler's output) on stderr."""

    def __init__(self, on: bool):
        self.on, self.log = on, logging.getLogger("vpforms")

    def __enter__(self):
        if self.on:
            self.handler = logging.StreamHandler(sys.stderr)
            self.handler.setFormatter(logging.Formatter("vpforms: %(message)s"))
            self.level = self.log.level
            self.log.addHandler(self.handler)
            self.log.setLevel(logging.INFO)

    def __exit__(self, *exc):
        if self.on:
            self.log.removeHandler(self.handler)
            self.log.setLevel(self.level)


def _error_line(msg: str) -> str:
    """The one-line error report (plain stderr: never wrapped)."""
    return "vpforms: error: " + " ".join(msg.split())

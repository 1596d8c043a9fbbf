"""The ``vpforms`` command line (argparse + rich), one module per subcommand group.

Subcommands: ``cases``, ``classify``, ``errata`` (:mod:`.tables`); ``run``, ``poincare``
(:mod:`.trace`), ``verify`` (:mod:`._distributed`, registered by :mod:`.trace`); ``order``, ``drift`` (:mod:`.studies`); ``fieldlines`` (:mod:`.fieldlines`); ``demo``
(:mod:`.demo`) — each with
``--help``. Each group module has ``register(sub)`` adding its subparsers; shared parsing and
method construction live in :mod:`._common`. ``main(argv) -> int`` never raises for bad input: it
prints one line ``vpforms: error: …`` and returns 2 (usage) or 1 (a failed computation).  Set
``VPFORMS_DEBUG=1`` to get the traceback instead.
"""

from __future__ import annotations

import argparse
import os
import sys

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
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for group in GROUPS:
        group.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 failed computation, 2 bad arguments)."""
    from rich.console import Console

    wide = not sys.stdout.isatty() and not os.environ.get("COLUMNS")
    console = Console(width=250) if wide else Console()  # tables don't wrap in pipes
    debug = bool(os.environ.get("VPFORMS_DEBUG"))
    try:
        args = build_parser().parse_args(argv)
    except CLIError as exc:
        _error(str(exc))
        return 2
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    try:
        return int(args.func(args, console) or 0)
    except CLIError as exc:
        _error(str(exc))
        return 2
    except KeyboardInterrupt:
        print("vpforms: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `vpforms errata | head`
        sys.stdout = open(os.devnull, "w")
        return 0
    except Exception as exc:  # one line, no traceback, for any failure
        if debug:
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        _error(f"{type(exc).__name__}: {msg}")
        return 1


def _error(msg: str) -> None:
    """The one-line error report (plain stderr: never wrapped)."""
    print("vpforms: error: " + " ".join(msg.split()), file=sys.stderr)

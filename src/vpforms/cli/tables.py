"""Tables and symbolic reports: ``cases``, ``classify``, ``errata``."""

from __future__ import annotations

from collections import Counter

import sympy as sp
from rich.table import Table

from .. import symbolic
from .._case import Case, cases
from ..symbolic import tables
from ._common import (
    CLIError,
    _parse_perm,
)


def _cases_table():
    table = Table(title="The 36 cases (σ, Σ) of eq:volpot and their classes")
    for col in ("#", "σ", "Σ", "τ = σ⁻¹∘Σ", "sgn τ", "class", "x₊ x∘ x₋", "X₊ X∘ X₋"):
        table.add_column(col)
    for n, c in enumerate(cases(), start=1):
        table.add_row(
            str(n),
            c.sigma.one_line(),
            c.Sigma.one_line(),
            f"{c.tau.one_line()} = {c.tau.cycle_notation()}",
            f"{c.sign:+d}",
            c.cls,
            f"x{c.x_plus} x{c.x_circ} x{c.x_minus}",
            f"X{c.X_plus} X{c.X_circ} X{c.X_minus}",
        )
    return table


def _cmd_cases(args, console) -> int:
    if args.format != "rich":  # the renderers of vpforms.symbolic.tables (issue #11)
        print((tables.table36_markdown if args.format == "markdown" else tables.table36_latex)(
            prove=args.prove), end="")
        return 0
    console.print(_cases_table())
    counts = Counter(c.cls for c in cases())
    console.print("class counts: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0


def _cmd_classify(args, console) -> int:
    c = Case(_parse_perm(args.sigma), _parse_perm(args.Sigma))
    console.print(f"case {c}: τ = σ⁻¹∘Σ = {c.tau.one_line()}, sgn τ = {c.sign:+d}, class [bold]{c.cls}[/bold]")
    r = c.roles
    console.print(
        f"roles: x₊ = x{r['x+']}, x∘ = x{r['x∘']}, x₋ = x{r['x-']};  "
        f"X₊ = X{r['X+']}, X∘ = X{r['X∘']}, X₋ = X{r['X-']}"
    )
    console.print(f"sign in (volpot2) must be sgn τ = {c.sign:+d}")
    return 0


def _errata_function():
    """The symbolic errata report of issue #3, if present: a callable returning text."""
    for mod_name in ("errata", "report"):
        try:
            mod = __import__(f"{symbolic.__name__}.{mod_name}", fromlist=["_"])
        except ImportError:
            continue
        for fn_name in ("errata_report", "report", "errata"):
            fn = getattr(mod, fn_name, None)
            if callable(fn):
                return fn
    for fn_name in ("errata_report", "errata"):
        fn = getattr(symbolic, fn_name, None)
        if callable(fn):
            return fn
    raise CLIError("the symbolic errata report (issue #3, vpforms.symbolic) is not available in this build")


def _cmd_errata(args, console) -> int:
    fn = _errata_function()
    kw = {}
    if args.matrix:
        try:
            rows = [[sp.Rational(v.strip()) for v in r.split(",")] for r in args.matrix.split(";")]
            A = sp.Matrix(rows)
        except (ValueError, TypeError, sp.SympifyError) as exc:
            raise CLIError(f"--matrix must be 3 rows 'a,b,c;d,e,f;g,h,i' of numbers: {exc}") from None
        if A.shape != (3, 3) or A.trace() != 0:
            raise CLIError("--matrix must be a traceless 3×3 matrix, e.g. '1,2,3;-1,2,1;2,-2,-3'")
        kw["A"] = A
    fmt = "markdown" if args.markdown else "text"
    with console.status("checking the paper's formulas symbolically (about 30 s on a generic matrix)…"):
        try:
            out = fn(fmt=fmt, **kw)
        except TypeError:  # a report function without the fmt/A keywords
            out = fn()
    text = out if isinstance(out, str) else str(out)
    if not args.markdown:
        console.print("[bold]Errata of arXiv 1412.6345, measured symbolically[/bold] "
                      "(consistency M(0) = I, M'(0) = A, order and det of X = M(h)x)")
    print(text)
    return 0


def register(sub) -> None:
    """Add this group's subcommands to the subparsers ``sub``."""
    p = sub.add_parser("cases", help="print the 36-case classification table",
                       description="Print the 36 cases (σ, Σ), τ = σ⁻¹∘Σ, its sign and class.")
    p.add_argument("--format", choices=("rich", "markdown", "latex"), default="rich",
                   help="rich table (default), or Markdown / LaTeX longtable with the forms of each case")
    p.add_argument("--prove", action="store_true",
                   help="with --format markdown|latex: prove dλ = f*ν̃ − ν for each case (SymPy, slower)")
    p.set_defaults(func=_cmd_cases)

    p = sub.add_parser("classify", help="classify a case (σ, Σ)",
                       description="Class, sign and roles of the case (σ, Σ).")
    p.add_argument("sigma", help="σ in one-line notation, e.g. 3,2,1 or 321")
    p.add_argument("Sigma", help="Σ in one-line notation, e.g. 1,2,3")
    p.set_defaults(func=_cmd_classify)

    p = sub.add_parser("errata", help="the paper's errata, checked symbolically",
                       description="Print the symbolic errata report (every printed formula that is wrong, "
                                   "with the corrected one, re-derived by SymPy).")
    p.add_argument("--markdown", action="store_true", help="print raw Markdown")
    p.add_argument("--matrix", default=None, metavar="'a,b,c;d,e,f;g,h,i'",
                   help="check on this traceless rational matrix instead of the generic symbolic one "
                        "(faster, but a special matrix can hide a defect)")
    p.set_defaults(func=_cmd_errata)

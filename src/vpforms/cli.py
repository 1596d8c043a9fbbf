"""The ``vpforms`` command line."""

from __future__ import annotations

import argparse
import sys

__all__ = ["main"]


def _cases_table():
    from rich.table import Table

    from ._case import cases

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
    console.print(_cases_table())
    return 0


def _cmd_classify(args, console) -> int:
    from ._case import Case

    c = Case(_parse_perm(args.sigma), _parse_perm(args.Sigma))
    console.print(repr(c))
    console.print(f"roles: {c.roles}")
    return 0


def _cmd_demo(args, console) -> int:
    import jax.numpy as jnp
    import numpy as np

    from collections import Counter

    from ._case import Case, cases
    from ._map import GeneratingMap

    console.print(_cases_table())
    counts = Counter(c.cls for c in cases())
    console.print("class counts: " + ", ".join(f"{k}: {v}" for k, v in counts.items()))

    # One generating map: SE+SE case with nearly-linear potentials (twist holds near the origin).
    def phi(a, b, c):
        return a * b + 0.1 * jnp.sin(a + 2.0 * c) * b

    def Phi(a, b, c):
        return b * c + 0.1 * jnp.cos(b - a) * c

    case = Case((3, 2, 1), (1, 2, 3))
    m = GeneratingMap(phi, Phi, case)
    x = np.random.default_rng(0).uniform(-0.5, 0.5, (1000, 3))
    X = m(x)
    det = m.det(x)
    back = m.inverse()(X, guess=x)
    console.print(f"generating map {case}, class {case.cls}, sign {case.sign:+d} on 1000 points:")
    console.print(f"  max |det J − 1|     = {float(jnp.max(jnp.abs(det - 1))):.2e}")
    console.print(f"  max |f⁻¹(f(x)) − x| = {float(jnp.max(jnp.abs(back - x))):.2e}")
    console.print(f"  max residual        = {float(jnp.max(jnp.abs(m.residual(x, X)))):.2e}")
    return 0


def _parse_perm(text: str):
    from ._perm import Perm

    digits = [c for c in text if c.isdigit()]
    if len(digits) != 3 or any(not c.isdigit() and c not in "(), " for c in text):
        raise ValueError(f"{text!r} is not a permutation of (1, 2, 3), e.g. '3,2,1' or '(3,2,1)'")
    return Perm(tuple(int(c) for c in digits))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vpforms", description="Volume-preserving generating forms in R³ (arXiv 1412.6345)."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("cases", help="print the 36-case classification table")
    p.set_defaults(func=_cmd_cases)
    p = sub.add_parser("classify", help="classify a case (σ, Σ)")
    p.add_argument("sigma", help="σ in one-line notation, e.g. 3,2,1")
    p.add_argument("Sigma", help="Σ in one-line notation, e.g. 1,2,3")
    p.set_defaults(func=_cmd_classify)
    p = sub.add_parser("demo", help="a short tour")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    from rich.console import Console

    console = Console()
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args, console) or 0)
    except (ValueError, TypeError) as exc:
        console.print(f"[red]error:[/red] {exc}")
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

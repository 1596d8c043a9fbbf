"""Fuzzing field preparation (issue #22): ≥ 10⁴ generated ``--field`` strings through the command
line's preparation of a user field, written to results_fuzz_fields.md.

The strings mix nested exponents, long sums and products, complex-valued and overflowing
expressions, divergence-free fields by construction (f(y, z), g(x, z), h(x, y)) and as the curl of a
random vector potential (they need a proof), random fields (mostly not divergence free) and broken
syntax.  Each goes through what ``vpforms run --field S`` does before its first step — parsing,
the real-field check on the box and the initial conditions, the divergence check, linearity
detection (``_common._problem``) — and, for every 20th string, the SE and DL potentials (closed
form or quadrature, the budgeted ``integrate``).  Required: every string finishes in ≤ 10 s, none ends in anything but a
one-line refusal (exit 2) or an accepted field (exit 0), and an accepted field is real and finite
at the sampled points and divergence free — checked independently here, in 30-digit arithmetic at
random points (relative to the field's derivatives).  Every 400th accepted field is also run
end to end (``vpforms run --steps 1``).  The results file is rewritten every 250 strings (a
checkpoint), so a long run can be read while it goes.

    python benchmarks/fields/fuzz_fields.py [--smoke] [--n 10000] [--seed 0] [--out benchmarks/fields/results_fuzz_fields.md]

(10⁴ strings in two shards on two cores: ``--n 5000 --seed 0`` and ``--n 5000 --seed 1 --out
benchmarks/fields/results_fuzz_fields_seed1.md``.)

A string that ran longer than 60 s would end the script with a traceback of where it hung
(faulthandler; no signals, which the time budget of vpforms._budget uses itself).
"""

from __future__ import annotations

import faulthandler
import io
import os
import random
import sys
import time
from collections import Counter
from contextlib import redirect_stderr, redirect_stdout

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import machine, parser  # noqa: E402

V = ["x", "y", "z"]
FUN = ["sin", "cos", "exp", "tanh", "atan", "sqrt", "log", "cosh", "erf", "asin", "acos"]
CATEGORIES = ["nested exponents", "long sum", "long product", "complex-valued", "overflowing",
              "divergence free (construction)", "divergence free (curl)", "random", "syntax"]


def _expr(r: random.Random, vars_, depth: int = 0) -> str:
    """A random expression in vars_ (text)."""
    k = r.random()
    if depth > 2 or k < 0.3:
        return r.choice(vars_ + [str(r.randint(-3, 5)), f"{r.randint(1, 9)}/{r.randint(1, 9)}", "pi"])
    if k < 0.55:
        return f"{r.choice(FUN[:5])}({_expr(r, vars_, depth + 1)})"
    if k < 0.7:
        return f"({_expr(r, vars_, depth + 1)})**{r.randint(2, 4)}"
    op = r.choice(["+", "-", "*", "*", "/"])
    return f"({_expr(r, vars_, depth + 1)}){op}({_expr(r, vars_, depth + 1)})"


def _div_free(r: random.Random) -> str:
    return ", ".join(_expr(r, [v for v in V if v != w]) for w in V)


def _curl(r: random.Random) -> str:
    import sympy as sp

    from vpforms._parse import parse_expression

    A = [parse_expression(_expr(r, V)) for _ in range(3)]
    x, y, z = sorted(set().union(*(a.free_symbols for a in A)) | set(sp.symbols("x1 x2 x3", real=True)),
                     key=str)[:3]
    curl = (sp.diff(A[2], y) - sp.diff(A[1], z), sp.diff(A[0], z) - sp.diff(A[2], x),
            sp.diff(A[1], x) - sp.diff(A[0], y))
    return ", ".join(str(c) for c in curl)


def generate(r: random.Random) -> tuple[str, str]:
    """(category, field text)."""
    cat = r.choice(CATEGORIES)
    v = r.choice(V)
    if cat == "nested exponents":
        e = [r.choice([2, 9, 99, 999, 1000, 1001]) for _ in range(3)]
        text = r.choice([f"(({r.randint(2, 9)}**{e[0]})**{e[1]})**{e[2]}*{v}", f"((({v}**{e[0]})**{e[1]})**{e[2]})",
                         f"{v}**{e[0]}**{e[1]}", f"(x+y+z)**{e[0]}", f"exp(exp(exp({e[0]})))*{v}",
                         f"({v}**{e[0]})**(1/{e[1]})", f"(1+{v}**2)**(-{e[0]})", f"2**{e[0]}*{v}**{e[1] % 7}"])
        return cat, r.choice([f"{text}, 0, 0", f"0, {text.replace(v, 'x')}, 0", f"0, 0, {text.replace(v, 'y')}"])
    if cat == "long sum":
        n = r.randint(5, 120)
        f, w = r.choice(["sin", "cos"]), r.choice(["y", "z"])
        terms = [f"{r.choice(['', str(r.randint(1, 9)) + '*', '1/' + str(k) + '*'])}{f}({k}*{w})" for k in range(1, n + 1)]
        text = "+".join(terms)
        if len(text) > 1900:
            text = text[:text.rfind("+", 0, 1900)]
        return cat, r.choice([f"{text}, 0, 0", f"{text}, {text.replace(w, 'x')}, 0",
                              f"{text}, x, {r.choice(['0', 'x*' + w])}"])
    if cat == "long product":
        n = r.randint(3, 40)
        text = "*".join(f"({r.choice(['y', 'z'])}+{r.randint(1, 9)})" for _ in range(n))
        return cat, r.choice([f"{text}, 0, 0", f"({text})**{r.randint(2, 30)}, 0, 0", f"{text}, x*{text}, 0"])
    if cat == "complex-valued":
        c = r.randint(2, 9)
        text = r.choice([f"sqrt({v}-{c})", f"log({v}-{c})", f"acos({c})*{v}", f"asin({c}*{v})", f"(-{c})**(1/3)*{v}",
                         f"sqrt(-1-{v}**2)", f"log(-{c})", f"({v}-{c})**(1/2)", f"acosh({v})", f"atanh({c}*{v})"])
        return cat, r.choice([f"{text}, 0, 0", f"0, {text.replace(v, 'z')}, 0", f"0, 0, {text.replace(v, 'x')}"])
    if cat == "overflowing":
        c = r.choice([710, 1000, 10**6])
        text = r.choice([f"exp({c})*{v}", f"exp({c}*{v})", f"cosh({c}*{v})", f"1e300*exp(100*{v})", f"10**300*{v}**3*1e10",
                         f"{v}**1000*1e300", f"exp(exp({v}+7))", f"sinh({c})"])
        return cat, r.choice([f"{text}, 0, 0", f"0, {text.replace(v, 'z')}, 0", f"0, 0, {text.replace(v, 'x')}"])
    if cat == "divergence free (construction)":
        return cat, _div_free(r)
    if cat == "divergence free (curl)":
        return cat, _curl(r)
    if cat == "random":
        return cat, ", ".join(_expr(r, V) for _ in range(3))
    text = _div_free(r)  # syntax: a valid field, broken
    i = r.randrange(len(text) + 1)
    return cat, text[:i] + r.choice(["(", ")", ",", "**", "sin(", "", "'", ".", "__"]) + text[i:]


def _independent_check(field, n: int = 4) -> str | None:
    """Why an accepted field is not real/finite or not divergence free, or None (30 digits)."""
    import mpmath
    import numpy as np
    import sympy as sp

    from vpforms.fields import sample_box

    pts = sample_box(field.box, 64, 12345)
    syms, exprs = field.symbols, field.exprs
    for e in exprs:
        try:
            with np.errstate(all="ignore"):
                v = np.asarray(sp.lambdify(syms, e, ["scipy", "numpy"])(*pts.T), dtype=complex)
        except (TypeError, ValueError, ArithmeticError):
            continue  # not vectorisable here: the 30-digit check below still evaluates it
        if not np.all(np.isfinite(v)) or np.any(v.imag != 0):
            return "non-finite or complex value at a box point"
    div = sum(sp.diff(e, s) for e, s in zip(exprs, syms))
    f = sp.lambdify(syms, [div, *(sp.diff(e, s) for e in exprs for s in syms)], "mpmath")
    with mpmath.workdps(30):
        for p in pts[:n]:
            try:
                vals = [abs(mpmath.mpmathify(v)) for v in f(*(mpmath.mpf(float(c)) for c in p))]
                d, scale = vals[0], max(vals[1:])
            except (TypeError, ValueError, ZeroDivisionError, OverflowError):
                continue
            if d > mpmath.mpf(10) ** -20 * max(scale, 1) and not (d < 1e-12 * max(scale, 1) and exprs and any(
                    e.atoms(sp.Float) for e in exprs)):
                return f"|div a| = {mpmath.nstr(d, 5)} at {p} (scale {mpmath.nstr(scale, 5)})"
    return None


def prepare(text: str, tmp: str, potentials: bool = True) -> tuple[int, str, object]:
    """(exit code, stderr line, field or None) of what `vpforms run --field text` does before its
    first step, plus (``potentials``) the SE and DL potentials."""
    from vpforms.cli import _common, build_parser

    args = build_parser().parse_args(["run", "--field", text, "--steps", "1", "--particles", "4",
                                       "--out", os.path.join(tmp, "o.npz")])
    try:
        prob = _common._problem(args)
        if potentials:
            prob.field.se_potentials, prob.field.dl_potentials  # noqa: B018 - built here (budgeted)
    except _common.CLIError as exc:
        return 2, str(exc), None
    return 0, "", prob.field


def run(n: int, seed: int, tmp: str, end_to_end_every: int = 400, potentials_every: int = 20, log=None,
        checkpoint=None):
    """Fuzz n strings; returns (rows of outcomes per category, stats dict, problems list)."""
    from vpforms.cli import main

    r = random.Random(seed)
    out: dict[str, Counter] = {c: Counter() for c in CATEGORIES}
    times: list[float] = []
    slowest: list[tuple[float, str]] = []
    problems: list[str] = []
    accepted = 0
    for k in range(n):
        try:
            cat, text = generate(r)
        except Exception:  # noqa: BLE001 - the generator's own SymPy (curl of junk)
            out["random"]["generator skipped"] += 1
            continue
        faulthandler.dump_traceback_later(60, exit=True)
        t = time.perf_counter()
        try:
            rc, msg, field = prepare(text, tmp, potentials=k % potentials_every == 0)
        except Exception as exc:  # noqa: BLE001 - a traceback: counted as a problem
            rc, msg, field = -1, f"{type(exc).__name__}: {exc}", None
        dt = time.perf_counter() - t
        faulthandler.cancel_dump_traceback_later()
        times.append(dt)
        slowest = sorted([*slowest, (dt, text)], reverse=True)[:5]
        if rc == -1:
            out[cat]["traceback"] += 1
            problems.append(f"traceback: {text!r}: {msg}")
        elif rc == 2:
            if "\n" in msg or not msg.strip():
                problems.append(f"not one line: {text!r}: {msg!r}")
            out[cat]["refused: " + _reason(msg)] += 1
        else:
            accepted += 1
            why = _independent_check(field)
            if why is not None:
                problems.append(f"accepted but {why}: {text!r}")
                out[cat]["ACCEPTED WRONGLY"] += 1
            else:
                out[cat]["accepted (" + ("symbolic" if field.divergence_check == "symbolic" else "numerical") + ")"] += 1
            if accepted % end_to_end_every == 1:  # the whole command, a sample
                err = io.StringIO()
                with redirect_stderr(err), redirect_stdout(io.StringIO()):
                    rc2 = main(["run", "--field", text, "--steps", "1", "--particles", "2", "--method", "rk4",
                                "--backend", "jax", "--out", os.path.join(tmp, "e.npz")])
                out[cat]["end to end: exit 0" if rc2 == 0 else f"end to end: exit {rc2}"] += 1
                if rc2 != 0:
                    problems.append(f"accepted, but the run exits {rc2}: {text!r}: {err.getvalue().strip()}")
        if dt > 10:
            problems.append(f"{dt:.1f} s (> 10 s): {text!r}")
        if (k + 1) % 250 == 0:
            if log is not None:
                print(f"{k + 1} strings, max {max(times):.2f} s, {len(problems)} problems", file=log, flush=True)
            if checkpoint is not None:
                checkpoint(out, _stats(times, accepted, slowest), problems)
    return out, _stats(times, accepted, slowest), problems


def _stats(times, accepted, slowest) -> dict:
    import numpy as np

    return {"strings": len(times), "accepted": accepted, "max_s": max(times, default=0.0),
             "mean_s": float(np.mean(times)) if times else 0.0, "p99_s": float(np.quantile(times, 0.99)) if times else 0.0,
             "over_10s": sum(t > 10 for t in times), "slowest": slowest}


def _reason(msg: str) -> str:
    for key, label in (("too large", "too large (parse budget)"), ("is complex", "complex"),
                       ("is not real", "complex"),
                       ("overflows", "overflows float64"), ("not finite", "not finite"),
                       ("not divergence free", "not divergence free"), ("unclosed", "unclosed '('"),
                       ("unbalanced", "unbalanced ')'"), ("3 components", "not 3 components"),
                       ("is not allowed", "character/token not allowed"), ("cannot", "cannot parse/evaluate"),
                       ("nodes", "tree size budget")):
        if key in msg:
            return label
    return "other: " + msg[:60]


def report(out, stats, problems, seed: int, seconds: float, smoke: bool, done: bool = True) -> str:
    lines = ["# Fuzzing field preparation (issue #22)", "",
             f"{stats['strings']} generated field strings (seed {seed}), each through what "
             "`vpforms run --field S` does before its first step (every 20th also the SE and DL "
             "potentials; every 400th accepted one also run end to end)"
             + ("." if done else " — **checkpoint: the run was still going**."), "",
             f"Time per string: max {stats['max_s']:.2f} s, mean {stats['mean_s']:.3f} s, 99th percentile "
             f"{stats['p99_s']:.2f} s; over 10 s: {stats['over_10s']}.  Slowest: "
             + "; ".join(f"{t:.2f} s {s[:80]!r}" for t, s in stats["slowest"]) + ".", "",
             f"Accepted: {stats['accepted']}; problems (tracebacks, lines that are not one line, wrong "
             f"acceptances, over 10 s, failed end-to-end runs): {len(problems)}.", "",
             "| category | outcome | count |", "|---|---|---|"]
    for cat, c in out.items():
        for k, v in sorted(c.items(), key=lambda kv: -kv[1]):
            lines.append(f"| {cat} | {k} | {v} |")
    lines += ["", *[f"* {p}" for p in problems[:50]], "", machine("fuzz_fields.py", seconds, smoke), ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_fuzz_fields.md"), rounds=1)
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    import tempfile

    n = 30 if args.smoke else args.n
    t0 = time.perf_counter()

    def checkpoint(out, stats, problems):
        with open(args.out, "w") as fh:
            fh.write(report(out, stats, problems, args.seed, time.perf_counter() - t0, args.smoke, done=False))

    with tempfile.TemporaryDirectory() as tmp:
        out, stats, problems = run(n, args.seed, tmp, log=sys.stderr, checkpoint=checkpoint)
    text = report(out, stats, problems, args.seed, time.perf_counter() - t0, args.smoke)
    with open(args.out, "w") as fh:
        fh.write(text)
    print(text)
    return 0 if not problems else 1


if __name__ == "__main__":
    raise SystemExit(main())

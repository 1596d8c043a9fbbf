"""Shared pieces of the ``vpforms`` command line: the one-line error type, argument parsers,
problem and method construction (cached), and the common argument groups."""

from __future__ import annotations

import argparse
import inspect
import math
import os
import sys
from typing import Any

from rich.table import Table

from .._case import Case
from .._integrate import RK4
from .._methods import compose, scheme
from .._parse import FieldSyntaxError, parse_number  # never sympify (eval) user text
from .._perm import Perm
from . import _fields
from ._errors import CLIError
from ._fields import add_field_args


class _Parser(argparse.ArgumentParser):
    """One-line errors; every option records, when given, ``args._given[dest] = option string`` (so that
    an option that does nothing in a mode can be refused even when its value is the default)."""

    def error(self, message: str):  # one line instead of usage + message
        raise CLIError(f"{message} (see '{self.prog} --help')")

    def parse_known_args(self, args=None, namespace=None):
        args = sys.argv[1:] if args is None else list(args)
        return super().parse_known_args(self._values_attached(args), namespace)

    def _values_attached(self, args: list[str]) -> list[str]:
        """``--Z -0.2,0.2`` → ``--Z=-0.2,0.2``: the value of an option that takes one value may
        start with '-' (a negative number, a comma list, an expression such as ``-y,x,0``).

        argparse reads such a token as an option unless it is one plain number, and stops with
        "expected one argument". A token is attached to the option before it when that option takes
        exactly one value and the token is not an option of this parser (``-v``, ``--steps``, …)."""
        one = {s for a in self._actions if a.nargs is None for s in a.option_strings}
        out, i = [], 0
        while i < len(args):
            tok = args[i]
            if tok == "--":
                out.extend(args[i:])
                break
            nxt = args[i + 1] if i + 1 < len(args) else None
            if tok in one and nxt is not None and self._is_value(nxt):
                out.append(f"{tok}={nxt}")
                i += 2
                continue
            out.append(tok)
            i += 1
        return out

    def _is_value(self, tok: str) -> bool:
        """Whether ``tok``, which follows an option of one value, is that value although it starts
        with '-': not '-' alone, not a long option, not a short option of this parser (``-v``, ``-vh``)."""
        if not tok.startswith("-") or tok == "-" or tok.startswith("--"):
            return False
        return tok[:2] not in self._option_string_actions

    def add_argument(self, *args, **kwargs):
        action = super().add_argument(*args, **kwargs)
        if action.option_strings:
            action.__class__ = _recording(type(action))
        return action


_RECORDING: dict = {}


def _recording(cls):
    """``cls`` that also records its dest and spelling in ``namespace._given`` when it is used."""
    if cls not in _RECORDING:
        def __call__(self, parser, namespace, values, option_string=None):
            namespace.__dict__.setdefault("_given", {})[self.dest] = option_string or self.dest
            cls.__call__(self, parser, namespace, values, option_string)

        _RECORDING[cls] = type(cls.__name__, (cls,), {"__call__": __call__})
    return _RECORDING[cls]


def given(args, dest: str) -> bool:
    """Whether the option with this ``dest`` was on the command line (not just its default)."""
    return dest in getattr(args, "_given", ())


def refuse_unless(args, dests, applies: bool, why: str) -> None:
    """Refuse those of the options ``dests`` that were given when they do nothing (``applies`` is
    false): one line, "--a, --b do nothing ``why``", e.g. why = "with --x0 (…)"."""
    if applies:
        return
    bad = [args._given[d] for d in dests if given(args, d)]
    if bad:
        raise CLIError(f"{', '.join(bad)} {'does' if len(bad) == 1 else 'do'} nothing {why}")


# --------------------------------------------------------------------------------------------
# Parsing helpers
# --------------------------------------------------------------------------------------------
def _parse_perm(text: str):
    digits = [c for c in text if c.isdigit()]
    if len(digits) != 3 or any(not c.isdigit() and c not in "(), " for c in text):
        raise CLIError(f"{text!r} is not a permutation of (1, 2, 3); write e.g. 321, 3,2,1 or (3,2,1)")
    try:
        return Perm(tuple(int(c) for c in digits))
    except (ValueError, TypeError):
        raise CLIError(f"{text!r} is not a permutation of (1, 2, 3) (a repeated or out-of-range "
                       "digit); write e.g. 321, 3,2,1 or (3,2,1)") from None


def _parse_value(text: str):
    """An int or float literal, else a constant SymPy expression such as sqrt(2/3)."""
    if not text:
        raise CLIError("a parameter has no value: write NAME=VALUE, e.g. --param C=0")
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    try:
        return parse_number(text, what="parameter value")
    except FieldSyntaxError as exc:
        raise CLIError(f"cannot read {exc}") from None  # "cannot read parameter value: 'foo' is not a number (…)"


def _parse_params(items: list[str] | None) -> dict[str, Any]:
    out = {}
    for item in items or []:
        for part in item.split(","):
            if not part.strip():
                continue
            if "=" not in part:
                raise CLIError(f"parameter {part!r} must be NAME=VALUE, e.g. --param C=0")
            k, v = part.split("=", 1)
            out[k.strip()] = _parse_value(v.strip())
    return out


def _checked(convert, ok, must_be: str):
    """An argparse ``type``: convert the text, then require ``ok(value)`` (one-line errors)."""
    noun = "an integer" if convert is int else "a number"

    def parse(text: str):
        try:
            v = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {noun}") from None
        if not ok(v):
            raise argparse.ArgumentTypeError(f"{text!r} must be {must_be}")
        return v

    return parse


_positive_float = _checked(float, lambda v: v > 0 and math.isfinite(v), "a positive number")
_finite_float = _checked(float, math.isfinite, "a finite number")
_positive_int = _checked(int, lambda v: v >= 1, "a positive integer")
#: θ of the discrete Lagrangians: the two values documented (and tested) are 0 and ½
_theta = _checked(float, lambda v: v in (0.0, 0.5), "0 or 0.5 (θ of the discrete Lagrangian)")


def _float_list(text: str) -> list[float]:
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers") from None
    if not vals or any(not (v > 0 and math.isfinite(v)) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r} must list positive numbers")
    return vals


def _finite_list(text: str) -> list[float]:
    """A comma-separated list of finite numbers (any sign), e.g. a polygon R1,Z1,R2,Z2,…"""
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r} must list finite numbers")
    return vals


# --------------------------------------------------------------------------------------------
# Problems and methods (the APIs of issues #4 and #5)
# --------------------------------------------------------------------------------------------
def _problem(args):
    try:
        from .. import problems
    except ImportError as exc:  # pragma: no cover - only while issue #4 is missing
        raise CLIError(f"the problem library (vpforms.problems) is not available: {exc}") from None
    # the points of --x0 are the initial conditions: --particles and --seed would do nothing
    refuse_unless(args, ("particles", "seed"), not getattr(args, "x0", None),
                  "with --x0 (its points are the initial conditions)")
    params = _parse_params(getattr(args, "param", None))
    name = _fields.problem_name(args)  # --field/--field-file (issue #11) or --problem, and --x0
    if _fields.wants_user_field(args):
        prob = _fields.with_x0(_fields.user_problem(args, params), args)
        _fields.check_initial_conditions(prob, args)  # real and finite there (issue #22)
        return prob
    try:
        return _fields.with_x0(problems.get(name, **params), args)
    except KeyError as exc:
        raise CLIError(str(exc.args[0] if exc.args else exc)) from None
    except TypeError as exc:
        raise CLIError(_bad_params_message(problems, name, params, exc)) from None
    except ValueError as exc:  # e.g. a value out of the problem's range
        raise CLIError(f"bad parameters for problem {name!r}: {exc}") from None


def _bad_params_message(problems, name, params, exc) -> str:
    """Name the parameters the problem does not take and list the ones it does."""
    make = problems._MAKERS[str(name).lower().replace("-", "_")][0]
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    valid = [p.name for p in inspect.signature(make).parameters.values()
             if p.kind in kinds and p.name not in ("name", "source")]
    if name == "abc_gi":
        valid = ["A", "B", "C"]
    bad = [k for k in params if k not in valid]
    if not bad:
        return f"bad parameters for problem {name!r}: {exc}"
    return (f"problem {name!r} has no parameter(s) {', '.join(bad)}; its parameters are "
            f"{', '.join(valid) if valid else '(none)'}")


_METHODS: dict = {}


def _method(field, cls: str = "SE+SE", case=None, order: int = 1, fast: bool = False, theta=None,
            recover: bool = True, composition: str | None = None, engine: bool = False):
    """A vpforms method (class representative or explicit case, composed to ``order``) or RK4.

    Methods are cached per (field, options) so that repeated in-process calls (tests, the demo)
    reuse their compiled kernels.
    """
    key = (id(field), str(cls).strip().upper(), case, order, fast, theta, recover, composition, engine)
    hit = _METHODS.get(key)
    if hit is not None and hit[0] is field:
        return hit[1]
    m = _make_method(field, cls, case, order, fast, theta, recover, composition, engine)
    _METHODS[key] = (field, m)
    return m


def _make_method(field, cls, case, order, fast, theta, recover=True, composition=None, engine=False):
    if str(cls).strip().lower() == "rk4":
        bad = [name for name, on in (("--case", case is not None), ("--order", order != 1), ("--fast", fast),
                                     ("--engine", engine),
                                     ("--theta", theta is not None), ("--no-recover", not recover),
                                     ("--composition", composition is not None)) if on]
        if bad:
            raise CLIError(f"rk4 is the explicit baseline: {', '.join(bad)} "
                           f"{'does' if len(bad) == 1 else 'do'} not apply")
        return RK4(field)
    opts = {}
    if fast and engine:
        raise CLIError("--fast and --engine ask for two evaluations of the same map: choose one")
    if fast:
        opts["fast"] = True
    if engine:  # the DL classes' engine form (their default is the nested θ-stages)
        opts["fast"] = False
    if theta is not None:
        opts["theta"] = theta
    if not recover:  # issue #12: --no-recover
        opts["recover"] = False
    try:
        m = scheme(field, case if case is not None else cls, **opts)
    except ValueError as exc:  # unknown class, option that does not apply, bad θ: a usage error
        raise CLIError(str(exc)) from None
    if order == 1:
        if composition is not None:
            raise CLIError("--composition chooses the coefficients of --order 4, 6 or 8")
        return m
    if order not in (2, 4, 6, 8):
        raise CLIError(f"--order must be 1, 2, 4, 6 or 8, not {order}")
    try:
        return compose(m, order=order, scheme=composition)
    except ValueError as exc:  # unknown composition for that order
        raise CLIError(f"--composition: {exc}") from None


def _method_from_args(args, field):
    case = None
    if getattr(args, "case", None):
        case = Case(_parse_perm(args.case[0]), _parse_perm(args.case[1]))
    return _method(field, args.method, case, args.order, args.fast, args.theta,
                   not getattr(args, "no_recover", False), getattr(args, "composition", None),
                   getattr(args, "engine", False))


def _parse_method_spec(spec: str) -> tuple[str, int]:
    """'SE+SE' → (SE+SE, 1); 'SE+SE:4' → (SE+SE, 4); 'rk4' → (rk4, 1)."""
    name, _, order = spec.partition(":")
    try:
        return name.strip(), int(order) if order else 1
    except ValueError:
        raise CLIError(f"method spec {spec!r} must be CLASS or CLASS:ORDER, e.g. SE+SE:4 or rk4") from None


def _spec_label(name: str, order: int) -> str:
    if name.lower() == "rk4":
        return "RK4"
    return name.upper() if order == 1 else f"{name.upper()} ∘ order {order}"



def _summary_table(title: str, rows: dict[str, Any]):
    t = Table(title=title, show_header=False)
    t.add_column("", style="bold")
    t.add_column("", overflow="fold")
    for k, v in rows.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        t.add_row(str(k), str(v))
    return t


#: the suffixes each kind of output accepts: a file is written at exactly the name given (never a
#: name with a suffix added), so a name of another kind is refused before the computation
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
CSV_SUFFIXES = (".csv",)
RUN_SUFFIXES = (".npz", ".zarr")


def _check_out(args, *outputs: tuple[str, tuple[str, ...]]) -> set[str]:
    """Fail before the computation, not after it, for outputs ``(dest, suffixes)`` of ``args``:
    a name without one of the accepted suffixes (lower case), a folder that does not exist,
    two outputs on one file. Returns the paths that exist already (:func:`_written` says so when
    they are replaced)."""
    seen: dict[str, str] = {}
    existing = set()
    for dest, suffixes in outputs:
        path, option = str(getattr(args, dest)), "--" + dest.replace("_", "-")
        if not path.endswith(suffixes):
            raise CLIError(f"{option} {path!r}: the name must end in {', '.join(suffixes)} (the file is "
                           "written at exactly the name given)")
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise CLIError(f"cannot write {path!r}: folder {folder!r} does not exist")
        key = os.path.normcase(os.path.abspath(path))
        if key in seen:
            raise CLIError(f"{seen[key]} and {option} both name {path!r}: give each output its own file")
        seen[key] = option
        if os.path.isdir(path) and not path.endswith(".zarr"):
            raise CLIError(f"{option} {path!r} is a folder, not a file")
        if os.path.exists(path):
            existing.add(path)
    return existing


def _written(path: str, existing: set[str]) -> str:
    """``path``, and "(replaced an existing file)" when it was there before the run."""
    return f"{path} (replaced an existing file)" if path in existing else path


def _add_problem_args(p, default_problem="abc"):
    p.add_argument("--problem", default=default_problem,
                   help=f"test problem (vpforms.problems.names(): abc, abc_gi, linear, lotka_volterra, "
                        f"stokes_sphere, tokamak, rigid_body); default {default_problem}")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="problem parameter, repeatable or comma-separated, e.g. --param C=0 or "
                        "--param B=sqrt(2/3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the initial conditions (default 0)")
    add_field_args(p, default_problem)  # --field, --field-file, --box, --x0 (issue #11)


def _add_method_args(p, default_order=1, backend=False):
    if backend:  # integrate's backend (issue 9): native C kernel where it can be generated
        p.add_argument("--backend", choices=("auto", "jax", "native"), default="auto",
                       help="auto (native where available, else JAX; default), jax or native; a .zarr "
                            "store run records it and every chunk and worker runs it (auto resumes a "
                            "store with the backend that wrote it)")
    p.add_argument("--method", default="SE+SE", metavar="CLASS",
                   help="class representative: SE+SE, SE+DL (= DL+SE), DL+DL, S1, S2, or rk4 "
                        "(the explicit baseline); default SE+SE")
    p.add_argument("--case", nargs=2, metavar=("SIGMA", "SIGMA2"),
                   help="an explicit case (σ, Σ) instead of the class representative, e.g. --case 2,3,1 1,3,2")
    p.add_argument("--order", type=int, default=default_order, choices=(1, 2, 4, 6, 8),
                   help=f"composition order (1 = the bare method); default {default_order}")
    p.add_argument("--composition", default=None, metavar="NAME",
                   help="coefficients for --order 4: suzuki (default), blanes_moan (the method and "
                        "its adjoint, 12 stages: the cheapest for a given accuracy), triple_jump; "
                        "--order 6: kahan_li (default), blanes_moan, yoshida, triple_jump; --order 8: "
                        "kahan_li (default), suzuki_umeno, yoshida, triple_jump")
    p.add_argument("--fast", action="store_true",
                   help="SE+SE: the closed-form shears, a direct evaluation of the same map (the DL "
                        "classes always run as their nested θ-stages unless --engine)")
    p.add_argument("--engine", action="store_true",
                   help="SE+DL, DL+DL: solve the discrete-Lagrangian generating map by the engine (the "
                        "reference form; it fails at the fold of a stage, and runs on JAX only)")
    p.add_argument("--theta", type=_theta, default=None,
                   help="θ of the discrete Lagrangian (DL classes): 0 (default) or 0.5")
    p.add_argument("--no-recover", action="store_true",
                   help="freeze a particle at a failed step instead of recovering it (bare method)")


"""Users' own fields and initial conditions on the command line: ``--field``, ``--field-file``,
``--x0`` (issue #11).  Called from :mod:`._common` (``_add_problem_args`` and ``_problem``).

A field file is TOML::

    name = "my-abc"
    components = ["A*sin(z) + C*cos(y)", "B*sin(x) + A*cos(z)", "C*sin(y) + B*cos(x)"]
    box = [[0, "2*pi"], [0, "2*pi"], [0, "2*pi"]]   # initial conditions are drawn uniformly here
    [params]
    A = 1
    B = "sqrt(2/3)"
    C = 0.5

Expressions are read by :mod:`vpforms._parse` (no ``eval`` of the text).  ``--param`` values
override the file's.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib

import numpy as np

from .._errors import VPFormsError
from .._parse import FieldSyntaxError, field_from_text, parse_number
from ._errors import CLIError

FIELD_FILE_EXAMPLE = __doc__.split("::")[1].split("Expressions")[0]


def add_field_args(p, default_problem: str) -> None:
    """--field / --field-file / --x0 (and --problem's default moved here so that the three
    sources of a field can be told apart)."""
    p.add_argument("--field", default=None, metavar="'a1, a2, a3'",
                   help="your own divergence-free field in x, y, z (or x1, x2, x3) and the --param "
                        "names, e.g. --field 'A*sin(z)+C*cos(y), B*sin(x)+A*cos(z), C*sin(y)+B*cos(x)' "
                        "--param A=1 --param B=0.8 --param C=0.5 (excludes --problem)")
    p.add_argument("--field-file", default=None, metavar="FILE.toml",
                   help="a field in a TOML file (keys components, params, box, name), e.g. "
                        "components = ['-y', 'x', '0']; box = [[-1, 1], [-1, 1], [-1, 1]]")
    p.add_argument("--box", default=None, metavar="LO,HI",
                   help="box [LO, HI]³ of the initial conditions of --field (default -1,1)")
    p.add_argument("--x0", default=None, metavar="POINTS.csv|.npy",
                   help="initial conditions: an (N, 3) or (3,) array in .npy or comma-separated .csv "
                        "(replaces --particles and --seed)")
    p.set_defaults(problem=None, default_problem=default_problem)


def wants_user_field(args) -> bool:
    return getattr(args, "field", None) is not None or getattr(args, "field_file", None) is not None


def problem_name(args) -> str:
    if wants_user_field(args):
        if args.problem is not None:
            raise CLIError("--field/--field-file and --problem are mutually exclusive")
        if args.field is not None and args.field_file is not None:
            raise CLIError("--field and --field-file are mutually exclusive")
    elif getattr(args, "box", None) is not None:
        raise CLIError("--box applies to --field only (a --problem has its own box)")
    return args.problem if args.problem is not None else getattr(args, "default_problem", "abc")


def _box(spec, what: str):
    if isinstance(spec, str):
        parts = spec.split(",")
        if len(parts) != 2:
            raise CLIError(f"{what} must be LO,HI, e.g. --box 0,6.283; got {spec!r}")
        spec = [parts] * 3
    try:
        rows = [[float(parse_number(str(v), what=what)) for v in r] for r in spec]
    except FieldSyntaxError as exc:
        raise CLIError(str(exc)) from None
    except TypeError:
        raise CLIError(f"{what} must be 3 pairs [lo, hi]") from None
    if len(rows) != 3 or any(len(r) != 2 or not r[0] < r[1] for r in rows):
        raise CLIError(f"{what} must be 3 pairs [lo, hi] with lo < hi; got {spec!r}")
    return tuple(tuple(r) for r in rows)


def _read_field_file(path: str) -> dict:
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise CLIError(f"cannot read --field-file {path!r}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CLIError(f"--field-file {path!r} is not valid TOML: {exc}") from None
    unknown = set(data) - {"name", "components", "params", "box"}
    if unknown:
        raise CLIError(f"--field-file {path!r}: unknown key(s) {', '.join(sorted(unknown))} "
                       "(expected components, params, box, name)")
    comps = data.get("components")
    if not isinstance(comps, list) or not all(isinstance(c, (str, int, float)) for c in comps):
        raise CLIError(f"--field-file {path!r}: 'components' must be a list of 3 strings")
    if not isinstance(data.get("params", {}), dict):
        raise CLIError(f"--field-file {path!r}: [params] must be a table NAME = value")
    return data


def user_problem(args, params: dict):
    """A :class:`~vpforms.problems.Problem` for --field / --field-file (params from --param)."""
    from ..problems._base import Problem, box_sampler

    if args.field is not None:
        comps, name, box = args.field, "user field", _box(args.box or "-1,1", "--box")
    else:
        data = _read_field_file(args.field_file)
        comps = data["components"]
        name = str(data.get("name", os.path.splitext(os.path.basename(args.field_file))[0]))
        box = _box(args.box, "--box") if args.box else _box(data.get("box", [[-1, 1]] * 3), "box")
        params = {**{str(k): v for k, v in data["params"].items()}, **params} if "params" in data else params
    try:
        field = field_from_text(comps, params, name=name, box=box)
    except (VPFormsError, ValueError, TypeError) as exc:
        raise CLIError(" ".join(str(exc).split())) from None
    return Problem(name=name, field=field, params={k: str(v) for k, v in params.items()},
                   x0=np.zeros((0, 3)), invariants={}, invariant_exprs={}, source="user",
                   periodic=None, box=box, description=f"user field {comps}", sampler=box_sampler(box))


def check_initial_conditions(prob, args) -> None:
    """One line (CLIError) if the field is complex or not finite at an initial condition: the
    points of --x0, or those --particles and --seed draw from the box — before any run."""
    if isinstance(prob, _GivenX0):
        pts, what = prob.points, f"a point of --x0 {args.x0}"
    elif getattr(args, "particles", None):
        pts = prob.initial_conditions(args.particles, seed=getattr(args, "seed", 0))
        what = "an initial condition drawn from the box"
    else:
        return
    try:
        prob.field.check_real(pts, what)
    except ValueError as exc:
        raise CLIError(" ".join(str(exc).split())) from None


def load_x0(path: str) -> np.ndarray:
    """(N, 3) finite initial conditions from .npy or .csv (one line errors)."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".npy", ".csv", ".txt"):
        raise CLIError(f"--x0 {path!r} must be a .npy or .csv file")
    try:
        if ext == ".npy":
            x = np.load(path, allow_pickle=False)
        else:
            x = np.loadtxt(path, delimiter=",", dtype=float, ndmin=2, comments="#")
    except OSError as exc:
        raise CLIError(f"cannot read --x0 {path!r}: {exc.strerror or exc}") from None
    except (ValueError, TypeError, EOFError) as exc:
        raise CLIError(f"--x0 {path!r} is not a numeric array: {' '.join(str(exc).split())}") from None
    if not isinstance(x, np.ndarray) or x.dtype.kind not in "iuf":
        raise CLIError(f"--x0 {path!r} must hold real numbers")
    x = np.asarray(x, dtype=float)
    if x.shape == (3,):
        x = x[None]
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] == 0:
        raise CLIError(f"--x0 {path!r} must have shape (N, 3) or (3,) with N ≥ 1; got {x.shape}")
    if not np.all(np.isfinite(x)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(x), axis=1))[0])
        raise CLIError(f"--x0 {path!r}: row {bad} is not finite: {x[bad].tolist()}")
    return x


@dataclasses.dataclass(frozen=True, eq=False)
class _GivenX0:
    """A problem whose initial conditions are the points of --x0 (n and seed are ignored)."""

    problem: object
    points: np.ndarray

    def __getattr__(self, name):
        return getattr(self.problem, name)

    def initial_conditions(self, n: int, seed: int = 0) -> np.ndarray:
        return self.points


def with_x0(prob, args):
    path = getattr(args, "x0", None)
    if not path:
        return prob
    pts = load_x0(path)
    if not math.isfinite(float(np.max(np.abs(pts)))):  # pragma: no cover - load_x0 checked
        raise CLIError(f"--x0 {path!r} is not finite")
    return _GivenX0(prob, pts)

"""``vpforms fieldlines``: the field-line study of a toroidal field (issue #21).

A Poincaré section at φ = const in (R, Z), the magnetic axis (fixed point of the return map, its
ι from the tangent map), the ι/q profile of the traced lines (weighted Birkhoff averages), optional
island chains (fixed points of Pᵐ) and a wall polygon; two PNGs and a CSV of the section points;
with ``--connection-length N``, a connection-length map: N lines on an (R, Z) grid of the section
traced both ways to the wall, L_c coloured on the section (a PNG and a CSV).
The field is a library problem (``--problem``: tokamak — in (u, φ, Z) —, coil_tokamak,
coil_stellarator), a MAKEGRID coils file (``--coils``) or an mgrid netCDF file (``--mgrid``).
"""

from __future__ import annotations

import functools
import math
import time
from types import SimpleNamespace

import numpy as np

from .. import plots
from .._errors import RESULTS
from .._phases import LIBRARY_DELAY, Phases
from ..coils import device_axis, device_names, read_makegrid
from ..fieldlines import (
    Wall,
    connection_length,
    cylindrical,
    is_toroidal,
    island_chain,
    magnetic_axis,
    return_map,
    rotational_transform,
    start_grid,
    toroidal_section,
    trace_to_wall,
)
from ..fieldlines._domain import StartPointError
from ..fieldlines._native_map import _steps_per_period
from ..fieldlines._fixedpoints import _check_section_points
from ._common import (
    CLIError,
    _add_method_args,
    CSV_SUFFIXES,
    FIGURE_SUFFIXES,
    _check_out,
    _written,
    _finite_list,
    _method_from_args,
    _parse_params,
    _positive_float,
    _positive_int,
    _summary_table,
    refuse_unless,
)


def _wall_arg(text: str):
    """``--wall``: "default" (the problem's own wall), "divertor" (a device's divertor-like model
    wall) or the polygon's numbers."""
    key = text.strip().lower()
    return key if key in ("default", "divertor") else _finite_list(text)


def _read_input(read, path: str, option: str):
    """``read(path)``; a missing, unreadable or malformed file is a usage error naming it."""
    try:
        return read(path)
    except OSError as exc:
        raise CLIError(f"{option} {path!r}: cannot read the file ({exc.strerror or exc})") from None
    except ValueError as exc:  # CoilFileError, GridFileError: they name the file and the line
        raise CLIError(str(exc)) from None


#: points per segment at which a coil wire is tested against the grid's box (and the vertices)
_WIRE_SAMPLES = 32


def _refuse_wires_in_grid(coils, path: str, R: tuple, Z: tuple) -> None:
    """CLIError naming the first coil whose wire passes through the (R, Z) box of the spline grid
    (any φ: the grid covers the torus by periodicity): the coils' A and B are singular on the wire,
    so the spline is non-finite at a node on it and wrong near it. Each segment is sampled at
    ``_WIRE_SAMPLES`` points besides its ends."""
    if len(R) != 2 or len(Z) != 2 or not (0 < R[0] < R[1]) or not Z[0] < Z[1]:
        raise CLIError(f"--R and --Z take RMIN,RMAX and ZMIN,ZMAX with 0 < RMIN < RMAX, ZMIN < ZMAX; "
                       f"got --R {','.join(map(str, R))} --Z {','.join(map(str, Z))}")
    s = np.linspace(0.0, 1.0, _WIRE_SAMPLES, endpoint=False)[:, None, None]
    for n, coil in enumerate(coils):
        a, b = coil.segments()
        p = (a[None] + s * (b - a)[None]).transpose(1, 0, 2).reshape(-1, 3)  # segment by segment
        r = np.hypot(p[:, 0], p[:, 1])
        inside = np.flatnonzero((r >= R[0]) & (r <= R[1]) & (p[:, 2] >= Z[0]) & (p[:, 2] <= Z[1]))
        if inside.size:
            q = p[inside[0]]
            name = f" {coil.name!r}" if coil.name else ""
            raise CLIError(
                f"{path}: coil {n}{name} (group {coil.group}) passes through the spline grid R ∈ [{R[0]:g}, "
                f"{R[1]:g}], Z ∈ [{Z[0]:g}, {Z[1]:g}] at R = {r[inside[0]]:.6g}, φ = {math.atan2(q[1], q[0]):.6g}, "
                f"Z = {q[2]:.6g}: its field is singular on the wire; choose --R/--Z clear of the coils")


def _field_source(args):
    """(field, nfp, axis guess, default start radii span, name, default wall or None) of the chosen source."""
    from .. import problems
    from ..problems.coil_fields import spline_coil_field

    if sum(bool(v) for v in (args.coils, args.mgrid, args.device)) > 1:
        raise CLIError("give one of --coils, --mgrid and --device, not two")
    guess = tuple(args.axis_guess) if args.axis_guess else None
    if args.device:
        return _device_source(args, guess)
    if args.coils or args.mgrid:
        if args.coils:
            if not (args.R and args.Z):
                raise CLIError("--coils needs the grid box: --R RMIN,RMAX --Z ZMIN,ZMAX")
            coils = _read_input(read_makegrid, args.coils, "--coils")
            _refuse_wires_in_grid(coils, args.coils, tuple(args.R), tuple(args.Z))
            grid = args.grid or COILS_GRID
            field, err = spline_coil_field(coils, tuple(args.R), tuple(args.Z), n_R=grid[0], n_phi=grid[1],
                                           n_Z=grid[2], name=args.coils)
            name = f"{args.coils} (spline error {err:.2e})"
        else:
            from ..grids import gridded_field

            field = _read_input(gridded_field, args.mgrid, "--mgrid")  # GridFileError: B ≠ ∇×A too
            name = args.mgrid
        nfp = field_nfp(field)
        if guess is None:
            raise CLIError("--coils/--mgrid need --axis-guess R,Z (a point near the magnetic axis on φ = 0)")
        return field, nfp, guess, None, name, None
    params = _parse_params(args.param)
    key = args.problem.lower().replace("-", "_")
    if key == "tokamak":
        params.setdefault("coordinates", "toroidal")
    try:
        prob = problems.get(key, **params)
    except (KeyError, TypeError, ValueError) as exc:
        raise CLIError(f"problem {args.problem!r}: {exc}") from None
    if not str(getattr(prob.field, "coordinates", "")).startswith("toroidal") and key != "tokamak":
        raise CLIError(f"problem {args.problem!r} is not a toroidal field (use tokamak, coil_tokamak or coil_stellarator)")
    nfp = field_nfp(prob.field)
    guess = guess or prob.axis_guess
    if guess is None:
        raise CLIError(f"problem {args.problem!r} has no axis guess: give --axis-guess R,Z")
    R = np.asarray(cylindrical(prob.x0, True)[0]) if prob.field.coordinates.startswith("toroidal") else \
        np.hypot(prob.x0[:, 0], prob.x0[:, 1])
    return prob.field, nfp, guess, (float(R.min() - guess[0]), float(R.max() - guess[0])), prob.name, prob.wall


#: the default spline grid of --coils (n_R, n_φ, n_Z)
COILS_GRID = (40, 32, 40)


def _device_source(args, guess):
    """--device: the device's coils by their quadrature (simsopt's field) splined on a grid that
    follows its default domain (:func:`vpforms.problems.devices.grid_field`); the domain is the
    default wall (the grid exists only there), the axis guess the device's axis at φ₀, the start
    points span 10–90 % of the distance to the last closed surface (measured on φ = 0)."""
    from ..problems import devices

    key = args.device.strip().lower().replace("-", "").replace("_", "")
    if key not in device_names():
        raise CLIError(f"--device {args.device!r}: known devices are {', '.join(device_names())}")
    grid = tuple(args.grid or devices.GRID)
    field, err = devices.grid_field(key, grid)
    R0, Z0 = (float(v) for v in device_axis(key)(args.phi))
    edge = devices.EDGE[key]
    name = f"{key}, {'x'.join(map(str, grid))} grid (spline error {err:.1e} on the domain)"
    return field, field_nfp(field), guess or (R0, Z0), (0.1 * edge, 0.9 * edge), name, field.domain


#: the options that decide the field and the method of ``vpforms fieldlines``
_METHOD_OPTIONS = ("problem", "param", "coils", "mgrid", "device", "R", "Z", "grid", "axis_guess", "phi", "method",
                   "case", "order", "fast", "theta", "no_recover", "composition", "engine")


def build_method(options: dict):
    """The method of ``vpforms fieldlines`` with these ``options`` (:data:`_METHOD_OPTIONS`): the
    field by :func:`_field_source`, the method by ``_method_from_args`` — the command's own code path,
    for a Dask worker or a study to rebuild exactly what the command traces."""
    ns = SimpleNamespace(**{k: options.get(k) for k in _METHOD_OPTIONS})
    return _method_from_args(ns, _field_source(ns)[0])


def method_builder(args) -> functools.partial:
    """A picklable zero-argument builder of the command's method (:func:`build_method` of ``args``'
    field and method options): what :func:`vpforms.fieldlines.connection_length` ships to Dask workers."""
    return functools.partial(build_method, {k: getattr(args, k, None) for k in _METHOD_OPTIONS})


def _divertor_wall(args):
    """--wall divertor: the device's divertor-like model wall (:func:`vpforms.problems.devices.divertor_wall`)."""
    from ..problems import devices

    if not args.device:
        raise CLIError("--wall divertor is a device's model wall: give --device (w7x)")
    key = args.device.strip().lower().replace("-", "").replace("_", "")
    if key not in devices.DIVERTOR_INSET:
        raise CLIError(f"--wall divertor: no divertor-like wall for {key} (known: {', '.join(devices.DIVERTOR_INSET)})")
    return devices.divertor_wall(key)


def field_nfp(field) -> int:
    """The number of field periods of a toroidal field (2π / its φ period)."""
    return int(round(2 * math.pi / (field.periods[1] or 2 * math.pi)))


def _cmd_fieldlines(args, console) -> int:
    """The study; a start point that no answer fits (outside the field's box, R ≤ 0, on the axis:
    :mod:`vpforms.fieldlines._domain`) is a usage error, one line before any tracing."""
    try:
        return _study(args, console)
    except StartPointError as exc:
        raise CLIError(str(exc)) from None


def _study(args, console) -> int:
    """The study in phases (:mod:`vpforms._phases`): each says on stderr what it does and how long
    it took (``--quiet`` or ``VPFORMS_QUIET=1``: silent), and the summary's timing table lists every
    phase — nested ones, such as a spline grid's sampling or a native kernel's compilation, under
    theirs — with the time outside them and the total."""
    outs = [("png", FIGURE_SUFFIXES), ("iota_png", FIGURE_SUFFIXES), ("csv", CSV_SUFFIXES)]
    if args.connection_length:
        outs += [("lc_png", FIGURE_SUFFIXES), ("lc_csv", CSV_SUFFIXES)]
    existing = _check_out(args, *outs)
    refuse_unless(args, ("lc_depth", "lc_transits", "lc_png", "lc_csv", "lc_workers"), bool(args.connection_length),
                  "without --connection-length N")
    refuse_unless(args, ("R", "Z"), bool(args.coils), "without --coils (the spline grid of a coils file)")
    refuse_unless(args, ("grid",), bool(args.coils or args.device), "without --coils or --device (a spline grid)")
    refuse_unless(args, ("problem", "param"), not (args.coils or args.mgrid or args.device),
                  "with --coils/--mgrid/--device (the field is the file's or the device's)")
    refuse_unless(args, ("lines",), not args.radii, "with --radii (it gives the start points)")
    refuse_unless(args, ("island_range", "island_scan"), bool(args.islands), "without --islands M")
    with Phases(quiet=True if getattr(args, "quiet", False) else None) as log:
        # the field: its long parts (a coil set sampled and splined) are phases of their own; an
        # mgrid file is read, splined and checked in one, announced once it has run 2 s (a file
        # refused at once is one error line)
        with log.phase(f"reading {args.mgrid}" if args.mgrid else "reading the field", announce=bool(args.mgrid),
                       delay=LIBRARY_DELAY):
            field, nfp, guess, span, name, default_wall = _field_source(args)
        wall = None
        if args.wall == "divertor":
            wall = _divertor_wall(args)
        elif args.wall == "default":
            if default_wall is None:
                raise CLIError(f"--wall default: {name} has no default wall; give the polygon R1,Z1,R2,Z2,…")
            wall = default_wall
        elif args.wall:
            v = np.asarray(args.wall, float)
            if v.size % 2 or v.size < 8:
                raise CLIError("--wall takes R1,Z1,R2,Z2,… (a closed polygon: the last vertex repeats the first)")
            wall = Wall(v[0::2], v[1::2])
        elif args.device:
            wall = default_wall  # the device's domain: its grid exists only there
        if args.connection_length and wall is None:
            raise CLIError("--connection-length needs a wall: --wall default, divertor or R1,Z1,…")
        # a guess outside the field's box is a usage error before anything is built
        _check_section_points(SimpleNamespace(field=field), args.phi, [guess], "the axis guess")
        analytic = args.problem.lower().replace("-", "_") == "tokamak" and not (
            args.coils or args.mgrid or getattr(args, "device", None))
        units = "" if analytic else "m"  # the analytic tokamak's lengths are those of its R0: no unit
        order = f", order {args.order}" if args.order != 1 else ""
        with log.phase(f"building the method ({args.method}{order})"):
            method = _method_from_args(args, field)
        with log.phase("searching for the magnetic axis (Newton on the return map)"):
            P = return_map(method, args.h, args.phi, nfp, guess=guess)
            # bounded (map evaluations, never seconds); on failure the study goes on from the best point
            axis = magnetic_axis(method, guess, args.h, args.phi, nfp, return_map_=P, on_failure="guess")
        if not axis.converged:
            console.print(f"[bold yellow]warning:[/] {axis.note}", soft_wrap=True)
        # start points on the line Z = Z_axis of the section, outboard of the axis
        if args.radii:
            dr = np.asarray(args.radii, float)
        else:
            lo, hi = span if span is not None else (0.02, 0.2)
            dr = np.linspace(max(lo, 1e-3), hi, args.lines)
        Rs = axis.R + dr
        x0 = np.asarray(np.stack([P.state(np.array([r, axis.Z])) for r in Rs]), float)
        with log.phase(f"tracing the section ({len(x0)} lines, {args.transits:g} transits)"):
            # steps per transit from B^φ at the first start (one field evaluation, no step compiled)
            steps = max(2, int(math.ceil(args.transits * nfp * _steps_per_period(P, x0[0]))))
            sec = toroidal_section(method, x0, args.h, steps, phi=args.phi, nfp=nfp, progress="auto")
        with log.phase(f"computing ι of the lines (weighted Birkhoff averages, {len(x0)} lines)"):
            iota = rotational_transform(method, x0, args.h, steps, axis, progress="auto")
        chains = []
        if args.islands:
            lo, hi = (args.island_range if args.island_range else (Rs.min(), Rs.max()))
            with log.phase(f"searching for m = {args.islands} island chains ({args.island_scan} scan points)"):
                chains = island_chain(method, args.islands, args.h, np.linspace(lo, hi, args.island_scan), axis.Z,
                                      args.phi, nfp, axis=axis)  # O- and X-points, off the scanned line too
        hits = None
        if wall is not None:
            with log.phase(f"tracing the lines to the wall ({len(x0)} lines)"):
                hits = trace_to_wall(method, x0, args.h, steps, wall, progress="auto")
            sec = sec.before(hits.t_exit)  # a line ends where it meets the wall
        lc = None
        if args.connection_length:
            lc, lc_grid, lc_steps = _connection_map(args, log, method, P, wall, nfp)
        with log.phase("writing the CSV and the figures"):
            sec.to_csv(args.csv)
            what = f"{sec.section.method}, h = {args.h:g}, {args.transits:g} transits"
            R_label = f"starting R ({units})" if units else "starting R"
            plots.fieldline_figure(sec, axis, chains, wall.wall_at(sec.phi0) if hasattr(wall, "wall_at") else wall,
                                   title=f"{name}: {what}", path=args.png, units=units,
                                   color_by=Rs, color_label=R_label)
            plots.iota_figure(iota, title=f"{name}: rotational transform and safety factor; {what}",
                              path=args.iota_png, units=units, axis=axis if axis.converged else None)
            if lc is not None:
                lc.to_csv(args.lc_csv)
                plots.connection_length_figure(
                    lc, lc_grid, wall.wall_at(args.phi) if hasattr(wall, "wall_at") else wall, section=sec,
                    title=f"{name}: connection length to the wall, {len(lc.L)} lines from {plots._angle_text(args.phi, nfp)} "
                          f"traced both ways ({sec.section.method}, h = {args.h:g}, ≤ {lc_steps} steps "
                          f"≈ {args.lc_transits:g} transits each way)", path=args.lc_png, units=units)
    rows = {
        "field": name,
        "method": sec.section.method,
        "section": f"φ = {sec.phi0:.6g} (mod 2π/{nfp})",
        "lines × steps": f"{len(x0)} × {steps} (h = {args.h:g}, ≈ {args.transits:g} transits)",
        "magnetic axis (R, Z)": f"({axis.R:.10g}, {axis.Z:.3g}), residual {axis.residual:.1e}, {axis.kind}"
                                + ("" if axis.converged else " — NOT CONVERGED: the study went on from this point"),
        "ι on the axis (tangent map)": f"{axis.iota:.10g} (q = {axis.q:.10g})",
        "ι of the lines": f"{np.nanmin(iota.iota):.6g} … {np.nanmax(iota.iota):.6g} "
                          f"(max Birkhoff error estimate {np.nanmax(iota.error):.1e})",
        "crossings": len(sec),
        "failed lines": int(np.count_nonzero((sec.status != 0) & (sec.status != RESULTS.left_domain))),
    }
    left = int(np.count_nonzero(sec.status == RESULTS.left_domain))
    if left:  # a stop at the field's edge (a grid's box, a domain), never retried: not a failure
        rows["lines that left the field's domain"] = f"{left} of {len(x0)} (stopped at its edge; no ι)"
    for fp in chains:
        rows[f"{fp.kind}-point, m = {fp.m}"] = f"({fp.R:.8g}, {fp.Z:.3g}), residue {fp.residue:.4g}"
    if hits is not None:
        rows["lines that hit the wall"] = f"{int(hits.hit.sum())} of {len(x0)}" + (
            f", median connection length {np.median(hits.connection_length[hits.hit]):.4g}" if hits.hit.any() else "")
    if lc is not None:
        r = lc.reached
        rows["connection lengths"] = (
            f"{len(lc.L)} lines × 2 ways, ≤ {lc_steps} steps each ({lc.where}): {int(r.sum())} reached the wall"
            + (f", L_c median {np.median(lc.L[r]):.4g}, {lc.L[r].min():.3g} … {lc.L[r].max():.3g}" if r.any() else "")
            + (f"; {int(lc.unreached.sum())} not within the steps (L_c > {lc.traced[lc.unreached].min():.3g})"
               if lc.unreached.any() else "")
            + (f"; {int((~r & ~lc.unreached).sum())} failed" if (~r & ~lc.unreached).any() else ""))
    console.print(_summary_table("vpforms fieldlines", rows))
    console.print(log.table())
    console.print(f"section: {_written(args.png, existing)}\nι profile: {_written(args.iota_png, existing)}\n"
                  f"section points CSV: {_written(args.csv, existing)}", soft_wrap=True)
    if lc is not None:
        console.print(f"connection-length map: {_written(args.lc_png, existing)}\n"
                      f"connection lengths CSV: {_written(args.lc_csv, existing)}", soft_wrap=True)
    return 0


def _connection_map(args, log, method, P, wall, nfp):
    """--connection-length N: N lines on an (R, Z) grid of φ₀ inside the wall (within --lc-depth of
    it), traced both ways for at most --lc-transits transits (steps from B^φ at the first line), in
    this process or on --lc-workers Dask workers (each rebuilds the method: :func:`method_builder`).
    Returns (the ConnectionLengths, the grid, the steps per direction)."""
    try:
        grid = start_grid(wall, args.connection_length, phi0=args.phi, depth=args.lc_depth,
                          toroidal=is_toroidal(method.field))
    except ValueError as exc:  # no point in the band
        raise CLIError(f"--connection-length: {exc}") from None
    steps = max(2, int(math.ceil(args.lc_transits * nfp * _steps_per_period(P, grid.x0[0]))))
    where = f"{args.lc_workers} Dask workers" if args.lc_workers else "this process"
    with log.phase(f"connection lengths ({len(grid.x0)} lines both ways, ≤ {args.lc_transits:g} transits, {where})"):
        lc = connection_length(method, grid.x0, args.h, steps, wall, client=args.lc_workers or None,
                               builder=method_builder(args) if args.lc_workers else None, progress="auto")
    return lc, grid, steps


def register(sub) -> None:
    """Add the ``fieldlines`` subcommand."""
    p = sub.add_parser("fieldlines", help="field-line study of a toroidal field: section, axis, ι, islands, wall",
                       description="Poincaré section at φ = const in (R, Z), magnetic axis and its ι (tangent "
                                   "map of the return map), ι/q profile of the lines (weighted Birkhoff "
                                   "averages), optional island chains and wall; PNGs and a CSV. Each phase (grid, method, "
                                   "kernel compile, axis, section, ι, islands, wall, figures) says on stderr what "
                                   "it does and how long it took; the summary ends with a table of their times.")
    p.add_argument("--problem", default="tokamak",
                   help="tokamak (in u = R²/2, φ, Z), coil_tokamak or coil_stellarator; default tokamak")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", help="problem parameter, e.g. --param eps=0")
    p.add_argument("--coils", default=None, metavar="FILE", help="a MAKEGRID coils file (with --R, --Z, --axis-guess)")
    p.add_argument("--mgrid", default=None, metavar="FILE", help="an mgrid netCDF file (with --axis-guess)")
    p.add_argument("--device", default=None, metavar="NAME",
                   help="a stellarator by name: w7x, ncsx or hsx (its coils as simsopt integrates them, splined on a "
                        "grid that follows its default domain, which is also the wall)")
    p.add_argument("--R", type=_finite_list, default=None, help="R range of the coils' spline grid: RMIN,RMAX")
    p.add_argument("--Z", type=_finite_list, default=None, help="Z range of the coils' spline grid: ZMIN,ZMAX")
    p.add_argument("--grid", type=lambda s: tuple(int(v) for v in s.split("x")), default=None,
                   help="spline grid of --coils or --device: NRxNPHIxNZ (default 40x32x40 for --coils, 48x96x48 "
                        "for --device)")
    _add_method_args(p, default_order=2)
    p.add_argument("--h", type=_positive_float, default=0.05, help="step size (default 0.05)")
    p.add_argument("--transits", type=_positive_float, default=100.0, help="toroidal transits (default 100)")
    p.add_argument("--lines", type=_positive_int, default=12, help="field lines (default 12)")
    p.add_argument("--radii", type=_finite_list, default=None, help="start offsets R − R_axis (default: a spread)")
    p.add_argument("--phi", type=float, default=0.0, help="section angle φ₀ (default 0)")
    p.add_argument("--axis-guess", type=_finite_list, default=None, help="R,Z near the axis on φ₀")
    p.add_argument("--islands", type=_positive_int, default=None, metavar="M", help="find the m-island chains")
    p.add_argument("--island-range", type=_finite_list, default=None, help="RMIN,RMAX of the island scan")
    p.add_argument("--island-scan", type=_positive_int, default=33, help="scan points (default 33)")
    p.add_argument("--wall", type=_wall_arg, default=None,
                   help="closed (R, Z) polygon R1,Z1,…,R1,Z1, 'default': the problem's own wall, or 'divertor': "
                        "a device's divertor-like model wall (W7-X: its domain 0.24 m inward, through the 5/5 "
                        "islands)")
    p.add_argument("--connection-length", type=_positive_int, default=None, metavar="N",
                   help="a connection-length map: about N lines on a square (R, Z) grid of the section inside the "
                        "wall (within --lc-depth of it) traced both ways to the wall; L_c = L_fwd + L_bwd on a log "
                        "colour scale (--lc-png), every line's lengths and exits (--lc-csv)")
    p.add_argument("--lc-depth", type=_positive_float, default=None, metavar="D",
                   help="start the --connection-length lines only within D of the wall (the edge; default: all of "
                        "its inside)")
    p.add_argument("--lc-transits", type=_positive_float, default=20.0, metavar="T",
                   help="at most ≈ T toroidal transits each way (default 20): a line that does not reach the wall "
                        "by then has only a lower bound on L_c, shown apart")
    p.add_argument("--lc-workers", type=_positive_int, default=None, metavar="K",
                   help="trace the --connection-length lines on K local Dask worker processes (each rebuilds the "
                        "field and the method)")
    p.add_argument("--lc-png", default="vpforms-connection-length.png",
                   help="connection-length map: .png, .pdf or .svg (default vpforms-connection-length.png)")
    p.add_argument("--lc-csv", default="vpforms-connection-length.csv",
                   help="connection lengths, one row per line (ConnectionLengths.to_csv): .csv "
                        "(default vpforms-connection-length.csv)")
    p.add_argument("--png", default="vpforms-fieldlines.png",
                   help="section figure: .png, .pdf or .svg (default vpforms-fieldlines.png; an existing file "
                        "is replaced, and the summary says so)")
    p.add_argument("--iota-png", default="vpforms-iota.png",
                   help="ι and q profile figure: .png, .pdf or .svg (default vpforms-iota.png; replaced likewise)")
    p.add_argument("--csv", default="vpforms-fieldlines.csv",
                   help="section points line,transit,phi,t,R,Z, phi modulo the field period: .csv "
                        "(default vpforms-fieldlines.csv; replaced likewise)")
    p.add_argument("--quiet", action="store_true",
                   help="no phase lines on stderr (also VPFORMS_QUIET=1); the timing table is printed all the same")
    p.set_defaults(func=_cmd_fieldlines)

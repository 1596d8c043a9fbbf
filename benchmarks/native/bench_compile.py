"""Compile time and step speed of the native spline kernels (issue #41 item 3), written to results_compile.md.

A cold cache (a temporary ``VPFORMS_NATIVE_CACHE`` per compilation). The kernels ``vpforms
fieldlines`` builds on a spline of A, for SE+SE composed to order 2 (the CLI's default) and 4,
generated once and compiled by :func:`vpforms.backends.native.build.build` in each variant:

* **before issue #41**: one object per entry — ``vp_run`` (ι, plain traces) and ``vp_sections``
  (axis, sections; ``vp_wall`` too with ``--wall``, not counted here) — every stage
  ``always_inline`` d into the step and the step into each entry's lane loops, the flags ``FLAGS``
  less ``-g0`` (Python's own ``-g`` on): regenerated with ``entries.ONE_OBJECT = False`` and the
  stages' ``_VP_STAGE`` defined inline, i.e. the code generation of before;
* the same inlined ``vp_run`` at ``-O2`` and ``-O1``;
* **now**: one object with every entry (``vp_run``, ``vp_sections``/``vp_locate``, ``vp_wall``),
  each stage compiled once and called (``_VP_STAGE`` = ``noinline``), ``FLAGS`` (``-O3
  -march=native … -g0``); and that object at ``-O2``, ``-O2`` without ``-march=native``, ``-O1``.

For each: the C size, the compiler's wall time and CPU time (the children's rusage, user +
system: the machine's load inflates it far less than the wall time), the ``.so`` size, and the
step speed of ``vp_run`` on the same 12 field lines for the same steps (µs per line-step, best of
``--rounds`` interleaved rounds; |Δx|: each variant's end points against the current code's).
The field is the l = 2 stellarator's coils splined by
:func:`vpforms.problems.coil_fields.spline_coil_field` (``problems.get("coil_stellarator")``,
40×32×40). The C of a spline kernel depends only on the spline's structure (knots and
coefficients are run-time data), so ``vpforms fieldlines --coils <its MAKEGRID file>`` on the docs'
box compiles the same sources — checked by their hashes (not in smoke mode). So does the W7-X
grid of ``--device w7x`` (session 38's 898 s order-4 kernel): checked outside this script, whose
run would double with that grid's build.

    PYTHONPATH=src python benchmarks/native/bench_compile.py [--smoke] [--orders 2,4] [--inline-orders 2,4]
"""

from __future__ import annotations

import hashlib
import os
import resource
import sys
import tempfile
import time
from contextlib import contextmanager

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import interleaved, machine, native_missing, parser, write_results

import vpforms
from vpforms import problems
from vpforms.backends.native import build as native_build
from vpforms.backends.native.codegen import entries, kernel_parts
from vpforms.backends.native.codegen.entries import entries_cdef

#: the line the generator writes for kernels without a vectorised pass, and its inlined form (before #41)
CALLED = "#define _VP_STAGE __attribute__((noinline))"
INLINED = "#define _VP_STAGE inline _VP_INLINE"


def _flags(opt: str | None = None, native: bool = True, g0: bool = True) -> tuple[str, ...]:
    """``build.FLAGS`` with -O3 replaced by ``opt``, without -march=native, without -g0."""
    out = []
    for f in native_build.FLAGS:
        if f == "-O3" and opt:
            f = opt
        if (f == "-march=native" and not native) or (f == "-g0" and not g0):
            continue
        out.append(f)
    return tuple(out)


NOW = "**now: called, -O3 -march=native -g0 (FLAGS)**"
#: the variants of the one object with every entry: (label, flags)
CALLED_VARIANTS = [
    (NOW, _flags()),
    ("called, -O2 -march=native -g0", _flags("-O2")),
    ("called, -O2 -g0 (no -march=native)", _flags("-O2", native=False)),
    ("called, -O1 -march=native -g0", _flags("-O1")),
]
BEFORE = "before #41: inlined, -O3 -march=native -g"
#: the variants of the inlined per-entry objects: (label, flags, entries compiled)
INLINED_VARIANTS = [
    (BEFORE, _flags(g0=False), ("run", "sections")),
    ("inlined, -O2 -march=native -g", _flags("-O2", g0=False), ("run",)),
    ("inlined, -O1 -march=native -g", _flags("-O1", g0=False), ("run",)),
]


#: the run's compiled objects, each in a cache of its own (removed at exit; loaded objects stay mapped)
_TMP = tempfile.TemporaryDirectory(prefix="vpforms-bench-compile-")


@contextmanager
def _patched(module, name, value):
    saved = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, saved)


def compile_variant(source: str, flags, inline: bool = False) -> dict:
    """Compile ``source`` (its stages inlined where ``inline``) with ``flags`` into a fresh cache:
    the lib, wall and CPU seconds, sizes."""
    if CALLED not in source:
        raise RuntimeError("the generated kernel does not call its stages: not a kernel without a vectorised pass")
    if inline:
        source = source.replace(CALLED, INLINED)
    cache = tempfile.mkdtemp(prefix="compile-", dir=_TMP.name)
    saved = os.environ.get("VPFORMS_NATIVE_CACHE")
    os.environ["VPFORMS_NATIVE_CACHE"] = cache
    try:
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        # an empty in-process table too: a kernel this process already loaded (another test, an
        # earlier variant) would be returned without a compile, and without a file in the new cache
        with _patched(native_build, "FLAGS", flags), _patched(native_build, "_loaded", {}):
            lib = native_build.build(source, entries_cdef(source))
        wall = time.perf_counter() - t
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    finally:
        if saved is None:
            os.environ.pop("VPFORMS_NATIVE_CACHE", None)
        else:
            os.environ["VPFORMS_NATIVE_CACHE"] = saved
    so = [f for f in os.listdir(cache) if f.endswith((".so", ".pyd"))]
    return dict(lib=lib, wall=wall, cpu=(r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime),
                so_kb=os.path.getsize(os.path.join(cache, so[0])) / 1024, c_kb=len(source.encode()) / 1024)


def stepper(lib, fd, x0: np.ndarray, h: float, n: int):
    """A call of ``vp_run`` for n steps of every line from x0 (fresh state each call): (x, status)."""
    from cffi import FFI

    ffi = FFI()
    fdp = ffi.cast("double *", fd.ctypes.data)

    def go():
        x = np.array(x0, dtype=np.float64, order="C", copy=True)
        st = np.zeros(len(x), np.int32)
        nn = np.zeros(len(x), np.int64)
        lib.lib.vp_run(len(x), ffi.cast("double *", x.ctypes.data), ffi.cast("int32_t *", st.ctypes.data),
                       ffi.cast("int64_t *", nn.ctypes.data), n, h, 0, 0, ffi.NULL, 0, fdp)
        return x, st

    return go


def coils_sources(orders) -> dict:
    """The sources of the same kernels for ``vpforms fieldlines --coils``: the l = 2 coils written as
    a MAKEGRID file, read back and splined on the docs' box (R 0.8–1.2, Z −0.2–0.2, 40×32×40)."""
    from vpforms.coils import l2_stellarator, read_makegrid, write_makegrid
    from vpforms.problems.coil_fields import spline_coil_field

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "coils.l2")
        write_makegrid(l2_stellarator(), path)
        coils = read_makegrid(path)
    field, _ = spline_coil_field(coils, (0.8, 1.2), (-0.2, 0.2), n_R=40, n_phi=32, n_Z=40, name="coils.l2")
    base = vpforms.scheme(field, "SE+SE", recover=False)
    return {o: kernel_parts(vpforms.compose(base, order=o))[0] for o in orders}


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",") if v.strip()]


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def main(argv=None) -> int:
    ap = parser(__doc__, os.path.join(HERE, "results_compile.md"), rounds=3)
    ap.add_argument("--orders", default="2,4", help="composition orders (default 2,4)")
    ap.add_argument("--inline-orders", default="2,4",
                    help="orders whose inlined (before #41) variants are compiled too (default 2,4; an "
                         "inlined order-4 kernel takes gcc many minutes)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    smoke = args.smoke
    rounds = 1 if smoke else args.rounds
    orders = [2] if smoke else _ints(args.orders)
    inline_orders = [] if smoke else _ints(args.inline_orders)
    called = [v for v in CALLED_VARIANTS if v[0] == NOW or "-O1" in v[0]] if smoke else CALLED_VARIANTS
    grid = dict(n_R=10, n_phi=8, n_Z=10) if smoke else {}
    n, h = (20, 0.05) if smoke else (4000, 0.05)
    prob = problems.get("coil_stellarator", **grid)
    base = vpforms.scheme(prob.field, "SE+SE", recover=False)  # the kernel is the bare method's
    R = float(prob.axis_guess[0]) + np.linspace(0.02, 0.14, 12)  # 12 lines (the CLI's default) on φ = 0, Z = 0
    x0 = np.stack([0.5 * R * R, np.zeros_like(R), np.zeros_like(R)], axis=1)
    loads, rows, sources, totals = [], [], {}, {}

    def compiled(order, what, label, src, flags, inline=False):
        loads.append(os.getloadavg()[0])
        print(f"[bench_compile] order {order}, {what}: {label} …", flush=True)
        r = compile_variant(src, flags, inline)
        print(f"[bench_compile]   {r['wall']:.1f} s wall, {r['cpu']:.1f} s CPU", flush=True)
        return r

    for order in orders:
        m = vpforms.compose(base, order=order)
        src, fd = kernel_parts(m)  # every entry, the stages called
        sources[order] = src
        built = {}  # label → (result, fd): the objects with vp_run, stepped below
        for label, flags in called:
            built[label] = (compiled(order, "every entry", label, src, flags), fd)
            rows.append((order, "every entry", label, built[label][0]))
        totals[order, "now"] = built[NOW][0]
        if order in inline_orders:
            with _patched(entries, "ONE_OBJECT", False):  # one entry per object, as before #41
                per_entry = {e: kernel_parts(m, "auto", e) for e in ("run", "sections")}
            for label, flags, which in INLINED_VARIANTS:
                for e in which:
                    r = compiled(order, f"vp_{e} alone", label, per_entry[e][0], flags, inline=True)
                    rows.append((order, f"`vp_{e}` alone", label, r))
                    if e == "run":
                        built[label] = (r, per_entry[e][1])
                if label == BEFORE:
                    mine = [r for o, w, lab, r in rows if o == order and lab == BEFORE]
                    totals[order, "before"] = {k: sum(r[k] for r in mine) for k in ("wall", "cpu")}
        fns = {lab: stepper(r["lib"], f, x0, h, n) for lab, (r, f) in built.items()}
        times, outs = interleaved(fns, rounds)
        ref = outs[NOW][0]
        for lab, (x, st) in outs.items():
            if np.any(st != 0):
                raise RuntimeError(f"order {order}, {lab}: {int(np.sum(st != 0))} lines failed; statuses {st}")
            built[lab][0]["step"] = times[lab] * 1e6 / (len(x0) * n)
            built[lab][0]["dx"] = float(np.max(np.abs(x - ref)))
    same = None
    if not smoke:
        other = coils_sources(orders)
        same = all(_sha(other[o]) == _sha(sources[o]) for o in orders)
    lines = ["# Native spline kernels: compile time and step speed (issue #41 item 3)", "",
             (f"Cold cache for every compilation. Field: the l = 2 stellarator's coils, A splined "
              f"({prob.params['grid']} nodes, degree 3), in (u = R²/2, φ, Z). Method: SE+SE (bare) "
              f"composed to each order. Step speed: `vp_run`, 12 lines from R = R_axis + 0.02 … 0.14 m "
              f"on φ = 0, Z = 0, {n} steps of h = {h}, best of {rounds} interleaved rounds; µs per "
              "line-step; |Δx|: max difference of the end points from the current code's (same "
              "lines, same steps). Compile: `build.build` (cffi + gcc), wall seconds and the compiler's "
              "CPU seconds (user + system of the child processes). *Before #41*: one object per entry, "
              "stages inlined (`vp_sections` is compiled for its time only: its step is `vp_run`'s)."), ""]
    if same is not None:
        lines += [("Check: `vpforms fieldlines --coils` (the l = 2 coils written as MAKEGRID, read back, "
                   "splined on R 0.8–1.2, Z −0.2–0.2, 40×32×40) generates the same C as "
                   f"`--problem coil_stellarator` at every order here: **{'yes' if same else 'NO'}** "
                   "(sha256 of the sources)."), ""]
    lines += ["| order | object | stages, flags | C (KB) | compile wall (s) | compile CPU (s) | .so (KB) | "
              "µs / line-step | × now | \\|Δx\\| |",
              "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for order, what, lab, r in rows:
        now = next(rr for o, w, lb, rr in rows if o == order and lb == NOW)
        step = r.get("step")
        speed = ("", "", "") if step is None else (f"{step:.2f}", f"{step / now['step']:.2f}", f"{r['dx']:.1e}")
        lines.append(f"| {order} | {what} | {lab} | {r['c_kb']:.0f} | {r['wall']:.1f} | {r['cpu']:.1f} | "
                     f"{r['so_kb']:.0f} | {' | '.join(speed)} |")
    lines.append("")
    for order in orders:
        if (order, "before") in totals:
            b, a = totals[order, "before"], totals[order, "now"]
            run = next(r for o, w, lb, r in rows if o == order and lb == BEFORE and "run" in w)
            lines.append(f"Order {order}, the CLI's kernels (`vp_run` + `vp_sections`): before #41 "
                         f"{b['cpu']:.1f} s CPU ({b['wall']:.1f} s wall) → now {a['cpu']:.1f} s CPU "
                         f"({a['wall']:.1f} s wall), {b['cpu'] / a['cpu']:.1f}× less compiler time; "
                         f"time per line-step now ÷ before = {a['step'] / run['step']:.2f}.")
    lines += ["", (f"Load average (1 min) at each compilation's start: {min(loads):.1f} … {max(loads):.1f}; "
                   f"at the end: {os.getloadavg()[0]:.1f}."), "",
              machine("bench_compile.py" + ("" if smoke else f" --orders {args.orders} --inline-orders "
                                            f"{args.inline_orders}"), time.perf_counter() - t0, smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

"""The cost floor of a spline step: what reading the spline costs, without solving anything
(issue #20, the ratio targets), written to results_spline_floor.md.

A step of SE+SE on a spline of A evaluates the spline at three points: the guard's field B(x)
needs every component of A at x, and each implicit solve evaluates its potentials at its own
point. Whatever the code, each (spline, point) pair reads the (k₀+1)(k₁+1)(k₂+1) coefficients of
its cell (64 for a tricubic spline) and contracts them with the three bases. This script times
exactly that and nothing else, in C compiled with the backend's flags, on the same data the
native kernel gets (``fd``, the header layout of :mod:`vpforms.backends.native.codegen.splines`):

* the pairs are read off the generated kernel: the splines read at x for a(x) (the guard's B(x),
  which the first stage evaluates), and the splines each Newton loop reads (``vp_lines``, the
  blocks of its hoisted lines, contracted on entering a cell);
* the points are the field lines' own: x, and for the solves the state after one native step
  (within one step of the solves' points: the same cells, the same cache behaviour);
* per pair: the cell on each axis (the uniform guess, clipped), the three bases (Horner on the
  cell polynomials) and the contraction; nothing is shared between pairs;
* a second floor reads another representation of the same spline: per cell, the coefficients of
  its polynomial in the local y (64 contiguous doubles for a tricubic cell, where the B-spline has
  about one coefficient per cell: ~50× the memory), evaluated by a 3-D Horner — no bases. Both floors compute the sum of
  the splines' values at the points; they agree to rounding (checked), so the tables are the
  spline.

Rows (one process, 2 OpenMP threads, ns per particle-step): the closed-form tokamak step (native),
the spline step (native), and the two floors. A floor ÷ closed form is the least ratio a step
that reads the spline that way at those points could reach, before solving anything.

    PYTHONPATH=src python benchmarks/native/bench_spline_floor.py [--smoke]
"""

from __future__ import annotations

import os
import re
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]  # this topic's scripts; benchmarks/_bench.py
from _bench import best_of, machine, native_missing, parser, per_step, write_results
from bench_native_splines import tokamak_spline

import vpforms
from vpforms import problems
from vpforms.backends.native.build import build
from vpforms.backends.native.codegen import kernel_parts
from vpforms.backends.native.codegen.data import HS
from vpforms.toroidal import to_toroidal

FLOOR = "floor: the step's spline reads, nothing else"
FLOOR_MONO = "floor with per-cell monomial tables"
CDEF = ("void vp_floor(int64_t N, const double *x, const double *X, const double *fd, const double *md, "
        "int64_t n, double *out);")


def pairs(source: str) -> tuple[set[int], list[set[int]]]:
    """(the header offsets read at x for the guard's a(x), per Newton loop the offsets it reads)
    of a generated spline kernel: a(x) is evaluated by the step before its first stage, or by the
    first stage before its first loop (which then hands it to the guard)."""
    step = source[source.index("int vp_step_exact("):]
    stage = source[source.index("int vp_exact0("):]
    at_x = step[:step.index("vp_exact0(")]
    if "vp_c0" not in at_x:
        at_x = stage[:stage.index("for (int it = 0;")]
    guard = {int(o) for o in re.findall(r"vp_c0\w*\(fd, fd \+ (\d+),", at_x)}
    # a loop's splines: the blocks its cached lines contract (vp_lines, on entering a cell)
    loops = [{int(o) for o in re.findall(r"vp_lines_\w+\(fd, fd \+ (\d+),", body)}
             for body in re.findall(r"for \(int it = 0;.*?if \(n\d+_st == -1\)", source, re.S)]
    return guard, loops


def degrees(fd: np.ndarray, off: int) -> tuple[int, int, int]:
    """The degrees of the spline whose header is at ``off``: its knot vectors are stored one
    after the other (header: knot offsets h[0:3], cell tables from h[3]), m + k + 1 knots each."""
    h = fd[off:off + HS]
    n_knots = [int(h[1] - h[0]), int(h[2] - h[1]), int(h[3] - h[2])]
    return tuple(n - int(m) - 1 for n, m in zip(n_knots, h[7:10]))


def spline_arrays(fd: np.ndarray, off: int, k: tuple[int, int, int]) -> tuple[list, np.ndarray]:
    """(the three cell-polynomial tables P_a[cell, r, p], the coefficients) of the spline whose
    header is at ``off`` (the layout of :mod:`vpforms.backends.native.codegen.splines`)."""
    h = fd[off:off + HS]
    m = [int(v) for v in h[7:10]]
    P = [fd[int(h[3 + a]):int(h[3 + a]) + (m[a] - k[a]) * (k[a] + 1) ** 2].reshape(m[a] - k[a], k[a] + 1, k[a] + 1)
         for a in range(3)]
    return P, fd[int(h[6]):int(h[6]) + m[0] * m[1] * m[2]].reshape(m)


def monomials(fd: np.ndarray, off: int, k: tuple[int, int, int]) -> np.ndarray:
    """Per cell, the (k₀+1)(k₁+1)(k₂+1) coefficients of the spline's polynomial in the cell's
    local y (y^p y^q y^r): the block contracted with the three cells' polynomial tables."""
    P, c = spline_arrays(fd, off, k)
    blocks = np.lib.stride_tricks.sliding_window_view(c, tuple(kk + 1 for kk in k))
    return np.einsum("ijkabc,iap,jbq,kcr->ijkpqr", blocks, *P, optimize=True)


def _cell(p: str, a: int, k: int) -> str:
    """C: the cell i{a} and local y{a} of axis a (the uniform guess, clipped; periodic wrap)."""
    return f"""          {{ const double *t = fd + (int64_t)h[{a}]; int64_t m = (int64_t)h[{7 + a}];
            double T = h[{10 + a}], v = {p}[3 * q + {a}] + eps, lo = t[{k}];
            if (T > 0.0) v = v - T * floor((v - lo) / T);
            double g = (v - lo) * h[{13 + a}], gm = (double)(m - {1 + k});
            g = g < 0.0 ? 0.0 : g < gm ? g : gm;
            i{a} = {k} + (int64_t)g;
            y{a} = v - t[i{a}]; }}"""


def floor_source(blocks: list[tuple[int, int, tuple[int, int, int]]], mono: list | None = None) -> str:
    """C of ``vp_floor``: the loop order of the kernel (blocks of 64 lines, all steps of a block,
    then the next), per line and step each (header offset, point 0 = x | 1 = X, degrees) block
    evaluated in full, its degrees compile-time constants (every loop unrolls): the sum of the
    splines' values. Without ``mono``, as the kernel reads a spline (the bases by Horner on the
    cell polynomials, then the coefficient block); with ``mono`` (per block: the offset of its
    per-cell monomial table in ``md`` and its cell counts), one contiguous table per cell and a
    3-D Horner. Each step's point moves by 1e-300 × the previous step's sum, so that no compiler
    hoists the reads out of the step loop."""
    body = []
    for j, (off, pt, k) in enumerate(blocks):
        p = "x" if pt == 0 else "X"
        head = f"""        {{ const double *h = fd + {off}; int64_t i0, i1, i2; double y0, y1, y2;
{chr(10).join(_cell(p, a, k[a]) for a in range(3))}"""
        if mono is None:
            bases = "".join(f"""
          double N{a}[{k[a] + 1}];
          {{ const double *P = fd + (int64_t)h[{3 + a}] + (i{a} - {k[a]}) * {(k[a] + 1) ** 2};
            for (int r = 0; r <= {k[a]}; r++) {{
              double s = P[r * {k[a] + 1} + {k[a]}];
              for (int c = {k[a] - 1}; c >= 0; c--) s = s * y{a} + P[r * {k[a] + 1} + c];
              N{a}[r] = s;
            }} }}""" for a in range(3))
            body.append(head + bases + f"""
          const double *c = fd + (int64_t)h[6];
          int64_t m1 = (int64_t)h[8], m2 = (int64_t)h[9];
          const double *b = c + ((i0 - {k[0]}) * m1 + (i1 - {k[1]})) * m2 + (i2 - {k[2]});
          double s = 0.0;
          for (int u = 0; u <= {k[0]}; u++)
            for (int w = 0; w <= {k[1]}; w++) {{
              double r = 0.0;
              for (int z = 0; z <= {k[2]}; z++) r += N2[z] * b[(u * m1 + w) * m2 + z];
              s += N0[u] * N1[w] * r;
            }}
          acc += s; }}  /* block {j} */""")
        else:
            mo, (n1, n2) = mono[j]
            size = (k[0] + 1) * (k[1] + 1) * (k[2] + 1)
            body.append(head + f"""
          const double *c = md + {mo} + (((i0 - {k[0]}) * {n1} + (i1 - {k[1]})) * {n2} + (i2 - {k[2]})) * {size};
          double sx = 0.0;
          for (int u = {k[0]}; u >= 0; u--) {{
            double sy = 0.0;
            for (int w = {k[1]}; w >= 0; w--) {{
              const double *r = c + (u * {k[1] + 1} + w) * {k[2] + 1};
              double sz = r[{k[2]}];
              for (int z = {k[2] - 1}; z >= 0; z--) sz = sz * y2 + r[z];
              sy = sy * y1 + sz;
            }}
            sx = sx * y0 + sy;
          }}
          acc += sx; }}  /* block {j} */""")
    return f"""
#include <math.h>
#include <stdint.h>
void vp_floor(int64_t N, const double *x, const double *X, const double *fd, const double *md,
              int64_t n, double *out) {{
    int64_t nb = (N + 63) / 64;
    #pragma omp parallel for schedule(dynamic, 1)
    for (int64_t blk = 0; blk < nb; blk++) {{
        int64_t hi = blk * 64 + 64 < N ? blk * 64 + 64 : N;
        for (int64_t k = 0; k < n; k++)
            for (int64_t q = blk * 64; q < hi; q++) {{
                double acc = 0.0, eps = 1e-300 * out[q];
{chr(10).join(body)}
                out[q] = acc;
            }}
    }}
}}
"""


def main(argv=None) -> int:
    args = parser(__doc__, os.path.join(HERE, "results_spline_floor.md"), rounds=3).parse_args(argv)
    t0 = time.perf_counter()
    if native_missing():
        return 1
    smoke = args.smoke
    rounds = 1 if smoke else args.rounds
    N, n, h = (200, 5, 0.01) if smoke else (20_000, 100, 0.01)
    grid = (12, 8, 12) if smoke else (48, 32, 48)
    tok = problems.get("tokamak")
    x_cart = tok.initial_conditions(N, seed=0)
    x_tor = np.ascontiguousarray(np.asarray(to_toroidal(x_cart)), dtype=np.float64)
    spl = tokamak_spline(*grid)
    m_spl = vpforms.scheme(spl, "SE+SE", recover=False)
    m_tok = vpforms.scheme(tok.field, "SE+SE", recover=False)
    per = {}
    for label, m, x0 in (("tokamak (closed form), native step", m_tok, x_cart),
                         ("tokamak (spline of A), native step", m_spl, x_tor)):
        def go(steps, m=m, x0=x0):
            return vpforms.integrate(m, x0, h, steps, progress=False, backend="native")

        per[label], _, sol = per_step(go, n, N, rounds, strict=not smoke)
        assert sol.stats["backend"] == "native" and np.all(np.asarray(sol.status) == 0)
    source, fd = kernel_parts(m_spl)
    guard, loops = pairs(source)
    assert guard and len(loops) == 2 and all(loops), (guard, loops)
    blocks = [(off, 0, degrees(fd, off)) for off in sorted(guard)]
    blocks += [(off, 1, degrees(fd, off)) for loop in loops for off in sorted(loop)]
    X = np.ascontiguousarray(np.asarray(vpforms.integrate(m_spl, x_tor, h, 1, progress=False,
                                                          backend="native").x_final), dtype=np.float64)
    fdc = np.ascontiguousarray(fd, dtype=np.float64)
    tables, mono, pos = {}, [], 0  # one per-cell monomial table per spline, in one array md
    for off, _, k in blocks:
        if off not in tables:
            tables[off] = (pos, monomials(fdc, off, k))
            pos += tables[off][1].size
        mono.append((tables[off][0], tables[off][1].shape[1:3]))
    md = np.ascontiguousarray(np.concatenate([t.ravel() for _, t in tables.values()]))
    sums = {}
    for label, variant in ((FLOOR, None), (FLOOR_MONO, mono)):
        mod = build(floor_source(blocks, variant), CDEF)
        out = np.zeros(N)
        ptr = [mod.ffi.cast("double *", a.ctypes.data) for a in (x_tor, X, fdc, md, out)]

        def floor_call(mod=mod, ptr=ptr, out=out):
            out[:] = 0.0
            mod.lib.vp_floor(N, *ptr[:4], n, ptr[4])
            return out.copy()

        floor_call()
        t_floor, sums[label] = best_of(floor_call, rounds)
        per[label] = t_floor * 1e9 / (N * n)
    # both readings compute the same sum of spline values: the monomial tables are the spline
    diff = float(np.max(np.abs(sums[FLOOR] - sums[FLOOR_MONO])) / np.max(np.abs(sums[FLOOR])))
    assert np.all(np.isfinite(sums[FLOOR])) and diff <= 1e-10, diff
    ref = per["tokamak (closed form), native step"]
    coeffs = sum((k[0] + 1) * (k[1] + 1) * (k[2] + 1) for _, _, k in blocks)
    lines = ["# The cost floor of a spline step (issue #20)", "",
             (f"SE+SE (recover=False), h = {h}, N = {N:,} field lines of the tokamak, one process, "
              f"2 OpenMP threads; ns per particle-step (steps: (best of {rounds} runs of {2 * n} − "
              f"best of {rounds} runs of {n}) / (N·n); floor: best of {rounds} runs of {n} "
              f"steps / (N·n), in the kernel's loop order). Spline: {'×'.join(map(str, grid))} (R, φ, Z) nodes of A. The floor reads "
              f"the {len(blocks)} (spline, point) blocks the generated step reads — "
              f"{len(guard)} at x for a(x) (the guard's B(x), also the first guess), "
              + ", ".join(f"{len(lp)} in solve {j + 1}" for j, lp in enumerate(loops))
              + f" ({coeffs} coefficients) — with their cells and bases, and nothing else "
              "(no solve, no sharing between blocks); the second floor reads them from per-cell "
              f"monomial tables (a 3-D Horner, no bases; {md.nbytes / fdc.nbytes:.1f}× the memory of "
              f"the kernel's data). The two floors' sums of spline values agree to {diff:.1g} "
              "(relative)."), "",
             "| row | ns / particle-step | × closed-form step |", "|---|---:|---:|"]
    for label, t in per.items():
        lines.append(f"| {label} | {t:,.1f} | {t / ref:.2f} |")
    fl = per[FLOOR]
    lines += ["", (f"The issue's targets: spline step ≤ 5× the closed-form step (≤ {5 * ref:.0f} ns "
                   f"here); the floor alone is {fl / ref:.1f}× it ({per[FLOOR_MONO] / ref:.1f}× with "
                   f"monomial tables), the step {per['tokamak (spline of A), native step'] / fl:.1f}× "
                   "the floor."), "",
              f"Load average at the end: {os.getloadavg()[0]:.1f}.", "",
              machine("bench_spline_floor.py", time.perf_counter() - t0, smoke), ""]
    return write_results(args.out, "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())

"""simsopt on W7-X as its users run it, against a tight direct-Biot–Savart reference (issue #38, item 5).

The simsopt side of the W7-X side-by-side benchmark; never in CI, never a vpforms dependency. Run it
with the python of simsopt's own virtual environment, from the repository root, one thread:

    OMP_NUM_THREADS=1 nice -n 5 /work/peers/simsopt/bin/python benchmarks/peers/run_simsopt_w7x.py all
    # stages one by one: reference | verify | direct | interp | bscost | report   (--work DIR keeps the parts)

What it does (numpy and simsopt only; it reads vpforms' coil file as JSON, it never imports vpforms):

1. W7-X exactly as ``benchmarks/peers/make_devices.py`` builds it: ``simsopt.configs.get_data("w7x")``
   (96 quadrature points per coil), ``coils_via_symmetries(curves, currents, 5, stellsym=True)`` — all
   70 coils, the 20 planar ones with zero current included, as simsopt evaluates them — and
   ``BiotSavart``; checked against the B stored in ``src/vpforms/coils/data/w7x.json``.
2. 20 start points on the outboard midplane of φ = 0: Z = 0, R = R_axis + linspace(0.0125, 0.25, 20),
   R_axis the JSON's corrected axis at φ = 0.
3. REFERENCE: ``compute_fieldlines`` on the direct ``BiotSavart`` at tol 1e-12, 50 toroidal transits,
   section crossings of the 10 planes φ = kπ/5 (φ = 0 mod 2π/5 the bean, π/5 mod 2π/5 the triangle,
   every period) → ``benchmarks/peers/data/w7x_reference.npz`` (ordering: ``w7x_reference.py``); its own
   error: two lines retraced at tol 1e-13.
4. simsopt as users run it: ``InterpolatedField`` (degree 3 and 5, (nr, nφ, nz) = (20, 40, 10)·k on one
   period, ``nfp=5, stellsym=True`` as simsopt's ``tracing_fieldlines_QA.py`` example, on the (R, Z) box
   of vpforms' default W7-X domain) traced at tol 1e-7, 1e-9, 1e-10 (degree 5 on the finer grid: 1e-10,
   1e-11, 1e-12) for 1 000 transits: the section error
   over the first 50 transits against the reference, the wall time of 20 lines × 1 000 transits, the
   build time apart, the peak RSS; the direct ``BiotSavart`` traced for 50 transits at tol 1e-7 and
   1e-9 (1 000 transits extrapolated ×20); simsopt's ``BiotSavart`` cost per point-segment pair.
5. ``benchmarks/peers/results_simsopt_w7x.json`` and ``.md``.

All timings at OMP_NUM_THREADS=1 (the script refuses another value), each timed setting in its own
process (peak RSS = ``resource.getrusage`` of that process), the load average recorded before each.
``compute_fieldlines`` stores every step of a line; the script traces one line per call (20 calls) and
keeps only the section crossings, so the peak RSS is the field plus one line's trajectory.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if os.environ.get("OMP_NUM_THREADS") != "1":
    sys.exit("run_simsopt_w7x.py: set OMP_NUM_THREADS=1 (all timings are single-threaded)")

import simsopt  # noqa: E402
from simsopt.configs import get_data  # noqa: E402
from simsopt.field import BiotSavart, InterpolatedField, compute_fieldlines  # noqa: E402
from simsopt.field.coil import coils_via_symmetries  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
JSON_COILS = ROOT / "src" / "vpforms" / "coils" / "data" / "w7x.json"
REFERENCE = HERE / "data" / "w7x_reference.npz"
RESULTS_JSON = HERE / "results_simsopt_w7x.json"
RESULTS_MD = HERE / "results_simsopt_w7x.md"
WORK = Path("/tmp/vpforms_simsopt_w7x")

NFP = 5
N_LINES = 20
OFFSETS = np.linspace(0.0125, 0.25, N_LINES)          # m outboard of the axis, φ = 0, Z = 0
PHIS = [k * np.pi / NFP for k in range(2 * NFP)]       # every period's bean (k even) and triangle (k odd)
PLANES_PER_TRANSIT = 2 * NFP
TRANSITS_REF = 50
TOL_REF = 1e-12
TOL_CHECK = 1e-13
CHECK_LINES = (9, 19)                                   # retraced at TOL_CHECK (mid radius, outermost)
TRANSITS_LONG = 1000
TOLS_INTERP = (1e-7, 1e-9, 1e-10)
TOLS_DIRECT = (1e-7, 1e-9)
#: (degree, k, tols): (nr, nφ, nz) = (20, 40, 10)·k cells on one period; the last one is the finest that
#: reaches ~1e-5 m (the error issue #38 asks of vpforms) within the time at hand
INTERP = ((3, 1, TOLS_INTERP), (3, 2, TOLS_INTERP), (5, 1, TOLS_INTERP), (5, 2, (1e-10, 1e-11, 1e-12)))
N_BS_POINTS = 10_000
CPU_SECONDS: list = []                                 # CPU s of each trace() call (load-independent)
REFINE_H = 1e-3                                        # rad, RK4 step of ``refine``


# ------------------------------------------------------------------------------------------------
# the device and the start points
# ------------------------------------------------------------------------------------------------
def load_coil_json() -> dict:
    return json.loads(JSON_COILS.read_text())


def axis_R_at_0(data: dict) -> float:
    """R of the JSON's corrected axis at φ = 0: R(0) = Σ_m rc_m (Z(0) = 0, stellarator symmetric)."""
    return float(np.sum(data["axis"]["rc"]))


def start_points(data: dict) -> tuple[np.ndarray, np.ndarray]:
    R = axis_R_at_0(data) + OFFSETS
    return R, np.zeros_like(R)


def biot_savart() -> BiotSavart:
    """W7-X as make_devices.py builds it, checked against the JSON's stored B (20 points)."""
    curves, currents, _, nfp, _ = get_data("w7x")
    bs = BiotSavart(coils_via_symmetries(curves, currents, nfp, True))
    check = load_coil_json()["check"]
    bs.set_points(np.ascontiguousarray(check["points"], dtype=float))
    B, B_json = np.array(bs.B()), np.array(check["B"])
    err = float(np.max(np.abs(B - B_json)) / np.max(np.abs(B_json)))
    if err > 1e-12:
        raise RuntimeError(f"simsopt's W7-X B differs from w7x.json's stored B by {err:.1e} (relative)")
    return bs


def n_quadrature_points(bs: BiotSavart) -> int:
    return int(sum(len(c.curve.quadpoints) for c in bs.coils))


def box(data: dict, pad: float = 0.01) -> tuple[tuple[float, float], tuple[float, float]]:
    """(R range, Z range ≥ 0) of vpforms' default W7-X domain (its VMEC-form boundary on 512 θ × 200 φ
    of one period), padded by ``pad`` and rounded outward to 1 cm; Z from 0 (stellsym)."""
    d = data["domain"]
    rmnc, zmns, xm, xn = (np.asarray(d[k], dtype=float) for k in ("rmnc", "zmns", "xm", "xn"))
    th, ph = np.meshgrid(np.linspace(0, 2 * np.pi, 512, endpoint=False),
                         np.linspace(0, 2 * np.pi / NFP, 200, endpoint=False))
    ang = np.multiply.outer(th, xm) - np.multiply.outer(ph, xn)
    R, Z = np.cos(ang) @ rmnc, np.sin(ang) @ zmns
    lo, hi = np.floor((R.min() - pad) * 100) / 100, np.ceil((R.max() + pad) * 100) / 100
    return (float(lo), float(hi)), (0.0, float(np.ceil((Z.max() + pad) * 100) / 100))


# ------------------------------------------------------------------------------------------------
# tracing and the crossings
# ------------------------------------------------------------------------------------------------
def crossings(hits: np.ndarray, direction: int) -> dict:
    """The section crossings of one line from compute_fieldlines' ``res_phi_hits`` rows
    [t, idx, x, y, z]: the accumulated toroidal angle of a hit is PHIS[idx] unwrapped along the hits
    from φ = 0 (consecutive hits are π/5 apart); its crossing index j = direction·φ_acc/(π/5) (1, 2, …;
    the start, which simsopt records as a hit at t = 0 when the line moves towards −φ, is j = 0 and
    dropped). R, Z, φ: the hit point as simsopt returns it (see ``refine``)."""
    h = hits[hits[:, 1] >= 0]
    phi = np.unwrap(np.r_[0.0, np.asarray(PHIS)[h[:, 1].astype(int)]])[1:]
    j = np.rint(direction * phi / (np.pi / NFP)).astype(np.int64)
    keep = j >= 1
    h, j = h[keep], j[keep]
    return {"j": j, "R": np.hypot(h[:, 2], h[:, 3]), "Z": h[:, 4].copy(), "t": h[:, 0].copy(),
            "phi": np.arctan2(h[:, 3], h[:, 2]), "idx": h[:, 1].astype(np.int64)}


def refine(field, c: dict, h_max: float) -> dict:
    """The crossings moved exactly onto their planes along the traced field.

    simsopt 1.11.1's ``solve`` (src/simsoptpp/tracing.cpp) locates a plane crossing with
    ``toms748_solve(…, roottol, rootmaxit)``, whose ``max_iter`` argument is passed by reference and
    set to the iterations used; ``rootmaxit`` is declared once per line, so it only shrinks — and a
    line that leaves φ = 0 towards −φ (W7-X) records its start as a hit with f(a) = 0, which sets it to
    0 at once. From then on no iteration is made: the "crossing" is the step end (tlast or tcurrent)
    nearer to the plane, off it by up to half a step in φ (mm at tol 1e-12). The hit is still a point
    of the integrated trajectory, so integrating dR/dφ = R·B_R/B_φ, dZ/dφ = R·B_Z/B_φ from its φ to the
    plane's (classical RK4, n = ⌈max|Δφ|/h_max⌉ equal steps, all crossings at once) puts it on the
    plane with the field that traced it. RK4's error is O(h⁴) of a path ≤ half a tracer step long."""
    if c["j"].size == 0:
        return {**c, "n_refine": 0}
    target = np.asarray(PHIS)[c["idx"]]
    dphi = np.remainder(target - c["phi"] + np.pi, 2 * np.pi) - np.pi
    n = max(1, int(np.ceil(np.abs(dphi).max() / h_max)))
    h = dphi / n
    R, Z, phi = c["R"].copy(), c["Z"].copy(), c["phi"].copy()

    def f(R, phi, Z):
        field.set_points_cyl(np.ascontiguousarray(np.c_[R, np.remainder(phi, 2 * np.pi), Z]))
        B = np.asarray(field.B_cyl())
        return R * B[:, 0] / B[:, 1], R * B[:, 2] / B[:, 1]

    for _ in range(n):
        k1 = f(R, phi, Z)
        k2 = f(R + 0.5 * h * k1[0], phi + 0.5 * h, Z + 0.5 * h * k1[1])
        k3 = f(R + 0.5 * h * k2[0], phi + 0.5 * h, Z + 0.5 * h * k2[1])
        k4 = f(R + h * k3[0], phi + h, Z + h * k3[1])
        R = R + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        Z = Z + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        phi = phi + h
    return {**c, "R_raw": c["R"], "Z_raw": c["Z"], "R": R, "Z": Z, "dphi_raw": dphi, "n_refine": n}


def trace(field, R0: np.ndarray, Z0: np.ndarray, tmax: np.ndarray, tol: float, direction: int) -> tuple[list, float]:
    """compute_fieldlines one line per call (the trajectory of each is dropped at once): per line its
    crossings, refined onto the planes with the same field (``refine``; not timed); the total wall
    seconds of the compute_fieldlines calls (their CPU seconds are appended to CPU_SECONDS)."""
    out, seconds, cpu = [], 0.0, 0.0
    for R, Z, T in zip(R0, Z0, tmax):
        t, c = time.perf_counter(), time.process_time()
        _, hits = compute_fieldlines(field, [float(R)], [float(Z)], tmax=float(T), tol=tol, phis=PHIS)
        seconds += time.perf_counter() - t
        cpu += time.process_time() - c
        out.append(crossings(np.asarray(hits[0]), direction))
    CPU_SECONDS.append(cpu)
    return [refine(field, c, REFINE_H) for c in out], seconds


def direction_of_B(bs, R0: float) -> int:
    """+1 if B^φ > 0 at (R0, φ = 0, Z = 0) (the line moves towards +φ), else −1."""
    bs.set_points(np.array([[R0, 0.0, 0.0]]))
    return 1 if float(np.asarray(bs.B())[0, 1]) > 0 else -1


def load() -> tuple[float, float, float]:
    return tuple(round(x, 2) for x in os.getloadavg())


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB


# ------------------------------------------------------------------------------------------------
# the errors against the reference
# ------------------------------------------------------------------------------------------------
def errors(ref, lines: list, transits: int | None = None, raw: bool = False) -> dict:
    """Section error over the first ``transits`` transits: per plane (bean: j even; triangle: j odd)
    max and median of |(R, Z) − reference| over every line and crossing; the error at the last
    crossing (j = 10·transits, the plane φ = 0); the lines that miss a crossing of the reference."""
    from w7x_reference import section_error  # this folder

    jmax = (TRANSITS_REF if transits is None else transits) * PLANES_PER_TRANSIT
    if raw:  # the points as compute_fieldlines returns them
        lines = [{**c, "R": c.get("R_raw", c["R"]), "Z": c.get("Z_raw", c["Z"])} for c in lines]
    out, missing, per_line = {}, [], []
    rows = {"bean": [], "triangle": []}
    for i, c in enumerate(lines):
        sel = c["j"] <= jmax
        j, R, Z = c["j"][sel], c["R"][sel], c["Z"][sel]
        if j.size == 0 or len(np.unique(j)) != jmax or j.min() != 1:
            missing.append(i)
        per_line.append(section_error(ref, R, Z, np.full(j.shape, i), j, plane="bean")[0] if j.size else float("nan"))
        for plane in rows:
            rows[plane].append((R, Z, np.full(j.shape, i), j))
    for plane, rr in rows.items():
        R, Z, li, j = (np.concatenate(x) for x in zip(*rr))
        mx, med = section_error(ref, R, Z, li, j, plane=plane)
        out[f"{plane}_max_m"], out[f"{plane}_median_m"] = mx, med
    last = []
    for i, c in enumerate(lines):
        sel = c["j"] == jmax
        if sel.any():
            last.append(section_error(ref, c["R"][sel], c["Z"][sel], np.array([i]), np.array([jmax]))[0])
    out["last_crossing_max_m"] = max(last) if last else float("nan")
    out["per_line_bean_max_m"] = per_line
    out["lines_missing_crossings"] = missing
    return out


def reached(lines: list, transits: int) -> dict:
    jmax = transits * PLANES_PER_TRANSIT
    n = [int(np.sum(c["j"] <= jmax)) for c in lines]
    return {"crossings_expected_per_line": jmax, "crossings_min": min(n), "crossings_max": max(n),
            "lines_short": [i for i, k in enumerate(n) if k < jmax]}


# ------------------------------------------------------------------------------------------------
# stages
# ------------------------------------------------------------------------------------------------
def stage_reference(work: Path) -> None:
    data = load_coil_json()
    R0, Z0 = start_points(data)
    bs = biot_savart()
    direction = direction_of_B(bs, R0[0])
    # dx/dt = B: |B|·t is arclength; 15 % more than 50 transits of a circle at R0 with |B(start)|
    absB = []
    for R in R0:
        bs.set_points(np.array([[R, 0.0, 0.0]]))
        absB.append(float(np.linalg.norm(bs.B())))
    tmax = 1.06 * TRANSITS_REF * 2 * np.pi * R0 / np.array(absB)
    ld = load()
    lines, seconds = trace(bs, R0, Z0, tmax, TOL_REF, direction)
    jmax = TRANSITS_REF * PLANES_PER_TRANSIT
    for i, c in enumerate(lines):  # a line short of 50 transits: again with more time
        while c["j"].size and c["j"].max() < jmax:
            tmax[i] *= 1.1 * jmax / c["j"].max()
            print(f"reference line {i}: {c['j'].max()} crossings, again with tmax {tmax[i]:.1f}", flush=True)
            (c,), extra = trace(bs, R0[i:i + 1], Z0[i:i + 1], tmax[i:i + 1], TOL_REF, direction)
            seconds += extra
            lines[i] = c
    for i, c in enumerate(lines):
        if not np.array_equal(c["j"][c["j"] <= jmax], np.arange(1, jmax + 1)):
            raise RuntimeError(f"reference line {i}: crossings {c['j'][:5]}… do not run 1 … {jmax} in order")
    cut = [{k: v[c["j"] <= jmax] for k, v in c.items() if isinstance(v, np.ndarray)} for c in lines]
    cat = {k: np.concatenate([c[k] for c in cut]) for k in ("j", "R", "Z", "t", "idx", "R_raw", "Z_raw", "dphi_raw")}
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        REFERENCE,
        start_R=R0, start_Z=Z0, start_phi=np.zeros_like(R0), offsets=OFFSETS, R_axis=axis_R_at_0(data),
        line=np.concatenate([np.full(len(c["j"]), i, dtype=np.int32) for i, c in enumerate(cut)]),
        crossing=cat["j"].astype(np.int32), R=cat["R"], Z=cat["Z"], t=cat["t"],
        phi_plane=np.asarray(PHIS)[cat["idx"]],
        R_simsopt=cat["R_raw"], Z_simsopt=cat["Z_raw"], dphi_simsopt=cat["dphi_raw"],
        t_50_transits=np.array([c["t"][-1] for c in cut]),
        direction=np.int32(direction), nfp=np.int32(NFP), transits=np.int32(TRANSITS_REF),
        tol=np.float64(TOL_REF),
        info=np.array(json.dumps({
            "what": "W7-X (simsopt get_data('w7x'), 70 coils × 96 quadrature points) field-line section crossings, "
                    "simsopt compute_fieldlines on the direct BiotSavart",
            "R_Z": "R, Z: simsopt's crossings moved onto the plane along the direct BiotSavart (RK4 in φ, "
                   "run_simsopt_w7x.refine); R_simsopt, Z_simsopt: the points compute_fieldlines returns, "
                   "dphi_simsopt = plane − their φ (simsopt 1.11.1's root finder stops iterating: refine's docstring)",
            "simsopt": simsopt.__version__, "tol": TOL_REF, "transits": TRANSITS_REF, "seconds": seconds,
            "load": ld, "script": "benchmarks/peers/run_simsopt_w7x.py reference",
            "date": datetime.date.today().isoformat(),
            "ordering": "see benchmarks/peers/w7x_reference.py"})))
    write_part(work, "reference", {"tol": TOL_REF, "transits": TRANSITS_REF, "seconds": seconds, "load": ld,
                                   "simsopt_crossing_offplane_max_rad": float(np.abs(cat["dphi_raw"]).max()),
                                   "simsopt_crossing_vs_refined_max_m": float(np.hypot(cat["R"] - cat["R_raw"], cat["Z"] - cat["Z_raw"]).max()),
                                   "direction": direction, "peak_rss_mb": peak_rss_mb(),
                                   "npz_bytes": REFERENCE.stat().st_size})
    print(f"reference: {N_LINES} lines × {TRANSITS_REF} transits at tol {TOL_REF:g} in {seconds:.0f} s → {REFERENCE}")


def ref_tmax(ref, transits: float) -> np.ndarray:
    """Per line, the time to trace ``transits`` transits: the reference's time of 50 transits scaled,
    plus 2 % (the time per transit of one line varies by less over 50 transits)."""
    return 1.02 * ref["t_50_transits"] * transits / TRANSITS_REF


def stage_verify(work: Path) -> None:
    from w7x_reference import load_reference, section_error

    ref = load_reference(REFERENCE)
    bs = biot_savart()
    idx = np.array(CHECK_LINES)
    ld = load()
    lines, seconds = trace(bs, ref["start_R"][idx], ref["start_Z"][idx], ref_tmax(ref, TRANSITS_REF)[idx],
                           TOL_CHECK, int(ref["direction"]))
    per, raw = {}, {}
    for i, c in zip(idx, lines):
        sel = c["j"] <= TRANSITS_REF * PLANES_PER_TRANSIT
        per[int(i)] = section_error(ref, c["R"][sel], c["Z"][sel], np.full(sel.sum(), i), c["j"][sel], plane="all")
        raw[int(i)] = section_error({**ref, "R": ref["R_simsopt"], "Z": ref["Z_simsopt"]}, c["R_raw"][sel],
                                    c["Z_raw"][sel], np.full(sel.sum(), i), c["j"][sel], plane="all")
    write_part(work, "verify", {"tol": TOL_CHECK, "lines": [int(i) for i in idx], "seconds": seconds,
                                "cpu_seconds": CPU_SECONDS[-1], "load": ld,
                                "as_returned_max_m": max(v[0] for v in raw.values()),
                                "as_returned_per_line_max_median_m": {str(k): v for k, v in raw.items()},
                                "max_m": max(v[0] for v in per.values()),
                                "per_line_max_median_m": {str(k): v for k, v in per.items()}})
    print(f"verify: lines {list(idx)} at tol {TOL_CHECK:g}: max |Δ(R, Z)| {max(v[0] for v in per.values()):.2e} m")


def stage_direct(work: Path, tol: float) -> None:
    from w7x_reference import load_reference

    ref = load_reference(REFERENCE)
    bs = biot_savart()
    ld = load()
    lines, seconds = trace(bs, ref["start_R"], ref["start_Z"], ref_tmax(ref, TRANSITS_REF), tol,
                           int(ref["direction"]))
    write_part(work, f"direct_{tol:g}", {
        "field": "direct BiotSavart", "tol": tol, "transits": TRANSITS_REF, "seconds_50": seconds,
        "cpu_seconds_50": CPU_SECONDS[-1],
        "seconds_1000_extrapolated": seconds * TRANSITS_LONG / TRANSITS_REF, "load": ld,
        "errors": errors(ref, lines), "errors_as_returned": errors(ref, lines, raw=True), "reached": reached(lines, TRANSITS_REF), "peak_rss_mb": peak_rss_mb()})
    print(f"direct tol {tol:g}: 50 transits {seconds:.1f} s")


def stage_interp(work: Path, degree: int, k: int, tols, transits: int) -> None:
    from w7x_reference import load_reference

    ref = load_reference(REFERENCE)
    data = load_coil_json()
    (rlo, rhi), (zlo, zhi) = box(data)
    n = (20 * k, 40 * k, 10 * k)
    bs = biot_savart()
    ld = load()
    t, c = time.perf_counter(), time.process_time()
    field = InterpolatedField(bs, degree, (rlo, rhi, n[0]), (0, 2 * np.pi / NFP, n[1]), (zlo, zhi, n[2]),
                              True, nfp=NFP, stellsym=True)
    field.set_points(np.array([[ref["start_R"][0], 0.0, 0.0]]))
    field.B()  # the build happens in the constructor; one evaluation to be sure
    build, build_cpu = time.perf_counter() - t, time.process_time() - c
    rss_build = peak_rss_mb()
    runs = []
    for tol in tols:
        ld_run = load()
        lines, seconds = trace(field, ref["start_R"], ref["start_Z"], ref_tmax(ref, transits), tol, int(ref["direction"]))
        runs.append({"tol": tol, "transits": transits, "seconds": seconds, "cpu_seconds": CPU_SECONDS[-1], "load": ld_run,
                     "errors": errors(ref, lines), "errors_as_returned": errors(ref, lines, raw=True), "reached": reached(lines, transits), "peak_rss_mb": peak_rss_mb()})
        print(f"interp degree {degree} cells {n} tol {tol:g}: {transits} transits {seconds:.1f} s, "
              f"bean error@50 max {runs[-1]['errors']['bean_max_m']:.2e} m", flush=True)
    write_part(work, f"interp_d{degree}_k{k}", {
        "field": "InterpolatedField", "degree": degree, "cells": n, "rrange": [rlo, rhi], "zrange": [zlo, zhi],
        "phirange": [0, 2 * np.pi / NFP], "nfp": NFP, "stellsym": True, "extrapolate": True, "skip": None,
        "build_seconds": build, "build_cpu_seconds": build_cpu, "build_load": ld, "peak_rss_mb_after_build": rss_build, "runs": runs,
        "peak_rss_mb": peak_rss_mb()})


def stage_bscost(work: Path) -> None:
    """simsopt BiotSavart: seconds per point-segment pair, 10⁴ random points in the plasma (φ uniform,
    uniform in the disc of radius 0.2 m around the axis), best of 3 (set_points + B)."""
    data = load_coil_json()
    rng = np.random.default_rng(38)
    phi = rng.uniform(0, 2 * np.pi, N_BS_POINTS)
    m = np.arange(len(data["axis"]["rc"]))
    Ra = np.cos(np.outer(phi, m * NFP)) @ data["axis"]["rc"]
    Za = np.sin(np.outer(phi, m[1:] * NFP)) @ data["axis"]["zs"]
    r, a = 0.2 * np.sqrt(rng.uniform(0, 1, N_BS_POINTS)), rng.uniform(0, 2 * np.pi, N_BS_POINTS)
    R, Z = Ra + r * np.cos(a), Za + r * np.sin(a)
    pts = np.ascontiguousarray(np.c_[R * np.cos(phi), R * np.sin(phi), Z])
    bs = biot_savart()
    nq = n_quadrature_points(bs)
    ld = load()
    times, cpus = [], []
    for _ in range(3):
        t, c = time.perf_counter(), time.process_time()
        bs.set_points(pts)
        bs.B()
        times.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    best = min(times)
    write_part(work, "bscost", {"points": N_BS_POINTS, "coils": len(bs.coils), "quadrature_points": nq,
                                "seconds": times, "cpu_seconds": cpus, "load": ld, "seconds_per_point": best / N_BS_POINTS,
                                "cpu_seconds_per_pair": min(cpus) / (N_BS_POINTS * nq),
                                "seconds_per_pair": best / (N_BS_POINTS * nq)})
    print(f"BiotSavart: {best / N_BS_POINTS * 1e6:.1f} µs per point, {best / (N_BS_POINTS * nq) * 1e9:.2f} ns per pair")


def write_part(work: Path, name: str, d: dict) -> None:
    work.mkdir(parents=True, exist_ok=True)
    (work / f"{name}.json").write_text(json.dumps(d, indent=1, default=float))


# ------------------------------------------------------------------------------------------------
# the report
# ------------------------------------------------------------------------------------------------
def stage_report(work: Path) -> None:
    parts = {p.stem: json.loads(p.read_text()) for p in sorted(work.glob("*.json"))}
    data = load_coil_json()
    R0, _ = start_points(data)
    bs = biot_savart()
    out = {
        "what": "simsopt on W7-X (issue #38 item 5): reference, InterpolatedField and direct BiotSavart tracing",
        "script": "benchmarks/peers/run_simsopt_w7x.py",
        "date": datetime.date.today().isoformat(),
        "versions": {"simsopt": simsopt.__version__, "numpy": np.__version__, "python": platform.python_version()},
        "machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
                    "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS")},
        "device": {"coils": len(bs.coils), "quadrature_points_per_coil": int(data["n_quadpoints"]),
                   "quadrature_points_total": n_quadrature_points(bs), "nfp": NFP,
                   "coil_file": "src/vpforms/coils/data/w7x.json (checked: same B)"},
        "start_points": {"R": R0.tolist(), "Z": [0.0] * N_LINES, "phi": 0.0, "R_axis": axis_R_at_0(data),
                         "offsets_m": OFFSETS.tolist()},
        "planes": {"phis": PHIS, "note": "crossing j: φ_acc = direction·j·π/5; bean j even, triangle j odd"},
        "reference_file": "benchmarks/peers/data/w7x_reference.npz",
        "parts": parts,
    }
    RESULTS_JSON.write_text(json.dumps(out, indent=1, default=float) + "\n")
    RESULTS_MD.write_text(markdown(out))
    print(f"wrote {RESULTS_JSON} and {RESULTS_MD}")


def fmt(x, spec=".2e") -> str:
    return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def markdown(out: dict) -> str:
    p = out["parts"]
    ref, ver, bsc = p.get("reference", {}), p.get("verify", {}), p.get("bscost", {})
    ldf = lambda ld: "/".join(f"{x:.2f}" for x in ld)  # noqa: E731
    pair = lambda e, plane: f"{fmt(e[plane + '_max_m'])} / {fmt(e[plane + '_median_m'])}"  # noqa: E731
    inner = lambda e: fmt(max(e["per_line_bean_max_m"][:-1]))  # noqa: E731  (all lines but the outermost)
    rows, raw = [], []
    for name, d in sorted(p.items()):
        if name.startswith("interp_"):
            for r in d["runs"]:
                label = (f"InterpolatedField degree {d['degree']}, {d['cells'][0]}×{d['cells'][1]}×{d['cells'][2]}, "
                         f"tol {r['tol']:g}")
                e, ea = r["errors"], r["errors_as_returned"]
                rows.append((label, f"{d['build_seconds']:.1f} ({d['build_cpu_seconds']:.1f})", pair(e, "bean"),
                             inner(e), pair(e, "triangle"), f"{r['seconds']:.0f} ({r['cpu_seconds']:.0f})", fmt(d["peak_rss_mb"], ".0f"),
                             str(len(e["lines_missing_crossings"])), ldf(r["load"])))
                raw.append((label, pair(ea, "bean"), pair(ea, "triangle")))
    for name, d in sorted(p.items()):
        if name.startswith("direct_"):
            e, ea = d["errors"], d["errors_as_returned"]
            label = f"direct BiotSavart, tol {d['tol']:g}"
            rows.append((label, "0", pair(e, "bean"), inner(e), pair(e, "triangle"),
                         f"{d['seconds_1000_extrapolated']:.0f} ({20 * d['cpu_seconds_50']:.0f}), ×20 of "
                         f"{d['seconds_50']:.0f} s measured at 50 transits",
                         fmt(d["peak_rss_mb"], ".0f"), str(len(e["lines_missing_crossings"])), ldf(d["load"])))
            raw.append((label, pair(ea, "bean"), pair(ea, "triangle")))
    if ref and ver:
        rows.append((f"direct BiotSavart, tol {ref['tol']:g} (the reference)", "0",
                     f"≈ {fmt(ver['max_m'])} (own error, lines {ver['lines']})",
                     "—", "—",
                     f"{ref['seconds'] * TRANSITS_LONG / ref['transits']:.0f}, ×20 of {ref['seconds']:.0f} s "
                     f"measured at {ref['transits']} transits", fmt(ref["peak_rss_mb"], ".0f"), "0", ldf(ref["load"])))
    head = ("| setting | build s wall (CPU) | error@50 bean max / median (m) | bean max, lines 0–18 (m) | error@50 triangle max / median (m) "
            "| 20 lines × 1 000 transits, s wall (CPU) | peak RSS MB | lines missing crossings | load |")
    lines = [
        "# simsopt on W7-X: InterpolatedField and direct BiotSavart against a tol-1e-12 reference",
        "",
        f"Generated by `benchmarks/peers/run_simsopt_w7x.py` (simsopt {out['versions']['simsopt']}, "
        f"OMP_NUM_THREADS=1, one process per setting) on {out['date']}. W7-X from `get_data(\"w7x\")`: "
        f"{out['device']['coils']} coils × {out['device']['quadrature_points_per_coil']} quadrature points. "
        f"20 lines from (R_axis + {OFFSETS[0]} … {OFFSETS[-1]} m, φ = 0, Z = 0), R_axis = {out['start_points']['R_axis']:.6f} m.",
        "",
        head,
        "|" + "---|" * 9,
        *("| " + " | ".join(r) + " |" for r in rows),
        "",
        "Error@50: |(R, Z) − reference| over every line's crossings of the bean planes (φ ≡ 0 mod 2π/5, "
        "250 per line) and of the triangle planes (φ ≡ π/5 mod 2π/5) in the first 50 transits; the error grows "
        "towards the last closed surface and the outermost line (R_axis + 0.25 m) has the largest in most settings, hence "
        "the column without it (per-line maxima in the JSON). The 1 000-transit "
        "wall time is the sum of 20 `compute_fieldlines` calls (one line each, crossings of 10 planes recorded), "
        "the InterpolatedField's build apart. `load`: the machine's 1/5/15-minute load average before that timing "
        "(2 cores, shared); the CPU seconds (`time.process_time`, one thread) are what the load does not inflate. Peak RSS: the process of that setting (BiotSavart, the interpolant, one line's trajectory).",
        "",
        "The crossings above are simsopt's hit points moved onto their plane along the same field (RK4 in φ, "
        "`refine`): simsopt 1.11.1's root finder stops iterating after a line's first hit (`rootmaxit` is passed by "
        "reference to boost's `toms748_solve` and only shrinks; the start, a hit with f = 0, sets it to 0), so the "
        "points `compute_fieldlines` returns are step ends, up to half a step off the plane. Their errors as "
        f"returned (the reference's own points are off the plane by up to {fmt(ref.get('simsopt_crossing_vs_refined_max_m'))} m "
        f"at tol {ref.get('tol', float('nan')):g}):",
        "",
        "| setting | as returned: error@50 bean max / median (m) | triangle max / median (m) |",
        "|---|---|---|",
        *("| " + " | ".join(r) + " |" for r in raw),
        "",
        f"Reference: `compute_fieldlines` on the direct BiotSavart, tol {ref.get('tol', float('nan')):g}, "
        f"{ref.get('transits', '—')} transits, {fmt(ref.get('seconds'), '.0f')} s (load {ref.get('load')}), crossings "
        f"refined onto the planes; its own error (lines {ver.get('lines')} retraced at tol {ver.get('tol', float('nan')):g}): "
        f"max {fmt(ver.get('max_m'))} m (as returned: {fmt(ver.get('as_returned_max_m'))} m).",
        "",
        f"simsopt BiotSavart: {fmt(bsc.get('seconds_per_point', float('nan')) * 1e6, '.1f')} µs per point, "
        f"{fmt(bsc.get('seconds_per_pair', float('nan')) * 1e9, '.2f')} ns per point-segment pair "
        f"({bsc.get('points')} points × {bsc.get('quadrature_points')} quadrature points, 1 thread, load {bsc.get('load')}).",
        "",
    ]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------
def run_all(work: Path, skip_reference: bool) -> None:
    """Every stage in its own process, one after the other."""
    me = [sys.executable, str(Path(__file__).resolve()), "--work", str(work)]
    steps = [] if skip_reference else [["reference"]]
    steps += [["verify"], ["bscost"]]
    steps += [["interp", "--degree", str(d), "--k", str(k), "--tols", *(f"{t:g}" for t in tols)] for d, k, tols in INTERP]
    steps += [["direct", "--tol", f"{t:g}"] for t in TOLS_DIRECT]
    steps += [["report"]]
    for s in steps:
        print("$", " ".join(s), flush=True)
        subprocess.run(me + s, check=True)


def main() -> None:
    sys.path.insert(0, str(HERE))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stage", choices=("all", "reference", "verify", "direct", "interp", "bscost", "report"))
    ap.add_argument("--work", type=Path, default=WORK, help="folder of the per-stage JSON parts")
    ap.add_argument("--tol", type=float, default=1e-9, help="direct: the tolerance")
    ap.add_argument("--degree", type=int, default=3, help="interp: the InterpolatedField's degree")
    ap.add_argument("--k", type=int, default=1, help="interp: cells (20, 40, 10)·k")
    ap.add_argument("--tols", type=float, nargs="+", default=TOLS_INTERP, help="interp: the tolerances")
    ap.add_argument("--transits", type=int, default=TRANSITS_LONG, help="interp: transits of the timed run")
    ap.add_argument("--skip-reference", action="store_true", help="all: keep the existing reference file")
    a = ap.parse_args()
    if a.stage == "all":
        run_all(a.work, a.skip_reference)
    elif a.stage == "reference":
        stage_reference(a.work)
    elif a.stage == "verify":
        stage_verify(a.work)
    elif a.stage == "direct":
        stage_direct(a.work, a.tol)
    elif a.stage == "interp":
        stage_interp(a.work, a.degree, a.k, a.tols, a.transits)
    elif a.stage == "bscost":
        stage_bscost(a.work)
    else:
        stage_report(a.work)


if __name__ == "__main__":
    main()

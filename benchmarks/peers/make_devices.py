"""Export the coil sets simsopt ships (W7-X, NCSX, HSX) as small JSON files for vpforms (issue #38).

Run it with the python of simsopt's own virtual environment — never a dependency of vpforms, never
in CI:

    python3 -m venv /work/peers/simsopt && /work/peers/simsopt/bin/pip install simsopt
    /work/peers/simsopt/bin/python benchmarks/peers/make_devices.py            # writes src/vpforms/coils/data/*.json
    /work/peers/simsopt/bin/pip install -e .                                     # only for --makegrid
    /work/peers/simsopt/bin/python benchmarks/peers/make_devices.py --makegrid /tmp/coils   # + coils.w7x, ...

For each device, ``simsopt.configs.get_data(name)`` (default arguments) gives the base curves
(``CurveXYZFourier``), the base currents, the magnetic axis (``CurveRZFourier``) and nfp; the coil
set is ``coils_via_symmetries(curves, currents, nfp, stellsym=True)``. The JSON holds:

* every base curve's Fourier coefficients exactly as simsopt defines the curve, θ ∈ [0, 1),
  x_i(θ) = c_i0 + Σ_{m=1}^{order} (c_im cos 2πmθ + s_im sin 2πmθ)   (i = x, y, z; ``cos``: (3, order+1),
  ``sin``: (3, order)), and the number of quadrature points θ_k = k/n simsopt uses per coil;
* the base currents in ampere (the values simsopt uses, turns included);
* the magnetic axis as ``CurveRZFourier`` data: R(φ) = Σ_m rc_m cos(m nfp φ), Z(φ) = Σ_m zs_m sin(m nfp φ)
  (stellarator symmetric). simsopt's W7-X axis is not the axis of its own W7-X coils (its zs are
  shifted by one mode and of the wrong sign: the angle between B and the curve reaches 46°); the
  JSON's ``axis`` is the aligned one when simsopt's is not (``axis.note`` says which), simsopt's
  own is kept as ``axis_simsopt``; ``axis.max_angle_deg`` is the largest angle between simsopt's B
  and the axis' tangent at 200 points;
* a cross-check: simsopt's ``BiotSavart`` B of the full coil set at 20 seeded points near the axis
  (every φ, minor radii up to 4 % of R_axis), the axis point (R, Z) at φ = 0, and simsopt's own
  quadrature error there (the change of B when the quadrature points per coil are multiplied by 4);
* provenance: simsopt's version, the function called, the date.

``--makegrid DIR`` also writes each full device (the coils with current, vpforms' polylines at
simsopt's quadrature points, :func:`vpforms.coils.device`) as a MAKEGRID file ``DIR/coils.<name>``
with :func:`vpforms.coils.write_makegrid` (vpforms must be installed in this venv). Those files are
not committed.
"""

from __future__ import annotations

import argparse
import datetime
import json
from pathlib import Path

import numpy as np
import simsopt
from simsopt.configs import get_data
from simsopt.field import BiotSavart
from simsopt.field.coil import coils_via_symmetries
from simsopt.geo import CurveRZFourier

DEVICES = ("w7x", "ncsx", "hsx")
OUT = Path(__file__).resolve().parents[2] / "src" / "vpforms" / "coils" / "data"
N_CHECK = 20


def curve_data(curve) -> dict:
    """A ``CurveXYZFourier``'s coefficients: dofs [c0, s1, c1, …, s_N, c_N] per coordinate →
    ``cos`` (3, N+1), ``sin`` (3, N); checked against simsopt's own ``gamma()``."""
    d = np.array(curve.dofs_matrix, dtype=float)
    cos, sin = np.c_[d[:, :1], d[:, 2::2]], d[:, 1::2]
    th = np.asarray(curve.quadpoints)
    m = np.arange(cos.shape[1])
    xyz = cos @ np.cos(2 * np.pi * np.outer(m, th)) + sin @ np.sin(2 * np.pi * np.outer(m[1:], th))
    err = float(np.max(np.abs(xyz.T - curve.gamma())))
    if err > 1e-12:
        raise RuntimeError(f"the Fourier formula does not reproduce simsopt's curve: {err:.2e} m")
    return {"order": int(curve.order), "cos": cos.tolist(), "sin": sin.tolist()}


def axis_curve(rc, zs, nfp: int, n: int = 200) -> CurveRZFourier:
    a = CurveRZFourier(n, len(rc) - 1, nfp, True)
    a.rc[:], a.zs[:] = rc, zs
    a.x = a.get_dofs()
    return a


def max_angle_deg(bs, axis) -> float:
    """The largest angle between B and the axis curve's tangent (degrees)."""
    t = axis.gammadash()
    bs.set_points(np.ascontiguousarray(axis.gamma()))
    B = bs.B()
    cos = np.abs(np.sum(B * t, axis=1)) / (np.linalg.norm(B, axis=1) * np.linalg.norm(t, axis=1))
    return float(np.degrees(np.arccos(np.clip(cos.min(), -1, 1))))


def aligned_axis(ma, bs) -> tuple[dict, dict]:
    """(axis, axis_simsopt): simsopt's axis, and the one aligned with B (simsopt's when it is)."""
    rc, zs, nfp = np.array(ma.rc), np.array(ma.zs), int(ma.nfp)
    own = {"rc": rc.tolist(), "zs": zs.tolist(), "nfp": nfp, "stellsym": True,
           "max_angle_deg": max_angle_deg(bs, axis_curve(rc, zs, nfp))}
    if own["max_angle_deg"] < 0.5:
        return {**own, "note": "simsopt's axis"}, own
    # W7-X: simsopt assigns zs = sZ[:order] with sZ[0] = 0 the m = 0 entry; the aligned one is −sZ[1:]
    fixed = -np.r_[zs[1:], 0.0]
    angle = max_angle_deg(bs, axis_curve(rc, fixed, nfp))
    if angle > 0.5:
        raise RuntimeError(f"simsopt's axis is {own['max_angle_deg']:.1f}° off B and the shifted one {angle:.1f}°")
    return ({"rc": rc.tolist(), "zs": fixed.tolist(), "nfp": nfp, "stellsym": True, "max_angle_deg": angle,
             "note": "simsopt's zs shifted down one mode and negated (zs_m ← −zs_{m+1}); simsopt's own axis "
                     f"(axis_simsopt) is up to {own['max_angle_deg']:.1f}° off its coils' B"}, own)


def check_points(axis: dict, seed: int) -> np.ndarray:
    """N_CHECK Cartesian points near the axis: φ uniform in [0, 2π), minor radius ≤ 0.04 R_axis,
    poloidal angle uniform."""
    rng = np.random.default_rng(seed)
    phi = np.sort(rng.uniform(0, 2 * np.pi, N_CHECK))
    m = np.arange(len(axis["rc"]))
    R = np.cos(np.outer(phi, m * axis["nfp"])) @ axis["rc"]
    Z = np.sin(np.outer(phi, m[1:] * axis["nfp"])) @ axis["zs"]
    r = rng.uniform(0, 0.04 * axis["rc"][0], N_CHECK)
    al = rng.uniform(0, 2 * np.pi, N_CHECK)
    RR, ZZ = R + r * np.cos(al), Z + r * np.sin(al)
    return np.c_[RR * np.cos(phi), RR * np.sin(phi), ZZ]


def biot_savart_B(curves, currents, nfp: int, points: np.ndarray) -> np.ndarray:
    bs = BiotSavart(coils_via_symmetries(curves, currents, nfp, True))
    bs.set_points(np.ascontiguousarray(points))
    return np.array(bs.B())


def export(name: str, seed: int) -> dict:
    curves, currents, ma, nfp, bs = get_data(name)
    axis, axis_simsopt = aligned_axis(ma, bs)
    pts = check_points(axis, seed)
    B = biot_savart_B(curves, currents, nfp, pts)
    # simsopt's quadrature error at the check points: 4× the points per period
    ppp = len(curves[0].quadpoints) // curves[0].order
    fine, fine_currents, *_ = get_data(name, points_per_period=4 * ppp)
    B_fine = biot_savart_B(fine, fine_currents, nfp, pts)
    quad_err = float(np.max(np.linalg.norm(B - B_fine, axis=1)) / np.max(np.linalg.norm(B_fine, axis=1)))
    a0 = axis_curve(axis["rc"], axis["zs"], axis["nfp"]).gamma()[0]
    n_quad = {len(c.quadpoints) for c in curves}
    if len(n_quad) != 1:
        raise RuntimeError(f"{name}: the base curves have different quadrature counts {n_quad}")
    return {
        "name": name,
        "nfp": int(nfp),
        "stellsym": True,
        "curve_formula": "x_i(θ) = cos[i][0] + Σ_{m=1}^{order} (cos[i][m] cos 2πmθ + sin[i][m−1] sin 2πmθ), "
                         "i = x, y, z (m), θ ∈ [0, 1); quadrature points θ_k = k/n_quadpoints",
        "n_quadpoints": n_quad.pop(),
        "base_currents": [float(c.get_value()) for c in currents],
        "base_curves": [curve_data(c) for c in curves],
        "axis_formula": "R(φ) = Σ_m rc[m] cos(m nfp φ), Z(φ) = Σ_{m≥1} zs[m−1] sin(m nfp φ) (m)",
        "axis": axis,
        "axis_simsopt": axis_simsopt,
        "check": {
            "what": "simsopt BiotSavart of coils_via_symmetries(curves, currents, nfp, True), Cartesian (T)",
            "points": pts.tolist(),
            "B": B.tolist(),
            "simsopt_quadrature_error": quad_err,
            "axis_R_Z_at_phi0": [float(np.hypot(a0[0], a0[1])), float(a0[2])],
        },
        "provenance": {
            "simsopt": simsopt.__version__,
            "function": f"simsopt.configs.get_data({name!r})",
            "script": "benchmarks/peers/make_devices.py",
            "date": datetime.date.today().isoformat(),
        },
    }


def write_makegrid_files(directory: Path) -> None:
    from vpforms.coils import device, write_makegrid  # the peer venv's vpforms (pip install -e .)

    directory.mkdir(parents=True, exist_ok=True)
    for name in DEVICES:
        coils = device(name)
        write_makegrid(coils, directory / f"coils.{name}")
        print(f"wrote {directory / f'coils.{name}'}: {coils}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=OUT, help="directory of the JSON files")
    ap.add_argument("--makegrid", type=Path, default=None, help="also write MAKEGRID coils.<name> files here")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for seed, name in enumerate(DEVICES):
        data = export(name, seed)
        path = args.out / f"{name}.json"
        path.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
        print(f"{path}: {path.stat().st_size / 1024:.0f} KiB, {len(data['base_curves'])} base curves, "
              f"nfp {data['nfp']}, axis {data['axis']['max_angle_deg']:.3f}° off B "
              f"(simsopt's {data['axis_simsopt']['max_angle_deg']:.1f}°), simsopt quadrature error "
              f"{data['check']['simsopt_quadrature_error']:.1e}")
    if args.makegrid is not None:
        write_makegrid_files(args.makegrid)


if __name__ == "__main__":
    main()

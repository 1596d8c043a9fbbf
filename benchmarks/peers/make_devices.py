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
* provenance: simsopt's version, the function called, the date;
* ``domain``, the default domain (``default_domain``): one field line started just inside the last
  closed flux surface (``DOMAIN[name]["lcfs"]`` outboard of the axis on the midplane of φ = 0) is
  traced with ``compute_fieldlines`` on the direct ``BiotSavart`` (tol 1e-10, 100 transits); its
  Poincaré points on 24 planes per period get the straight-field-line angle θ = ι·φ (φ accumulated
  along the line, θ = 0 at the start: stellarator symmetric), and R(θ, φ), Z(θ, φ) are fitted by least
  squares in VMEC's form (m ≤ 12, |n| ≤ 8); that surface is moved outward by ``margin`` along its
  in-plane normal and refitted. The file stores the coefficients, the margin, the fit errors, the
  lines beyond the surface that the domain holds (W7-X: the 5/5 island chain), and the smallest
  distance from the domain to every coil filament (those without current too), in the plane and
  in 3-D. ``--domains-only`` remakes only this entry of existing files.

``--makegrid DIR`` also writes each full device (the coils with current, vpforms' polylines at
simsopt's quadrature points, :func:`vpforms.coils.device`) as a MAKEGRID file ``DIR/coils.<name>``
with :func:`vpforms.coils.write_makegrid` (vpforms must be installed in this venv). Those files are
not committed.
"""

from __future__ import annotations

import argparse
import datetime
import json
import time
from pathlib import Path

import numpy as np
import simsopt
from simsopt.configs import get_data
from simsopt.field import BiotSavart, Current, compute_fieldlines
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


def axis_RZ(axis: dict, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axis (R, Z) at the angles φ (``axis_formula``)."""
    m = np.arange(len(axis["rc"]))
    return np.cos(np.outer(phi, m * axis["nfp"])) @ axis["rc"], np.sin(np.outer(phi, m[1:] * axis["nfp"])) @ axis["zs"]


def check_points(axis: dict, seed: int) -> np.ndarray:
    """N_CHECK Cartesian points near the axis: φ uniform in [0, 2π), minor radius ≤ 0.04 R_axis,
    poloidal angle uniform."""
    rng = np.random.default_rng(seed)
    phi = np.sort(rng.uniform(0, 2 * np.pi, N_CHECK))
    R, Z = axis_RZ(axis, phi)
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


# ------------------------------------------------------------------------------------------------
# The default domain: a VMEC-form boundary fitted to the last closed flux surface, offset outward
# ------------------------------------------------------------------------------------------------
#: per device (m, outboard of the axis on the midplane of φ = 0): ``lcfs`` the start of the line just
#: inside the last closed flux surface; ``contain`` the starts of lines beyond it (W7-X: the 5/5
#: island chain) whose points the domain must hold; ``margin`` the smallest outward offset (the one
#: used is at least the farthest contained point beyond the fitted surface plus CLEARANCE)
DOMAIN = {
    "w7x": {"lcfs": 0.24, "contain": (0.26, 0.27, 0.30), "margin": 0.15},
    "ncsx": {"lcfs": 0.075, "contain": (), "margin": 0.05},
    "hsx": {"lcfs": 0.07, "contain": (), "margin": 0.02},
}
CLEARANCE = 0.02       # m between the contained lines and the domain's boundary
PLANES = 24            # φ-planes per field period where the Poincaré points are collected
TRANSITS = 100         # toroidal transits of each traced line
TOL = 1e-10            # compute_fieldlines' tolerance (direct BiotSavart)
MPOL, NTOR = 12, 8     # the boundary's modes: m = 0 … MPOL, n/nfp = −NTOR … NTOR
N_POLY = 2048          # vertices of the boundary polygon on a plane (distances)


def trace_sections(bs, nfp: int, R_starts, transits: float = TRANSITS, tol: float = TOL):
    """Poincaré points of field lines started at (R, φ = 0, Z = 0) on the PLANES·nfp planes
    φ = k·2π/(PLANES·nfp): per line, in the order the line meets them, the accumulated toroidal
    angle φ_t (unwrapped, from 0), R and Z; and the wall-clock seconds of simsopt's tracing."""
    R0 = float(R_starts[0])
    bs.set_points(np.array([[R0, 0.0, 0.0]]))
    tmax = transits * 2 * np.pi * R0 / float(np.linalg.norm(bs.B()))  # dx/dt = B: |B| t is the length
    phis = list(2 * np.pi * np.arange(PLANES * nfp) / (PLANES * nfp))
    t = time.perf_counter()
    _, hits = compute_fieldlines(bs, list(R_starts), [0.0] * len(R_starts), tmax=tmax, tol=tol, phis=phis)
    seconds = time.perf_counter() - t
    out = []
    for h in hits:
        h = h[h[:, 1] >= 0]
        phi = np.unwrap(np.r_[0.0, np.asarray(phis)[h[:, 1].astype(int)]])[1:]
        out.append((phi, np.hypot(h[:, 2], h[:, 3]), h[:, 4]))
    return out, seconds


def field_line_angle(phi, R, Z, axis: dict) -> tuple[np.ndarray, float]:
    """(θ, ι): the straight-field-line (PEST) poloidal angle θ = ι·φ_t of the points of one line on
    a flux surface (φ_t its accumulated toroidal angle, θ = 0 at the start on the outboard midplane
    of φ = 0: stellarator symmetric), and the rotational transform ι. ι is first the winding of the
    line about the axis over φ_t (error ≲ π/|φ_t|), then the value within ±0.02 of it (steps 1e-6)
    that orders the points of the plane φ = 0 into the shortest closed polygon: a wrong ι by δ
    displaces the k-th point by δ·φ_t in θ and scrambles the order once that passes the spacing."""
    Ra, Za = axis_RZ(axis, phi)
    winding = np.unwrap(np.arctan2(Z - Za, R - Ra))
    iota0 = (winding[-1] - winding[0]) / (phi[-1] - phi[0])
    period = 2 * np.pi / axis["nfp"]
    on0 = np.abs(np.remainder(phi + 0.5 * period, period) - 0.5 * period) < 1e-9
    p0, r0, z0 = phi[on0], R[on0], Z[on0]

    def perimeter(iota):
        k = np.argsort(np.remainder(iota * p0, 2 * np.pi))
        return np.sum(np.hypot(np.diff(r0[k], append=r0[k[0]]), np.diff(z0[k], append=z0[k[0]])))

    iotas = iota0 + np.arange(-0.02, 0.02, 1e-5)
    best = iotas[np.argmin([perimeter(i) for i in iotas])]
    fine = best + np.arange(-1e-5, 1e-5, 1e-7)
    iota = float(fine[np.argmin([perimeter(i) for i in fine])])
    return iota * phi, iota


def modes(nfp: int, mpol: int = MPOL, ntor: int = NTOR) -> tuple[np.ndarray, np.ndarray]:
    """VMEC's mode list (xm, xn): m = 0 with n = 0 … ntor, m ≥ 1 with n = −ntor … ntor; xn = n·nfp."""
    mn = [(0, n) for n in range(ntor + 1)] + [(m, n) for m in range(1, mpol + 1) for n in range(-ntor, ntor + 1)]
    xm, n = np.array(mn).T
    return xm.astype(float), (n * nfp).astype(float)


def fourier_RZ(coeffs, theta, phi, derivative: bool = False):
    """R, Z of the boundary R = Σ rmnc cos(mθ − nφ), Z = Σ zmns sin(mθ − nφ) at θ, φ (broadcast);
    with ``derivative`` also ∂R/∂θ, ∂Z/∂θ."""
    rmnc, zmns, xm, xn = coeffs
    ang = np.multiply.outer(theta, xm) - np.multiply.outer(phi, xn)
    c, s = np.cos(ang), np.sin(ang)
    R, Z = c @ rmnc, s @ zmns
    return (R, Z, -(s * xm) @ rmnc, (c * xm) @ zmns) if derivative else (R, Z)


def fit_boundary(theta, phi, R, Z, nfp: int) -> tuple:
    """Least-squares VMEC coefficients (rmnc, zmns, xm, xn) of R(θ, φ), Z(θ, φ) at the points."""
    xm, xn = modes(nfp)
    ang = np.multiply.outer(theta, xm) - np.multiply.outer(phi, xn)
    rmnc = np.linalg.lstsq(np.cos(ang), R, rcond=None)[0]
    zs = np.linalg.lstsq(np.sin(ang[:, 1:]), Z, rcond=None)[0]  # (0, 0) has no sine
    return rmnc, np.r_[0.0, zs], xm, xn


def polygon_distance(R, Z, PR, PZ) -> np.ndarray:
    """Signed distance (negative inside, even-odd rule) of points (R, Z) (k,) to the closed polygons
    (PR, PZ) (k, N) (one polygon per point; vertices open)."""
    aR, aZ = PR, PZ
    bR, bZ = np.roll(PR, -1, axis=-1), np.roll(PZ, -1, axis=-1)
    dR, dZ = bR - aR, bZ - aZ
    t = np.clip(((R[:, None] - aR) * dR + (Z[:, None] - aZ) * dZ) / (dR ** 2 + dZ ** 2), 0, 1)
    d = np.hypot(aR + t * dR - R[:, None], aZ + t * dZ - Z[:, None]).min(axis=1)
    crosses = ((aZ > Z[:, None]) != (bZ > Z[:, None])) & (
        R[:, None] < aR + (Z[:, None] - aZ) * dR / np.where(dZ == 0, 1, dZ))
    return np.where(crosses.sum(axis=1) % 2 == 1, -d, d)


def boundary_distance(coeffs, R, phi, Z, chunk: int = 200) -> np.ndarray:
    """In-plane signed distance of points (R, φ, Z) to the boundary at their φ (polygon of N_POLY
    vertices: inside the exact curve by ≤ (perimeter/N_POLY)²·curvature/8)."""
    rmnc, zmns, xm, xn = coeffs
    th = 2 * np.pi * np.arange(N_POLY) / N_POLY
    cm, sm = np.cos(np.outer(xm, th)), np.sin(np.outer(xm, th))  # cos(mθ − nφ) = cos mθ cos nφ + sin mθ sin nφ
    out = np.empty(R.shape)
    for lo in range(0, R.size, chunk):
        sl = slice(lo, lo + chunk)
        cn, sn = np.cos(np.outer(phi[sl], xn)), np.sin(np.outer(phi[sl], xn))
        PR = (cn * rmnc) @ cm + (sn * rmnc) @ sm
        PZ = (cn * zmns) @ sm - (sn * zmns) @ cm
        out[sl] = polygon_distance(R[sl], Z[sl], PR, PZ)
    return out


def offset_boundary(coeffs, margin: float, nfp: int) -> tuple[tuple, float]:
    """The boundary moved outward by ``margin`` along its in-plane normal (R, Z) → (R, Z) + margin·n̂,
    n̂ = (∂Z/∂θ, −∂R/∂θ)/|·| (θ counter-clockwise), refitted with the same modes on a 256 × 4·PLANES
    grid of one period; and the largest distance of that grid's offset points to the refitted surface."""
    th, ph = np.meshgrid(2 * np.pi * np.arange(256) / 256, 2 * np.pi / nfp * np.arange(4 * PLANES) / (4 * PLANES))
    R, Z, Rt, Zt = fourier_RZ(coeffs, th.ravel(), ph.ravel(), derivative=True)
    norm = np.hypot(Rt, Zt)
    R, Z = R + margin * Zt / norm, Z - margin * Rt / norm
    new = fit_boundary(th.ravel(), ph.ravel(), R, Z, nfp)
    return new, float(np.abs(boundary_distance(new, R, ph.ravel(), Z)).max())


def all_coil_points(name: str, per_coil: int) -> np.ndarray:
    """Cartesian points of every coil filament of the device — the coils without current too (W7-X's
    planar coils) — ``per_coil`` points per coil, (n, 3)."""
    curves, _, _, nfp, _ = get_data(name)
    fine = get_data(name, points_per_period=per_coil // curves[0].order)[0]
    if len(fine[0].quadpoints) != per_coil:
        raise RuntimeError(f"{name}: asked for {per_coil} points per coil, got {len(fine[0].quadpoints)}")
    coils = coils_via_symmetries(fine, [Current(1.0) for _ in fine], nfp, True)
    return np.concatenate([c.curve.gamma() for c in coils])


def distance_3d(coeffs, nfp: int, xyz: np.ndarray) -> float:
    """Smallest 3-D distance between the coil points and the boundary surface (512 θ × 256 φ per
    period, all periods; the point sampling overestimates it by ≤ half the grid spacing)."""
    from scipy.spatial import cKDTree

    th = 2 * np.pi * np.arange(512) / 512
    rows = []
    for ph in np.array_split(2 * np.pi * np.arange(256 * nfp) / (256 * nfp), 4 * nfp):  # bounded memory
        R, Z = fourier_RZ(coeffs, th[None, :], ph[:, None])
        rows.append(np.stack([R * np.cos(ph)[:, None], R * np.sin(ph)[:, None], Z], axis=-1).reshape(-1, 3))
    return float(cKDTree(np.concatenate(rows)).query(xyz)[0].min())


def default_domain(name: str, bs, axis: dict) -> dict:
    """The device's default domain (module docstring): trace, fit, offset, measure."""
    spec, nfp = DOMAIN[name], int(axis["nfp"])
    R0 = float(axis_RZ(axis, np.zeros(1))[0][0])
    starts = [R0 + spec["lcfs"]] + [R0 + d for d in spec["contain"]]
    lines, seconds = trace_sections(bs, nfp, starts)
    phi_t, R, Z = lines[0]
    theta, iota = field_line_angle(phi_t, R, Z, axis)
    phi = np.remainder(phi_t, 2 * np.pi / nfp)
    lcfs = fit_boundary(theta, phi, R, Z, nfp)
    fit_error = float(np.abs(boundary_distance(lcfs, R, phi, Z)).max())
    beyond = [float(boundary_distance(lcfs, pr, np.remainder(pt, 2 * np.pi / nfp), pz).max()) for pt, pr, pz in lines[1:]]
    # the margin: the device's, or the farthest contained point beyond the surface + CLEARANCE, in cm
    margin = max(spec["margin"], float(np.ceil((max(beyond, default=0.0) + CLEARANCE) * 100) / 100))
    coeffs, offset_error = offset_boundary(lcfs, margin, nfp)
    coeffs = tuple(np.round(c, 10) for c in coeffs[:2]) + coeffs[2:]
    outside = [(b, float(boundary_distance(coeffs, pr, np.remainder(pt, 2 * np.pi / nfp), pz).max()))
               for b, (pt, pr, pz) in zip(beyond, lines[1:])]
    per_coil = 4 * len(get_data(name)[0][0].quadpoints)
    xyz = all_coil_points(name, per_coil)
    d_plane = boundary_distance(coeffs, np.hypot(xyz[:, 0], xyz[:, 1]), np.arctan2(xyz[:, 1], xyz[:, 0]), xyz[:, 2])
    d3 = distance_3d(coeffs, nfp, xyz)
    lcfs_d3 = distance_3d(lcfs, nfp, xyz)
    print(f"{name}: {len(starts)} lines × {TRANSITS} transits traced in {seconds:.1f} s; LCFS fit error "
          f"{fit_error:.2e} m over {R.size} points; lines beyond it up to {max([o[0] for o in outside], default=0):.3f} m "
          f"outside, {max([o[1] for o in outside], default=-1):.3f} m from the domain; margin {margin} m "
          f"(refit {offset_error:.1e} m); coils {d_plane.min():.3f} m "
          f"in-plane / {d3:.3f} m 3-D from the domain ({lcfs_d3:.3f} m 3-D from the LCFS fit)")
    if d_plane.min() <= 0 or d3 <= 0:
        raise RuntimeError(f"{name}: a coil filament is inside the domain")
    if any(o[1] >= 0 for o in outside):
        raise RuntimeError(f"{name}: a line of contained_lines leaves the domain: {outside}")
    return {
        "formula": "R(θ, φ) = Σ_k rmnc[k] cos(xm[k] θ − xn[k] φ), Z(θ, φ) = Σ_k zmns[k] sin(xm[k] θ − xn[k] φ) (m), "
                   "xn including nfp (VMEC's convention); vpforms.coils.device_domain",
        "rmnc": coeffs[0].tolist(), "zmns": coeffs[1].tolist(),
        "xm": coeffs[2].astype(int).tolist(), "xn": coeffs[3].astype(int).tolist(), "nfp": nfp,
        "margin_m": margin,
        "how": (f"simsopt compute_fieldlines on the direct BiotSavart (tol {TOL:g}, {TRANSITS} transits) from "
                f"(R_axis + {spec['lcfs']} m, φ = 0, Z = 0), just inside the last closed flux surface; its Poincaré "
                f"points on {PLANES} planes per period (periods folded), θ = ι·φ its straight-field-line angle (ι: "
                f"the value that orders the points of φ = 0 into the shortest polygon); least-squares fit "
                f"m ≤ {MPOL}, |n| ≤ {NTOR}; offset outward by margin_m along the in-plane normal and refitted"),
        "lcfs_start_offset_m": spec["lcfs"],
        "lcfs_fit_error_m": fit_error,
        "offset_refit_error_m": offset_error,
        "contained_lines": [{"start_offset_m": d, "max_outside_lcfs_fit_m": o[0], "max_signed_distance_m": o[1]} for d, o in zip(spec["contain"], outside)],
        "coil_points_per_coil": per_coil,
        "min_distance_to_coils_m": float(d_plane.min()),
        "min_distance_to_coils_3d_m": d3,
        "distance_note": "min_distance_to_coils_m: in-plane distance (the domain's signed distance at the coil point's φ) "
                         "over every coil filament, those without current too, at coil_points_per_coil points per coil; "
                         "_3d_m: the 3-D distance between those points and the surface",
        "tracing_seconds": round(seconds, 1),
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
    ap.add_argument("--devices", nargs="+", choices=DEVICES, default=DEVICES, help="only these devices")
    ap.add_argument("--domains-only", action="store_true",
                    help="keep the files' coil data, (re)make only their default domain")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for seed, name in enumerate(DEVICES):
        if name not in args.devices:
            continue
        path = args.out / f"{name}.json"
        data = json.loads(path.read_text()) if args.domains_only else export(name, seed)
        data["domain"] = default_domain(name, get_data(name)[4], data["axis"])
        path.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
        print(f"{path}: {path.stat().st_size / 1024:.0f} KiB, {len(data['base_curves'])} base curves, "
              f"nfp {data['nfp']}, axis {data['axis']['max_angle_deg']:.3f}° off B "
              f"(simsopt's {data['axis_simsopt']['max_angle_deg']:.1f}°), simsopt quadrature error "
              f"{data['check']['simsopt_quadrature_error']:.1e}")

if __name__ == "__main__":
    main()

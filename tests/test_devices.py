"""Real stellarators by name (vpforms.coils.devices, issue #38): W7-X, NCSX, HSX from simsopt's data.

The reference is simsopt's own ``BiotSavart`` B of the full coil set, stored in each data file by
``benchmarks/peers/make_devices.py`` (simsopt's quadrature error there ≤ 8e-7, also stored). vpforms
sums the exact fields of straight segments between the curve's points, so its B converges to the
smooth curve's as O(1/n²): the tests measure that rate, not a pasted tolerance.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import jax

from vpforms.coils import CoilSet, device, device_axis, device_data, device_names
from vpforms.coils.devices import curve_points, curve_tangents

DEVICES = device_names()


def _check(name):
    c = device_data(name)["check"]
    return np.array(c["points"]), np.array(c["B"]), c["simsopt_quadrature_error"]


def _rel_diff(B, B_ref) -> float:
    return float(np.max(np.linalg.norm(B - B_ref, axis=1)) / np.max(np.linalg.norm(B_ref, axis=1)))


@pytest.mark.parametrize("name", DEVICES)
def test_B_converges_to_simsopt_at_second_order(name):
    """max |B_vpforms − B_simsopt| / max |B| at the 20 stored points for n, 2n, 4n, 8n points per coil:
    each doubling divides it by ≈ 4 (log-log slope −2 over three steps), and at 8n it is < 1e-4."""
    pts, B_ref, quad_err = _check(name)
    n0 = device_data(name)["n_quadpoints"]
    ns = [n0, 2 * n0, 4 * n0, 8 * n0]
    errs = [_rel_diff(np.asarray(device(name, n).B(pts)), B_ref) for n in ns]
    slopes = np.diff(np.log(errs)) / np.diff(np.log(ns))
    assert np.all((slopes > -2.2) & (slopes < -1.8)), (name, errs, slopes)
    assert errs[-1] < 1e-4, (name, errs)
    assert errs[-1] > 10 * quad_err  # the polyline's error, not simsopt's, is what was measured


@pytest.mark.parametrize("name", DEVICES)
def test_quadrature_rule_is_simsopts_biot_savart(name):
    """rule="quadrature" sums simsopt's own current elements: at the 20 stored points its B equals the
    B simsopt computed to rounding (far below the polyline's O(1/n²) difference, which the test
    above measures), and B = ∇×A at a point (jacfwd of A)."""
    pts, B_ref, _ = _check(name)
    coils = device(name, rule="quadrature")
    assert _rel_diff(np.asarray(coils.B(pts)), B_ref) < 1e-13
    assert _rel_diff(np.asarray(device(name).B(pts)), B_ref) > 1e-6  # the polyline's is another field
    J = np.asarray(jax.jacfwd(coils.A)(pts[0]))
    curl = np.array([J[2, 1] - J[1, 2], J[0, 2] - J[2, 0], J[1, 0] - J[0, 1]])
    np.testing.assert_allclose(curl, np.asarray(coils.B(pts[0])), rtol=0, atol=1e-13 * np.abs(B_ref).max())


def test_curve_tangents_are_the_derivative_of_the_points():
    """curve_tangents(c, n)[k] = dγ/dθ at θ_k = k/n: the five-point difference of γ at θ_k ± δ, ± 2δ,
    γ summed from its Fourier series (the device file's formula) at those θ."""
    curve = device_data("hsx")["base_curves"][0]
    cos, sin = np.asarray(curve["cos"], float), np.asarray(curve["sin"], float)
    m = np.arange(cos.shape[1])

    def gamma(theta):
        a = 2 * np.pi * np.outer(m, theta)
        return (cos @ np.cos(a) + sin @ np.sin(a[1:])).T

    n, d = 16, 2e-4
    th = np.arange(n) / n
    np.testing.assert_allclose(curve_points(curve, n), gamma(th), rtol=0, atol=1e-14)
    fd = (-gamma(th + 2 * d) + 8 * gamma(th + d) - 8 * gamma(th - d) + gamma(th - 2 * d)) / (12 * d)
    np.testing.assert_allclose(curve_tangents(curve, n), fd, rtol=0, atol=1e-9 * np.abs(fd).max())


def test_quadrature_bad_rule():
    with pytest.raises(ValueError, match="rule must be 'polyline' or 'quadrature'"):
        device("hsx", rule="spline")


def _cylindrical_B(coils: CoilSet, R, phi, Z) -> np.ndarray:
    """(B_R, B_φ, B_Z) of the coils at the cylindrical points, shape (N, 3)."""
    B = np.asarray(coils.B(np.c_[R * np.cos(phi), R * np.sin(phi), Z]))
    c, s = np.cos(phi), np.sin(phi)
    return np.c_[B[:, 0] * c + B[:, 1] * s, -B[:, 0] * s + B[:, 1] * c, B[:, 2]]


@pytest.mark.parametrize("name", DEVICES)
def test_field_periodicity_and_stellarator_symmetry(name):
    """B of vpforms' coils: invariant under φ → φ + 2π/nfp; under (R, φ, Z) → (R, −φ, −Z) B_R is odd,
    B_φ and B_Z are even (rounding only)."""
    coils = device(name)
    axis = device_axis(name)
    rng = np.random.default_rng(7)
    phi = rng.uniform(0, 2 * np.pi, 12)
    R0, Z0 = axis(phi)
    r = 0.05 * axis.rc[0] * rng.uniform(0, 1, 12)
    al = rng.uniform(0, 2 * np.pi, 12)
    R, Z = R0 + r * np.cos(al), Z0 + r * np.sin(al)
    B = _cylindrical_B(coils, R, phi, Z)
    scale = np.max(np.abs(B))
    rotated = _cylindrical_B(coils, R, phi + 2 * np.pi / coils.nfp, Z)
    assert np.max(np.abs(rotated - B)) < 1e-12 * scale
    mirrored = _cylindrical_B(coils, R, -phi, -Z)
    assert np.max(np.abs(mirrored * [-1, 1, 1] - B)) < 1e-12 * scale
    assert np.max(np.abs(mirrored[:, 0] - B[:, 0])) > 1e-3 * scale  # B_R really is odd, not zero


@pytest.mark.parametrize("name", DEVICES)
def test_axis_is_closed_and_follows_B(name):
    """The axis closes after one field period and after 2π, sits at simsopt's (R, Z) on φ = 0, and is
    a field line of vpforms' coils: the angle between B and its tangent stays below 0.2°."""
    axis = device_axis(name)
    period = 2 * np.pi / axis.nfp
    phi = np.linspace(0, 2 * np.pi, 41)
    np.testing.assert_allclose(np.c_[axis(phi)], np.c_[axis(phi + period)], atol=1e-12)
    np.testing.assert_allclose(axis.xyz(0.0), axis.xyz(2 * np.pi), atol=1e-12)
    np.testing.assert_allclose(axis(0.0), device_data(name)["check"]["axis_R_Z_at_phi0"], atol=1e-12)
    h = 1e-6
    tangent = (axis.xyz(phi + h) - axis.xyz(phi - h)) / (2 * h)
    B = np.asarray(device(name).B(axis.xyz(phi)))
    cos = np.abs(np.sum(B * tangent, 1)) / (np.linalg.norm(B, axis=1) * np.linalg.norm(tangent, axis=1))
    assert np.degrees(np.arccos(min(cos.min(), 1.0))) < 0.2


def test_device_structure_and_currents():
    """W7-X: 5 non-planar coils with current × 5 periods × 2 (mirror) = 50 coils; giving the planar
    coils a current adds them (70 coils); B is linear in the currents."""
    data = device_data("W7-X")
    coils = device("w7x", 24)
    assert (len(coils), coils.nfp, coils.stellsym) == (50, 5, True)
    assert {c.group for c in coils} == {1, 2, 3, 4, 5}
    cur = np.array(data["base_currents"])
    both = device("w7x", 24, currents=np.r_[cur[:5], 0.1 * cur[0], -0.1 * cur[0]])
    assert len(both) == 70
    doubled = device("w7x", 24, currents=2 * cur)
    x = np.array([[5.9, 0.1, 0.05], [5.5, 0.5, -0.1]])
    np.testing.assert_allclose(np.asarray(doubled.B(x)), 2 * np.asarray(coils.B(x)), rtol=1e-13)


@pytest.mark.parametrize("bad, match", [
    (dict(name="lhd"), "unknown device 'lhd'; known devices: w7x, ncsx, hsx"),
    (dict(name=None), "unknown device None"),
    (dict(name="w7x", n_points=2), "n_points must be an integer ≥ 3"),
    (dict(name="w7x", n_points=96.0), "n_points must be an integer ≥ 3"),
    (dict(name="ncsx", currents=[1.0, 2.0]), "ncsx: currents must be a sequence of 3"),
    (dict(name="ncsx", currents=[1.0, np.nan, 2.0]), "ncsx base current 1 must be finite"),
    (dict(name="hsx", currents=[0.0] * 6), "hsx: every base coil has zero current"),
])
def test_bad_input(bad, match):
    with pytest.raises(ValueError, match=match.replace("(", r"\(")):
        device(**bad)


def test_bad_axis_name():
    with pytest.raises(ValueError, match="known devices: w7x, ncsx, hsx"):
        device_axis("W7-AS")


def test_data_files_are_package_data():
    """The JSON files ship with the package: pyproject's package-data names them and each is small."""
    root = Path(__file__).resolve().parents[1]
    config = tomllib.loads((root / "pyproject.toml").read_text())
    assert "data/*.json" in config["tool"]["setuptools"]["package-data"]["vpforms.coils"]
    for name in DEVICES:
        path = root / "src" / "vpforms" / "coils" / "data" / f"{name}.json"
        assert path.stat().st_size < 100_000
        assert device_data(name)["provenance"]["function"] == f"simsopt.configs.get_data({name!r})"


def test_device_problems_are_registered_lazily():
    """The three devices are coil problems; an unknown device is one clear error."""
    from vpforms import problems
    from vpforms.problems import devices as device_problems

    assert {"w7x", "ncsx", "hsx"} <= set(problems.coil_names())
    assert set(problems.coil_names()).isdisjoint(problems.names())
    with pytest.raises(ValueError, match="known devices: w7x, ncsx, hsx"):
        device_problems.make("lhd")


@pytest.mark.slow
def test_w7x_problem_traces_the_coils_directly():
    """problems.get("w7x"): the field in (u, φ, Z) is the coils' B (converted back to Cartesian, to
    rounding), its starting points lie on the outboard midplane inside the box, the axis guess is the
    axis on φ = 0, and φ has the field period."""
    from vpforms import problems
    from vpforms.toroidal import cartesian_field, from_toroidal

    p = problems.get("w7x")
    x = p.initial_conditions(4, seed=1)
    coils = device("w7x")
    B = np.asarray(cartesian_field(p.field(x), x))
    np.testing.assert_allclose(B, np.asarray(coils.B(from_toroidal(x))), atol=1e-12 * np.abs(B).max())
    assert p.axis_guess == pytest.approx(tuple(device_axis("w7x")(0.0)), abs=1e-12)
    assert p.periodic == (None, pytest.approx(2 * np.pi / 5), None)
    from vpforms.coils import device_domain

    assert p.domain is device_domain("w7x")
    p.domain.check_within(np.sqrt(2 * np.asarray(p.box[0])), p.box[2], what="the problem's box")
    for pts in (p.x0, x):
        R = np.sqrt(2 * pts[:, 0])
        assert np.all(pts[:, 1:] == 0) and np.all(R > p.axis_guess[0])
        assert np.all((pts[:, 0] > p.box[0][0]) & (pts[:, 0] < p.box[0][1]))
        assert p.domain.contains(np.c_[R, pts[:, 1], pts[:, 2]]).all()


# ------------------------------------------------------------------------------------------------
# The default domains (issue #38 item 3): a VMEC-form boundary that follows the plasma
# ------------------------------------------------------------------------------------------------
def _cylindrical(xyz: np.ndarray) -> np.ndarray:
    return np.c_[np.hypot(xyz[:, 0], xyz[:, 1]), np.arctan2(xyz[:, 1], xyz[:, 0]), xyz[:, 2]]


@pytest.mark.parametrize("name", DEVICES)
def test_domain_holds_the_axis_and_the_start_points(name):
    """The axis at 24 angles over the whole torus and the sampler's outermost start point
    (R_axis + 0.95·edge, φ = 0, Z = 0) are inside the default domain, with room: their signed
    distance is negative by more than the polygons' own error."""
    from vpforms.coils import device_domain
    from vpforms.problems.devices import EDGE

    dom = device_domain(name)
    axis = device_axis(name)
    phi = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    R, Z = axis(phi)
    R0 = float(axis(0.0)[0])
    pts = np.r_[np.c_[R, phi, Z], [[R0 + 0.95 * EDGE[name], 0.0, 0.0]]]
    assert dom.contains(pts).all()
    assert np.asarray(dom.signed_distance(pts[:, 0], pts[:, 1], pts[:, 2])).max() < -dom.fourier_error()


@pytest.mark.parametrize("name", DEVICES)
def test_domain_is_stellarator_symmetric(name):
    """(R, φ, Z) is inside exactly when (R, −φ, −Z) is, at 2 000 points of the domain's (R, Z)
    bounds (both answers occur)."""
    from vpforms.coils import device_domain

    dom = device_domain(name)
    rng = np.random.default_rng(3)
    r0, r1, z0, z1 = dom.bounds
    p = np.c_[rng.uniform(r0, r1, 2000), rng.uniform(0, 2 * np.pi, 2000), rng.uniform(z0, z1, 2000)]
    d = np.asarray(dom.signed_distance(p[:, 0], p[:, 1], p[:, 2]))
    mirrored = np.asarray(dom.signed_distance(p[:, 0], -p[:, 1], -p[:, 2]))
    clear = np.abs(d) > 2 * dom.fourier_error()  # points closer to the boundary than its own error may flip
    assert (d[clear] < 0).any() and (d[clear] > 0).any()
    np.testing.assert_array_equal(d[clear] < 0, mirrored[clear] < 0)


@pytest.mark.parametrize("name", DEVICES)
def test_coil_filaments_lie_outside_the_domain_at_the_stored_distance(name):
    """Every coil filament point — the coils without current too (W7-X's planar coils), at the points
    per coil the export script used — is outside the default domain, and the smallest in-plane
    distance vpforms' signed_distance finds is the one simsopt's side stored, within the
    polygon's discretisation error (the domain's fourier_error plus the export's 2048-vertex one)."""
    from vpforms.coils import device_domain

    data = device_data(name)
    stored = data["domain"]
    dom = device_domain(name)
    everything = device(name, stored["coil_points_per_coil"], currents=[1.0] * len(data["base_curves"]))
    pts = _cylindrical(np.concatenate([c.points for c in everything]))
    assert not dom.contains(pts).any()
    d = np.asarray(dom.signed_distance(pts[:, 0], pts[:, 1], pts[:, 2]))
    tol = dom.fourier_error(n_check=5000) + 1e-4
    assert abs(d.min() - stored["min_distance_to_coils_m"]) < tol, (d.min(), stored["min_distance_to_coils_m"], tol)
    assert d.min() >= (0.1 if name == "w7x" else 0.05)
    assert stored["min_distance_to_coils_3d_m"] <= stored["min_distance_to_coils_m"] + tol


@pytest.mark.parametrize("name", DEVICES)
def test_domain_fits_the_problem_box(name):
    """The problem's (u, φ, Z) box, read back as R = √(2u), holds the default domain; the domain
    is smaller than the box on every side (by BOX_MARGIN of its R extent)."""
    from vpforms.coils import device_domain
    from vpforms.problems.devices import _box

    dom = device_domain(name)
    box = _box(name, dom.nfp)
    R_range, Z_range = np.sqrt(2 * np.asarray(box[0])), box[2]
    dom.check_within(R_range, Z_range, what=f"{name}'s box")
    r0, r1, z0, z1 = dom.bounds
    assert R_range[0] < r0 and R_range[1] > r1 and Z_range[0] < z0 and Z_range[1] > z1
    with pytest.raises(ValueError, match="leaves the inner box"):
        dom.check_within((r0 + 0.01, r1), Z_range, what="the inner box")

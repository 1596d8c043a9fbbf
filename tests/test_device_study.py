"""vpforms on real stellarators (issue #38 item 4): the device grids and ``vpforms fieldlines --device``."""

from __future__ import annotations

import numpy as np
import pytest

from vpforms.cli import main


@pytest.mark.parametrize("argv, needle", [
    (["--device", "lhd"], "--device 'lhd': known devices are w7x, ncsx, hsx"),
    (["--device", "w7x", "--coils", "x.coils"], "give one of --coils, --mgrid and --device, not two"),
    (["--device", "w7x", "--problem", "coil_tokamak"], "with --coils/--mgrid/--device"),
    (["--device", "w7x", "--R", "5,6"], "without --coils"),
    (["--grid", "8x8x8"], "without --coils or --device"),
])
def test_device_arguments_are_one_clean_line(argv, needle, capsys, tmp_path):
    assert main(["fieldlines", *argv, "--png", str(tmp_path / "a.png"), "--iota-png", str(tmp_path / "b.png"),
                 "--csv", str(tmp_path / "c.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error: ") and needle in err[0], err


def test_domain_mask_keeps_whole_phi_lines_clear_of_the_wires():
    """The grid that follows a domain keeps every node of the dilated cells that meet it and the
    whole φ line through each, except nodes nearer a wire than the nearest of those cells' nodes
    (computed here with the wires' own points, brute force)."""
    from vpforms.coils import Coil, CoilSet
    from vpforms.domains import ToroidalDomain
    from vpforms.problems.coil_fields import _domain_mask, wire_points

    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    coils = CoilSet([Coil(np.c_[1.12 * np.cos(t), 1.12 * np.sin(t), 0 * t], 1e5)], nfp=4)
    dom = ToroidalDomain.tube(lambda p: (1.25 + 0.05 * np.cos(4 * p), 0 * p), 0.05, nfp=4, n_phi=8)
    R, phi, Z = np.linspace(1.0, 1.4, 21), 2 * np.pi / 4 * np.arange(12) / 12, np.linspace(-0.2, 0.2, 21)
    keep = _domain_mask(coils, dom, R, phi, Z, 2, None, "ring")
    near = dom.node_mask(R, phi, Z, pad=2)
    RR, PP, ZZ = np.meshgrid(R, phi, Z, indexing="ij")
    xyz = np.stack([RR * np.cos(PP), RR * np.sin(PP), ZZ], -1)
    w = wire_points(coils, 0.005)
    d = np.min(np.linalg.norm(xyz[..., None, :] - w, axis=-1), axis=-1)
    clearance = d[near].min()
    assert np.all(keep[near])
    expect = near.any(axis=1, keepdims=True) & (d >= clearance - 0.005)  # wire points 5 mm apart
    assert np.all(keep <= expect) and np.all(keep >= near.any(axis=1, keepdims=True) & (d >= clearance + 0.005))
    assert keep.sum() > near.sum()  # whole φ lines add nodes
    with pytest.raises(ValueError, match="clearance must be a distance ≥ 0"):
        _domain_mask(coils, dom, R, phi, Z, 2, -1.0, "ring")
    with pytest.raises(ValueError, match="a coil wire lies within clearance"):
        _domain_mask(coils, dom, R, phi, Z, 2, 10 * clearance, "ring")


@pytest.mark.slow  # a W7-X grid (~40 s), the method, the axis search, 3 lines × 5 transits
def test_w7x_study_from_the_command_line(tmp_path, capsys):
    """``vpforms fieldlines --device w7x``: the axis found on φ = 0 lies within 1 cm of the device's
    stored axis, |ι| there is W7-X's (0.85–0.87: ι ≈ 0.858 on the axis), no line fails, none
    leaves the domain, and the section's points lie inside the domain."""
    import csv

    from vpforms.coils import device_axis, device_domain

    png, ipng, out = tmp_path / "s.png", tmp_path / "i.png", tmp_path / "s.csv"
    lpng, lcsv = tmp_path / "lc.png", tmp_path / "lc.csv"
    assert main(["fieldlines", "--device", "w7x", "--grid", "32x48x32", "--lines", "3", "--transits", "5",
                 "--png", str(png), "--iota-png", str(ipng), "--csv", str(out), "--quiet",
                 "--wall", "divertor", "--connection-length", "40", "--lc-depth", "0.08", "--lc-transits", "2",
                 "--lc-png", str(lpng), "--lc-csv", str(lcsv)]) == 0
    text = capsys.readouterr().out
    assert png.stat().st_size > 0 and ipng.stat().st_size > 0
    rows = list(csv.DictReader(out.open()))
    R, Z = np.array([float(r["R"]) for r in rows]), np.array([float(r["Z"]) for r in rows])
    assert len(R) > 3 * 4
    dom = device_domain("w7x")
    assert dom.contains(np.c_[R, np.zeros_like(R), Z]).all()
    R0, Z0 = device_axis("w7x")(0.0)
    line = next(ln for ln in text.splitlines() if "magnetic axis (R, Z)" in ln)
    Ra = float(line.split("(")[2].split(",")[0])
    assert abs(Ra - R0) < 0.01, (line, R0)
    iota = float(next(ln for ln in text.splitlines() if "ι on the axis" in ln).split("│")[2].split()[0])
    assert 0.85 < abs(iota) < 0.87, iota
    failed = next(ln for ln in text.splitlines() if "failed lines" in ln).split("│")[2].strip()
    assert failed == "0", failed
    # the connection-length map to the divertor-like wall: starts within 0.08 m inside it, exits on it
    # (in-plane distance ≤ 1e-9 m at the exit's own φ), L = L_fwd + L_bwd where both ways reached it
    from vpforms.problems.devices import divertor_wall

    wall = divertor_wall("w7x")
    lc = np.genfromtxt(lcsv, delimiter=",", names=True)
    d0 = np.asarray(wall.signed_distance(lc["R0"], lc["phi0"], lc["Z0"]))
    assert lc.size > 30 and np.all((d0 < 0) & (d0 >= -0.08))
    for way in ("fwd", "bwd"):
        hit = lc[f"status_{way}"] == 0
        assert hit.any()
        d = np.asarray(wall.signed_distance(lc[f"exit_R_{way}"][hit], lc[f"exit_phi_{way}"][hit],
                                            lc[f"exit_Z_{way}"][hit]))
        assert np.abs(d).max() < 1e-9, np.abs(d).max()
    both = (lc["status_fwd"] == 0) & (lc["status_bwd"] == 0)
    np.testing.assert_allclose(lc["L"][both], lc["L_fwd"][both] + lc["L_bwd"][both], rtol=1e-15)
    assert lpng.stat().st_size > 20_000

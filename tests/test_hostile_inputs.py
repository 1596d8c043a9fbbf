"""Issue #41 item 4 ("errors where answers would be wrong") and issue #40 item 5 (the CLI writes what
was asked): hostile inputs get one clear error, never a silent NaN, a wrong number or a file of
another name.  The CLI tests run ``vpforms.cli.main`` with argv and read its real output; the
field-line tests use the exactly solvable twist method of ``tests/test_fieldlines.py`` (fast)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vpforms.cli import build_parser, main


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error: "), err
    return err[0]


# ------------------------------------------------------------------ negative numbers (issue #41)
def test_negative_numbers_in_comma_lists_parse():
    """argparse reads a token that starts with '-' as an option unless it is one plain number:
    ``--Z -0.2,0.2`` used to stop with "expected one argument"."""
    p = build_parser()
    a = p.parse_args(["fieldlines", "--coils", "c", "--R", "0.8,1.2", "--Z", "-0.2,0.2",
                      "--axis-guess", "0.98,-0.01", "--radii", "-0.05,0.05", "--island-range", "-1,1",
                      "--phi", "-1e-3", "--wall", "-1,-1,1,-1,1,1,-1,1,-1,-1"])
    assert a.Z == [-0.2, 0.2] and a.axis_guess == [0.98, -0.01] and a.radii == [-0.05, 0.05]
    assert a.island_range == [-1.0, 1.0] and a.phi == -1e-3 and a.wall[:3] == [-1.0, -1.0, 1.0]
    a = p.parse_args(["poincare", "--value", "-.5", "--box", "-3,3", "--param", "C=-1"])
    assert a.value == -0.5 and a.box == "-3,3"
    assert p.parse_args(["errata", "--matrix", "-1,0,0;0,1,0;0,0,0"]).matrix == "-1,0,0;0,1,0;0,0,0"
    assert p.parse_args(["run", "--field", "-y,x,0"]).field == "-y,x,0"  # any value, not only numbers
    assert p.parse_args(["run", "-v", "--h", "0.1"]).verbose  # options stay options
    # an option that is not one stays an error, in one line
    with pytest.raises(Exception, match="unrecognized arguments: --nope"):
        p.parse_args(["poincare", "--nope"])


def test_fieldlines_coils_command_of_the_docs_gets_past_the_parser(tmp_path, capsys):
    """The doc's command, verbatim but for the file: the error is about the file, not --Z."""
    missing = tmp_path / "coils.mine"
    rc = main(["fieldlines", "--coils", str(missing), "--R", "0.8,1.2", "--Z", "-0.2,0.2",
               "--axis-guess", "0.98,0"])
    line = _error_line(capsys)
    assert rc == 2 and "expected one argument" not in line and str(missing) in line


# ------------------------------------------------------------ outputs are what was asked (issue #40)
@pytest.mark.parametrize("argv, option, accepted", [
    (["run", "--out", "{d}/plain.txt"], "--out", ".npz, .zarr"),
    (["run", "--out", "{d}/noext"], "--out", ".npz, .zarr"),
    (["poincare", "--png", "{d}/p.jpg"], "--png", ".png, .pdf, .svg"),
    (["poincare", "--csv", "{d}/p.txt"], "--csv", ".csv"),
    (["fieldlines", "--iota-png", "{d}/i"], "--iota-png", ".png, .pdf, .svg"),
    (["fieldlines", "--csv", "{d}/s.dat"], "--csv", ".csv"),
    (["drift", "--png", "{d}/d.gif"], "--png", ".png, .pdf, .svg"),
])
def test_an_output_name_of_another_kind_is_refused_before_the_run(tmp_path, capsys, argv, option, accepted):
    """The file is written exactly where asked, or the name is refused (nothing written, nothing
    computed) with the suffixes that are accepted."""
    argv = [a.format(d=tmp_path) for a in argv]
    assert main(argv) == 2
    line = _error_line(capsys)
    assert option in line and accepted in line and argv[-1] in line
    assert list(tmp_path.iterdir()) == []


def test_two_outputs_on_one_file_are_refused(tmp_path, capsys):
    same = str(tmp_path / "s.png")
    assert main(["fieldlines", "--png", same, "--iota-png", same]) == 2
    line = _error_line(capsys)
    assert "--png" in line and "--iota-png" in line and same in line


@pytest.mark.parametrize("command", ["run", "poincare", "fieldlines", "order", "drift"])
def test_help_gives_the_default_output_names(command, capsys, monkeypatch):
    """Each output option's help states its default file name (the file a bare command writes)."""
    monkeypatch.setenv("COLUMNS", "250")  # argparse would break a name at its hyphen
    sub = build_parser()._subparsers._group_actions[0].choices[command]
    outs = [a for a in sub._actions if any(s in ("--out", "--png", "--iota-png", "--csv") for s in a.option_strings)]
    assert outs
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for a in outs:
        assert a.default and a.default in a.help and a.default in text, a.option_strings


def test_run_writes_exactly_the_file_asked_and_says_when_it_replaced_one(tmp_path, capsys):
    out = tmp_path / "r.npz"
    argv = ["run", "--steps", "2", "--particles", "2", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert f"written: {out}" in text and "replaced" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]
    before = out.stat().st_mtime_ns
    assert main(argv) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"written: {out} (replaced an existing file)" in text and out.stat().st_mtime_ns >= before


# ------------------------------------------ field-line studies from impossible starts (issue #41)
def _twist():
    from .test_fieldlines import R0, TwistMethod

    return TwistMethod(), R0


def test_iota_outside_the_box_is_refused_before_tracing():
    """Radii beyond the field's box (R ∈ [0.5, 1.5] here) used to give ι = NaN, status 2, after a
    full trace; now one error names the radius and the box, before any step."""
    from vpforms.fieldlines import iota_profile

    m, R0 = _twist()
    with pytest.raises(ValueError, match=r"R = 3.*outside the field's box.*R ∈ \[0\.5, 1\.5\]") as err:
        iota_profile(m, [1.1, 3.0], 0.1, 64, (R0, 0.0), progress=False)
    assert "line 1" in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(ValueError, match=r"Z = 0\.9.*outside the field's box.*Z ∈ \[-0\.5, 0\.5\]"):
        iota_profile(m, [1.1], 0.1, 64, (R0, 0.0), Z=0.9, progress=False)


@pytest.mark.parametrize("R", [-1.0, 0.0, math.nan])
def test_iota_at_a_radius_that_is_not_positive_is_refused(R):
    """R = −1 used to be traced as R = +1 (u = R²/2 forgets the sign)."""
    from vpforms.fieldlines import iota_profile, rotational_transform

    m, R0 = _twist()
    with pytest.raises(ValueError, match=r"line 1: R must be a positive"):
        iota_profile(m, [1.1, R], 0.1, 64, (R0, 0.0), progress=False)
    with pytest.raises(ValueError, match=r"\(R, Z\) pair with R > 0"):
        iota_profile(m, [1.1], 0.1, 64, (R, 0.0), progress=False)  # an axis at R ≤ 0 neither
    if R == 0.0:  # u = 0 given directly: R = 0
        with pytest.raises(ValueError, match=r"R = 0"):
            rotational_transform(m, [[0.0, 0.0, 0.0]], 0.1, 64, (R0, 0.0), progress=False)


def test_iota_of_a_line_started_on_the_axis_is_refused():
    """θ about the axis is undefined on it: the line read ι = 0 with error 0 and status 0."""
    from vpforms.fieldlines import iota_profile

    m, R0 = _twist()
    iota_profile(m, [R0 + 1e-4], 0.1, 64, (R0, 0.0), progress=False)  # near the axis is a line
    with pytest.raises(ValueError, match=r"line 1 starts on the magnetic axis.*tangent map"):
        iota_profile(m, [R0 + 0.1, R0 + 1e-9], 0.1, 64, (R0, 0.0), progress=False)


def test_axis_and_islands_from_outside_the_box_say_outside():
    from vpforms.fieldlines import island_chain, magnetic_axis, toroidal_section

    m, R0 = _twist()
    with pytest.raises(ValueError, match=r"axis guess.*R = 3.*outside the field's box"):
        magnetic_axis(m, (3.0, 0.0), 0.1)
    with pytest.raises(ValueError, match=r"axis guess.*R must be a positive"):
        magnetic_axis(m, (-1.0, 0.0), 0.1)
    with pytest.raises(ValueError, match=r"island scan point 2 is at R = 1.6.*outside the field's box"):
        island_chain(m, 2, 0.1, np.linspace(1.2, 2.0, 5))
    x0 = np.array([[0.5 * 1.1**2, 0.0, 0.0], [0.5 * 2.0**2, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"line 1.*R = 2.*outside the field's box"):
        toroidal_section(m, x0, 0.1, 64, progress=False)


def test_cli_fieldlines_axis_guess_outside_the_box_is_a_usage_error(tmp_path, capsys):
    """The tokamak's box is R ∈ [0.5, 1.5]: a guess at R = 3 is refused before the axis search."""
    outs = ["--png", str(tmp_path / "a.png"), "--iota-png", str(tmp_path / "b.png"), "--csv", str(tmp_path / "c.csv")]
    assert main(["fieldlines", "--axis-guess", "3,0", *outs]) == 2
    line = _error_line(capsys)
    assert "the axis guess is at R = 3, Z = 0, outside the field's box R ∈ [0.5, 1.5]" in line
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ MAKEGRID coil files (issue #41)
def _coil_file(tmp_path, rows, current="1000.0"):
    """A one-coil MAKEGRID file, a square of side 2 at z = 0 (``rows`` replaces its points)."""
    pts = rows or [("1.0", "0.0", "0.0"), ("0.0", "1.0", "0.0"), ("-1.0", "0.0", "0.0"), ("0.0", "-1.0", "0.0")]
    lines = ["periods 1", "begin filament", "mirror NIL"]
    lines += [f"{x} {y} {z} {current}" for x, y, z in pts]
    lines += [f"{pts[0][0]} {pts[0][1]} {pts[0][2]} 0.0 1 ring", "end"]
    path = tmp_path / "coils.test"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("row, current, line, needle", [
    (("1e308", "0.0", "0.0"), "1000.0", 4, "x = 1e+308"),
    (("1.0", "0.0", "-2e4"), "1000.0", 4, "z = -20000"),
    (None, "1e300", 4, "the current 1e+300"),
    (None, "-5e9", 4, "the current -5e+09"),
])
def test_makegrid_absurd_values_are_refused_with_the_line(tmp_path, row, current, line, needle):
    from vpforms.coils import CoilFileError, read_makegrid
    from vpforms.coils.makegrid import MAX_COORDINATE, MAX_CURRENT

    rows = None
    if row is not None:
        rows = [row, ("0.0", "1.0", "0.0"), ("-1.0", "0.0", "0.0"), ("0.0", "-1.0", "0.0")]
    path = _coil_file(tmp_path, rows, current)
    with pytest.raises(CoilFileError) as err:
        read_makegrid(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}, line {line}: ") and needle in msg
    bound = MAX_CURRENT if "current" in needle else MAX_COORDINATE
    assert f"{bound:g}" in msg


def test_makegrid_file_without_current_is_refused(tmp_path):
    from vpforms.coils import CoilFileError, read_makegrid

    path = _coil_file(tmp_path, None, "0.0")
    with pytest.raises(CoilFileError, match=r"every coil carries current 0.*no field"):
        read_makegrid(path)
    assert len(read_makegrid(_coil_file(tmp_path, None, "1.0"))) == 1  # the same file with a current reads


# ------------------------------------------------------------------ vpforms verify (issue #41)
@pytest.fixture
def small_store(tmp_path):
    pytest.importorskip("zarr")
    import vpforms
    from vpforms import problems
    from vpforms.distributed import run

    prob = problems.get("abc")
    store = str(tmp_path / "s.zarr")
    run(vpforms.scheme(prob.field, "SE+SE"), prob.initial_conditions(4, seed=0), 0.1, 2, store=store,
        chunk_particles=2, progress=False, backend="jax")
    assert main(["verify", store]) == 0
    return store


@pytest.mark.parametrize("where", ["zarr.json", "x/zarr.json", "status/zarr.json"])
@pytest.mark.parametrize("garbage", [b"\xff\xfe\x00garbage", b'{"zarr_format": 3, "node_type": "array"'])
def test_verify_names_a_damaged_metadata_file_and_never_passes_it(small_store, capsys, where, garbage):
    import os

    from vpforms.io import StoreVerificationError, verify_store

    path = os.path.join(small_store, where)
    with open(path, "wb") as fh:
        fh.write(garbage)
    assert main(["verify", small_store]) == 1
    line = _error_line(capsys)
    assert path in line and "UnicodeDecodeError" not in line
    with pytest.raises(StoreVerificationError, match="store metadata .* is damaged|differs from its copy") as err:
        verify_store(small_store)
    assert path in str(err.value)


# ------------------------------------------------------------------ mgrid: B against ∇×A (issue #41)
def _mgrid_two_groups():
    """Two coil groups: a 1/R toroidal field, A = (0, 0, −B₀R₀ ln R) → B = (0, B₀R₀/R, 0), and a
    vertical field, A = (0, cR/2, 0) → B = (0, 0, c): B is the exact curl of A (physical
    cylindrical components), so the spline's ∇×A matches it to interpolation accuracy."""
    from vpforms.grids import MGrid

    B0R0, c = 1.0, 0.2
    kw = dict(rmin=0.7, rmax=1.3, zmin=-0.3, zmax=0.3, ir=10, jz=9, kp=6, nfp=2)
    zero = lambda R, P, Z: 0.0 * R  # noqa: E731
    return MGrid.from_functions(
        [lambda R, P, Z: (zero(R, P, Z), B0R0 / R, zero(R, P, Z)), lambda R, P, Z: (zero(R, P, Z), zero(R, P, Z), c + 0 * R)],
        A=[lambda R, P, Z: (zero(R, P, Z), zero(R, P, Z), -B0R0 * np.log(R)), lambda R, P, Z: (zero(R, P, Z), 0.5 * c * R, zero(R, P, Z))],
        names=["tf", "vf"], currents=[1.0, 1.0], **kw)


def test_mgrid_whose_B_disagrees_with_curl_A_is_refused_with_group_and_place(tmp_path):
    from vpforms.grids import GridFileError, gridded_field, read_mgrid, write_mgrid

    mg = _mgrid_two_groups()
    good = tmp_path / "mgrid_good.nc"
    write_mgrid(mg, good)
    f = gridded_field(good)  # B and ∇×A agree: accepted, the mismatch reported
    assert f.grid_report.source == "A" and f.grid_report.curl_error < 1e-2
    k, j, i = 3, 4, 7  # one cell of group 2's B_Z: 1e300
    mg.B[1, 2, k, j, i] = 1e300
    bad = tmp_path / "mgrid_bad.nc"
    write_mgrid(mg, bad)
    back = read_mgrid(bad)
    with pytest.raises(GridFileError) as err:
        gridded_field(bad)
    msg = str(err.value)
    assert str(bad) in msg and "coil group 2 (vf)" in msg and "∇×A" in msg and "\n" not in msg
    assert f"R = {back.R[i]:.6g}" in msg and f"φ = {back.phi[k]:.6g}" in msg and f"Z = {back.Z[j]:.6g}" in msg


# ------------------------------------------------------------ a coil wire inside the grid (issue #41)
def test_cli_coil_wire_inside_the_spline_grid_names_the_coil_and_the_point(tmp_path, capsys):
    """A wire through the (R, Z) box of the spline grid: A and B are singular on it (non-finite at
    a node on the wire, a large spline error near it); refused before the grid is built."""
    path = _coil_file(tmp_path, [("1.0", "0.0", "0.0"), ("0.0", "1.0", "0.0"), ("-1.0", "0.0", "0.0"),
                                 ("0.0", "-1.0", "0.0")])
    outs = ["--png", str(tmp_path / "a.png"), "--iota-png", str(tmp_path / "b.png"), "--csv", str(tmp_path / "c.csv")]
    assert main(["fieldlines", "--coils", str(path), "--R", "0.8,1.2", "--Z", "-0.2,0.2", "--axis-guess", "1,0.1",
                 *outs]) == 2
    line = _error_line(capsys)
    assert "coil 0 'ring' (group 1)" in line and "R = 1, φ = 0, Z = 0" in line and "R ∈ [0.8, 1.2]" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["coils.test"]


def test_a_grid_node_where_A_is_not_finite_is_named():
    from vpforms.grids import cylindrical_potential

    R, phi, Z = np.linspace(0.8, 1.2, 5), np.linspace(0, 2 * np.pi, 4, endpoint=False), np.linspace(-0.2, 0.2, 5)
    A = np.ones((3, 5, 4, 5))
    A[1, 2, 1, 3] = np.inf
    with pytest.raises(ValueError, match=r"src: A has a non-finite value \(inf\) in A_φ at the node R = 1, "
                                         r"φ = 1\.5708, Z = 0\.1"):
        cylindrical_potential(R, phi, Z, A=A, source="src")

"""Connection lengths both ways to a wall (issue #38 item 4): ``vpforms.fieldlines.connection_length``.

Every expected value is computed here, independently of the tracer:

* the length of a line of the field B_R = α/R, B_φ = β/R, B_Z = γ (in u = R²/2: u̇ = α, φ̇ = β/2u,
  Ż = γ) to the planes Z = ±Z_w is a closed form — u and Z are linear in t and
  |B|² = (α² + β²)/2u + γ², so s(t) = [F(u(t)) − F(u₀)]/α with F(w) = √(w(A + cw)) + (A/√c)·asinh(√(cw/A)),
  A = (α² + β²)/2, c = γ²: the error of L_fwd, L_bwd and L falls as h² (ratio 4);
* both ways on the tokamak with islands: from a point k steps along a line, the backward length
  grows and the forward one shrinks by the length of those k steps (a symmetric method retraces its
  own steps), the exits are the same points;
* lines on closed surfaces never reach a wall around them: a lower bound with status OPEN, L NaN.
"""

from __future__ import annotations

import functools
import math

import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import vpforms
from vpforms import RESULTS, problems
from vpforms._errors import SpecError
from vpforms.fieldlines import (ConnectionLengths, Wall, connection_length, start_grid, trace_to_wall)
from vpforms.fieldlines._connection import FAILED, LEFT_FIELD, NOT_TRACED, OPEN, STATUS_NAMES, WALL

from .test_walls import HELIX, HELIX_WALL, V, _ExactHelix

_OK, _WHY = vpforms.native.available()
native = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")

ALPHA, BETA, GAMMA = 0.2, 2.0, 0.5
ZW = 0.4  # the wall's planes Z = ±ZW


@functools.lru_cache(maxsize=1)
def drift_field():
    """B_R = α/R, B_φ = β/R, B_Z = γ in (u = R²/2, φ, Z): a = (α, β/2u, γ), divergence free."""
    u, ph, Z = sp.symbols("u phi Z", real=True)
    f = vpforms.Field.from_sympy([sp.Float(ALPHA), sp.Float(BETA) / (2 * u), sp.Float(GAMMA)], (u, ph, Z),
                                 name="radial drift helix", box=((0.2, 1.6), (0.0, 2 * np.pi), (-0.6, 0.6)))
    f.coordinates = "toroidal (u = R²/2, φ, Z)"
    return f


def exact_length(u0, u1):
    """The arclength from u0 to u1 along a line of drift_field (closed form, module docstring)."""
    A, c = (ALPHA**2 + BETA**2) / 2, GAMMA**2

    def F(w):
        return math.sqrt(w * (A + c * w)) + A / math.sqrt(c) * math.asinh(math.sqrt(c * w / A))

    return (F(u1) - F(u0)) / ALPHA


def drift_method(order: int = 2):
    """A module-level builder: SE+SE on drift_field composed to ``order`` (symmetric for order ≥ 2)."""
    return vpforms.compose(vpforms.scheme(drift_field(), "SE+SE"), order)


DRIFT_WALL = Wall.box(0.7, 1.6, -ZW, ZW)


@pytest.fixture(scope="module")
def drift():
    R0, Z0 = np.array([1.0, 1.1]), np.array([0.05, -0.13])
    return drift_method(2), np.stack([R0**2 / 2, np.array([0.0, 1.0]), Z0], 1), DRIFT_WALL


def test_exact_lengths_both_ways_converge_at_order_two(drift):
    """L_fwd, L_bwd to the planes Z = ±Z_w and their sum against the closed form, at h, h/2, h/4:
    errors fall by 4 per halving (the trapezoid rule on |B|); the exits lie on the planes at the
    exact R; the statuses say WALL both ways."""
    m, x0, wall = drift
    Z0 = x0[:, 2]
    tp, tm = (ZW - Z0) / GAMMA, (-ZW - Z0) / GAMMA  # the exact exit times (the R walls are not reached)
    u0 = x0[:, 0]
    Lf = np.array([exact_length(a, a + ALPHA * t) for a, t in zip(u0, tp)])
    Lb = np.array([exact_length(a + ALPHA * t, a) for a, t in zip(u0, tm)])
    assert np.all(np.sqrt(2 * (u0 + ALPHA * tp)) < 1.6) and np.all(np.sqrt(2 * (u0 + ALPHA * tm)) > 0.7)
    errs = []
    for h in (0.08, 0.04, 0.02):
        res = connection_length(m, x0, h, 2000, wall, progress=False)
        assert isinstance(res, ConnectionLengths) and res.both_ways
        np.testing.assert_array_equal(res.status_fwd, WALL)
        np.testing.assert_array_equal(res.status_bwd, WALL)
        assert res.reached.all()
        np.testing.assert_array_equal(res.L, res.L_fwd + res.L_bwd)
        np.testing.assert_array_equal(res.traced, res.L)
        for d, t in (("forward", tp), ("backward", tm)):
            e = res.exit(d)
            np.testing.assert_allclose(e["Z"], np.sign(t) * ZW, atol=1e-13)
            np.testing.assert_allclose(e["R"], np.sqrt(2 * (u0 + ALPHA * t)), rtol=1e-12)  # u is linear: exact
        errs.append(np.abs(np.r_[res.L_fwd - Lf, res.L_bwd - Lb, res.L - (Lf + Lb)]))
    errs = np.array(errs)
    assert errs[-1].max() < 1e-4 * (Lf + Lb).min(), errs
    ratios = errs[:-1] / errs[1:]
    assert np.all((ratios > 3.6) & (ratios < 4.4)), ratios


def test_round_trip_and_lower_bound_on_the_exact_field(drift):
    """From x_k, k steps forwards: L_bwd grows and L_fwd shrinks by the k steps' length ℓ_k, L and
    both exits stay (a symmetric method retraces its steps backwards). Too few steps: OPEN, L NaN,
    the length traced a lower bound."""
    m, x0, wall = drift
    h = 0.04
    res = connection_length(m, x0, h, 2000, wall, progress=False)
    k = int(res.forward.step.min() // 2)
    assert k >= 5
    xk = np.asarray(vpforms.integrate(m, x0, h, k, progress=False).xs[:, -1])
    ell = np.asarray(trace_to_wall(m, x0, h, k, wall, progress=False).connection_length)
    again = connection_length(m, xk, h, 2000, wall, progress=False)
    np.testing.assert_array_equal(again.status, WALL)
    np.testing.assert_allclose(again.L_bwd, res.L_bwd + ell, rtol=1e-12)
    np.testing.assert_allclose(again.L_fwd, res.L_fwd - ell, rtol=1e-12)
    np.testing.assert_allclose(again.L, res.L, rtol=1e-12)
    for d in ("forward", "backward"):
        np.testing.assert_allclose(again.exit(d)["point"], res.exit(d)["point"], atol=1e-12)
    short = connection_length(m, x0, h, k, wall, progress=False)
    np.testing.assert_array_equal(short.status, OPEN)
    np.testing.assert_array_equal(short.status_fwd, OPEN)
    assert np.isnan(short.L).all() and np.isnan(short.L_fwd).all() and np.isnan(short.L_bwd).all()
    np.testing.assert_allclose(short.length_fwd, ell, rtol=1e-12)  # the k steps: a lower bound, < L_fwd
    assert np.all(short.traced < res.L)
    assert "2 inside after n_steps (lower bound)" in short.summary() and "L_c >" in short.summary()


@pytest.fixture(scope="module")
def tok():
    """The tokamak in (u, φ, Z) with its (2, 1) islands, SE+SE composed to order 2 (symmetric), and a
    box wall that cuts the outer surfaces: inner lines never reach it, outer lines do both ways."""
    prob = problems.get("tokamak", coordinates="toroidal")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), 2)
    R = np.array([1.05, 1.1, 1.27, 1.29, 1.31])
    x0 = np.stack([R**2 / 2, 0 * R, 0 * R], 1)
    return m, x0, Wall.box(0.7, 1.32, -0.17, 0.17)


@native
@pytest.mark.slow  # two native kernels of the composed method on the tokamak (~25 s to compile)
def test_both_ways_round_trip_and_lower_bounds(tok):
    """From x_k (k steps forwards along a line), L_bwd grows and L_fwd shrinks by the length ℓ_k of
    those steps (a symmetric method retraces its steps backwards), L = L_fwd + L_bwd is the same and
    so are both exits. Lines on closed surfaces inside the wall: OPEN both ways, L NaN, the length
    traced a lower bound that grows with n_steps."""
    m, x0, wall = tok
    h, n = 0.05, 3000
    res = connection_length(m, x0, h, n, wall, progress=False)
    inner = np.array([True, True, False, False, False])
    np.testing.assert_array_equal(res.status[inner], OPEN)
    np.testing.assert_array_equal(res.status[~inner], WALL)
    assert np.isnan(res.L[inner]).all() and np.isnan(res.L_fwd[inner]).all() and np.isnan(res.L_bwd[inner]).all()
    assert np.all(res.traced[inner] > 0)
    longer = connection_length(m, x0[inner], h, 2 * n, wall, progress=False)
    np.testing.assert_array_equal(longer.status, OPEN)
    assert np.all(longer.traced > 1.9 * res.traced[inner])
    # k steps forwards from the outer starts (half way to their first exit), then both ways again
    k = int(res.forward.step[~inner].min() // 2)
    assert k >= 3
    out = x0[~inner]
    xk = np.asarray(vpforms.integrate(m, out, h, k, progress=False).xs[:, -1])
    ell = np.asarray(trace_to_wall(m, out, h, k, wall, progress=False).connection_length)  # the k steps' length
    again = connection_length(m, xk, h, n, wall, progress=False)
    np.testing.assert_array_equal(again.status, WALL)
    np.testing.assert_allclose(again.L_bwd, res.L_bwd[~inner] + ell, rtol=1e-9)
    np.testing.assert_allclose(again.L_fwd, res.L_fwd[~inner] - ell, rtol=1e-9)
    np.testing.assert_allclose(again.L, res.L[~inner], rtol=1e-9)
    for d in ("forward", "backward"):
        np.testing.assert_allclose(again.exit(d)["point"], res.exit(d)["point"][~inner], atol=1e-9)
    s = res.summary()
    assert "3 reached it" in s and "2 inside after n_steps (lower bound)" in s, s


def test_one_way_statuses_and_csv(drift, tmp_path):
    m, x0, wall = drift
    x0 = np.r_[x0, [[0.5, 0.0, -0.39]]]  # this one reaches the bottom soon, the top not within 10 steps
    res = connection_length(m, x0, 0.05, 10, wall, both_ways=False, progress=False)
    assert res.backward is None and not res.both_ways
    np.testing.assert_array_equal(res.status_bwd, NOT_TRACED)
    np.testing.assert_array_equal(res.status, res.status_fwd)
    np.testing.assert_array_equal(res.L[res.reached], res.L_fwd[res.reached])
    np.testing.assert_array_equal(res.status, OPEN)
    with pytest.raises(ValueError, match="direction must be"):
        res.exit("backward")
    both = connection_length(m, x0, 0.05, 10, wall, progress=False)
    np.testing.assert_array_equal(both.status_bwd, [OPEN, OPEN, WALL])
    path = tmp_path / "lc.csv"
    both.to_csv(str(path))
    head = path.read_text().splitlines()[0].split(",")
    data = np.genfromtxt(path, delimiter=",", skip_header=1)
    col = {c: data[:, i] for i, c in enumerate(head)}
    np.testing.assert_array_equal(col["status_fwd"], both.status_fwd)
    np.testing.assert_array_equal(np.isnan(col["L"]), ~both.reached)  # empty where not reached
    np.testing.assert_array_equal(col["L"][both.reached], both.L[both.reached])
    np.testing.assert_allclose(col["R0"], np.sqrt(2 * x0[:, 0]), rtol=1e-15)
    np.testing.assert_array_equal(col["exit_R_bwd"][both.status_bwd == WALL],
                                  both.exit("backward")["R"][both.status_bwd == WALL])


class _GridStop(_ExactHelix):
    """The exact helix whose field ends (a grid's domain: status left_domain) where the failing
    step of _ExactHelix is."""

    def step_with_status(self, x, h):
        X, code = super().step_with_status(x, h)
        return X, jnp.where(code == RESULTS.successful, code, RESULTS.left_domain).astype(jnp.int32)


def test_statuses_of_failed_and_grid_stopped_lines():
    """A failed step and the field's own domain map to FAILED and LEFT_FIELD (lower bounds: the
    length to the last good point), never to a connection length."""
    x0 = np.array([[1.47, 0.0, -0.0137], [1.0, 0.0, 0.0]])
    for m, code in ((HELIX[False], FAILED), (_GridStop(False, V), LEFT_FIELD)):
        res = connection_length(m, x0, 0.1, 400, HELIX_WALL, progress=False)
        np.testing.assert_array_equal(res.status_fwd, [code, WALL])
        np.testing.assert_array_equal(res.status_bwd, [WALL, WALL])
        np.testing.assert_array_equal(res.status, [code, WALL])
        k = np.floor((0.4 - x0[0, 2]) / (V * 0.1))  # good steps before the stop (tests/test_walls.py)
        np.testing.assert_allclose(res.length_fwd[0], np.hypot(1.47, V) * k * 0.1, rtol=1e-13)
        assert np.isnan(res.L[0]) and np.isnan(res.L_fwd[0]) and res.L_bwd[0] > 0
        assert f"1 {STATUS_NAMES[code]}" in res.summary()


def test_bad_arguments(drift):
    m, x0, wall = drift
    with pytest.raises(ValueError, match=r"x0\[0\] starts outside the wall"):
        connection_length(m, [[0.5 * 1.65**2, 0.0, 0.0]], 0.05, 10, wall)
    for h in (0.0, -0.05, float("nan")):
        with pytest.raises(ValueError, match="h must be finite and > 0"):
            connection_length(m, x0, h, 10, wall)
    with pytest.raises(TypeError, match="both_ways must be True or False"):
        connection_length(m, x0, 0.05, 10, wall, both_ways=1)
    with pytest.raises(TypeError, match="does not pickle"):
        connection_length(m, x0, 0.05, 10, wall, client=1, builder=lambda: m)


def test_a_field_without_spec_needs_a_builder_on_dask():
    with pytest.raises(SpecError, match="pass builder="):
        connection_length(HELIX[True], [[0.5, 0.0, 0.0]], 0.1, 10, HELIX_WALL, client=1)


# ------------------------------------------------------------------------------ Dask
@pytest.fixture(scope="module")
def threaded_client():
    """Two worker threads in this process: the Dask route (recipes, chunks, both directions submitted
    together) without the seconds a process cluster takes to start."""
    dd = pytest.importorskip("dask.distributed")
    cl = dd.Client(processes=False, n_workers=2, threads_per_worker=1, dashboard_address=None)
    yield cl
    cl.close()


def _same(a: ConnectionLengths, b: ConnectionLengths):
    for f in ("status_fwd", "status_bwd", "length_fwd", "length_bwd"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    for d in ("forward", "backward"):
        np.testing.assert_array_equal(a.exit(d)["point"], b.exit(d)["point"])


@native
def test_dask_equals_in_process_bit_for_bit(drift, threaded_client):
    """The same lines natively in this process and on two Dask workers (chunks of 1 line, both
    directions at once), rebuilt from the spec and by a builder: equal bit for bit."""
    m, x0, wall = drift
    x0 = np.r_[x0, [[0.6, 2.0, 0.3], [0.9, -1.0, -0.2]]]
    one = connection_length(m, x0, 0.05, 600, wall, progress=False)
    assert one.forward.backend == "native" and one.reached.all()
    spec = connection_length(m, x0, 0.05, 600, wall, client=threaded_client, chunk_lines=1, progress=False)
    assert spec.where == "Dask, 2 worker thread(s)" and "both" in spec.wall_s
    _same(spec, one)
    built = connection_length(m, x0, 0.05, 600, wall, client=threaded_client, chunk_lines=1, progress=False,
                              builder=functools.partial(drift_method, 2))
    _same(built, one)
    with pytest.raises(ValueError, match="the builder built"):  # a builder of another method is refused
        connection_length(m, x0, 0.05, 10, wall, client=threaded_client, progress=False,
                          builder=functools.partial(drift_method, 4))


@native
@pytest.mark.slow  # a LocalCluster of 2 worker processes (~20 s to start, rebuild and load the kernel there)
def test_dask_worker_processes_equal_in_process(tok):
    """Two worker processes, the method rebuilt there from its spec (a field in (u, φ, Z): the spec
    keeps its coordinates) and by the command's builder: equal bit for bit to one in-process run."""
    from vpforms.cli import build_parser
    from vpforms.cli import fieldlines as fl

    m, x0, wall = tok
    one = connection_length(m, x0, 0.05, 600, wall, progress=False)
    par = connection_length(m, x0, 0.05, 600, wall, client=2, chunk_lines=2, progress=False)  # the spec route
    assert par.where == "Dask, 2 worker thread(s)"
    _same(par, one)
    args = build_parser().parse_args(["fieldlines", "--order", "2"])  # the tokamak in (u, φ, Z), as tok
    b = fl.method_builder(args)
    mc = b()
    one = connection_length(mc, x0, 0.05, 600, wall, progress=False)
    par = connection_length(mc, x0, 0.05, 600, wall, client=2, chunk_lines=2, progress=False, builder=b)
    _same(par, one)


# ------------------------------------------------------------------------------ start points
def test_start_grid_fills_the_band_inside_the_wall():
    wall = Wall.circle(1.0, 0.0, 0.3, n=64)
    g = start_grid(wall, 2000, depth=0.1)
    R, Z = np.sqrt(2 * g.x0[:, 0]), g.x0[:, 2]
    d = np.asarray(wall.signed_distance(R, Z))
    assert np.all((d < 0) & (d >= -0.1))
    ring = math.pi * (0.3**2 - 0.2**2)  # the band's area (the 64-gon's to 0.2 %)
    assert abs(g.x0.shape[0] - 2000) < 0.05 * 2000 and g.spacing == pytest.approx(math.sqrt(ring / 2000), rel=0.02)
    np.testing.assert_allclose(np.sort(g.Z), np.sort(-g.Z), atol=1e-15)  # nodes symmetric in Z
    img = g.image(np.arange(g.x0.shape[0]))
    assert np.count_nonzero(np.isfinite(img)) == g.x0.shape[0]
    np.testing.assert_array_equal(img[g.index[:, 0], g.index[:, 1]], np.arange(g.x0.shape[0]))
    np.testing.assert_array_equal(g.R[g.index[:, 1]], R)
    cart = start_grid(wall, 500, phi0=0.5, toroidal=False)
    np.testing.assert_allclose(np.arctan2(cart.x0[:, 1], cart.x0[:, 0]), 0.5, atol=1e-15)
    with pytest.raises(ValueError, match="depth must be > 0"):
        start_grid(wall, 10, depth=0.0)
    with pytest.raises(ValueError, match="n must be an integer"):
        start_grid(wall, 0)
    with pytest.raises(TypeError, match="wall must be a Wall"):
        start_grid([1, 2], 10)


# ------------------------------------------------------------------------------ the command line
@pytest.mark.parametrize("argv, needle", [
    (["--lc-depth", "0.1"], "--lc-depth does nothing without --connection-length N"),
    (["--lc-transits", "3", "--lc-workers", "2"], "--lc-transits, --lc-workers do nothing without --connection-length"),
    (["--connection-length", "10"], "--connection-length needs a wall: --wall default, divertor or"),
    (["--wall", "divertor"], "--wall divertor is a device's model wall: give --device (w7x)"),
    (["--connection-length", "10", "--wall", "default", "--lc-png", "x.txt"], "--lc-png 'x.txt': the name must end in"),
])
def test_cli_connection_length_arguments_are_one_clean_line(argv, needle, capsys, tmp_path):
    from vpforms.cli import main

    outs = ["--png", str(tmp_path / "a.png"), "--iota-png", str(tmp_path / "b.png"), "--csv", str(tmp_path / "c.csv")]
    assert main(["fieldlines", *argv, *outs]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error: ") and needle in err[0], err


def test_cli_builder_rebuilds_the_commands_method():
    """The command's builder (what Dask workers call) pickles and builds the method the command traces."""
    import pickle

    from vpforms.cli import build_parser
    from vpforms.cli import fieldlines as fl
    from vpforms.cli._common import _method_from_args

    args = build_parser().parse_args(["fieldlines", "--order", "2", "--h", "0.05"])
    b = pickle.loads(pickle.dumps(fl.method_builder(args)))
    field = fl._field_source(args)[0]
    assert b().spec() == _method_from_args(args, field).spec()


def test_divertor_wall_is_the_default_domain_moved_inward():
    """Every vertex of W7-X's model wall lies ``inset`` inside the default domain (its in-plane
    distance to the domain's boundary at the same φ, to the polygons' discretisation), the default
    inset is DIVERTOR_INSET; bad insets are refused."""
    from vpforms.coils import device_domain
    from vpforms.problems.devices import DIVERTOR_INSET, divertor_wall

    dom = device_domain("w7x")
    for inset in (None, 0.1):
        w = divertor_wall("w7x", inset)
        want = DIVERTOR_INSET["w7x"] if inset is None else inset
        d = np.asarray(dom.signed_distance(w.R.ravel(), np.repeat(w.phis, w.n_vertices), w.Z.ravel()))
        # measured to the domain's chords, interpolated between its planes: within 1.5 mm of the inset
        assert np.all(d < 0) and np.abs(d + want).max() < 1.5e-3, (want, d.min(), d.max())
        assert w.nfp == dom.nfp and np.array_equal(w.phis, dom.phis)
    with pytest.raises(ValueError, match="inset must be > 0"):
        divertor_wall("w7x", -0.1)
    with pytest.raises(ValueError, match="no default divertor inset"):
        divertor_wall("hsx")
    with pytest.raises(ValueError, match="intersects itself"):
        divertor_wall("w7x", 0.3)  # past the smallest radius of curvature (0.27 m): a plane folds


def test_connection_length_figure_log_colour_bar_units_lower_bounds_and_wall(drift, tmp_path):
    """The map: a logarithmic colour bar over the reached lines' L_c, labelled with its unit; the
    lines without a wall hit listed apart with their smallest lower bound; the wall in the legend;
    the title inside the figure; with and without the grid."""
    from matplotlib.colors import LogNorm

    from vpforms import plots

    from .test_fieldline_figures import LONG_TITLE, _inside, _legend_texts

    m, _, wall = drift
    g = start_grid(wall, 60, depth=0.15)
    res = connection_length(m, g.x0, 0.05, 8, wall, progress=False)
    assert 0 < res.reached.sum() < res.reached.size and res.unreached.any()
    for grid in (g, None):
        fig = plots.connection_length_figure(res, grid, wall, title=LONG_TITLE, path=str(tmp_path / "lc.png"))
        fig.canvas.draw()
        cbar = fig.axes[-1]
        assert cbar.get_ylabel() == "connection length L_c = L_fwd + L_bwd (m)"
        norm = fig.axes[0].collections[0].norm
        assert isinstance(norm, LogNorm)
        assert norm.vmin == pytest.approx(np.nanmin(res.L)) and norm.vmax == pytest.approx(np.nanmax(res.L))
        texts = _legend_texts(fig)
        n = res.reached.size
        assert f"reached the wall ({int(res.reached.sum())} of {n} lines): L_c in colour" in texts, texts
        lb = f"L_c > {np.min(res.traced[res.unreached]):.3g} m, a lower bound"
        assert any(t.endswith(lb) for t in texts) and "wall" in texts, texts
        assert _inside(fig, fig._suptitle)
    assert (tmp_path / "lc.png").stat().st_size > 10_000

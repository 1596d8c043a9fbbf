"""Walls on the native backend and in Dask chunks (issue #21 item 4: "the same status on JAX, native,
Dask runs").

The native kernel ``vp_wall`` (``vpforms.backends.native.codegen.walls``) stops a line at the first
step whose new point is outside the polygon, as the JAX scan of ``trace_to_wall`` does; both locate
the exit with the same JAX code. So the two backends stop the same lines at the same steps with the
same statuses, and their numbers agree to rounding (C against XLA); chunks of lines run as Dask tasks
equal one call bit for bit. The steps a recovering method takes through JAX inside a native run are
tested against the wall by ``WallRun.recovered`` (unit test below, with an exact answer).
"""

from __future__ import annotations

import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, distributed, problems
from vpforms.backends import NativeUnavailableError
from vpforms.backends.native.walls import WallRun
from vpforms.domains import ToroidalDomain
from vpforms.fieldlines import Wall, WallHits, trace_to_wall

_OK, _WHY = vpforms.native.available()
native = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")

FIELDS = ("status", "hit", "step", "theta", "t_exit", "exit_point", "exit_RZ", "exit_phi", "connection_length",
          "transits", "last_point", "fallback")


def assert_same(a: WallHits, b: WallHits, atol: float | None):
    """Same lines stopped at the same steps with the same statuses; the numbers equal bit for bit
    (atol None) or to atol, NaN exactly in the same places."""
    for f in ("status", "hit", "step", "fallback"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    for f in FIELDS[3:-1]:
        x, y = getattr(a, f), getattr(b, f)
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=f)
        if atol is None:
            np.testing.assert_array_equal(x, y, err_msg=f)
        else:
            np.testing.assert_allclose(x, y, rtol=0, atol=atol, equal_nan=True, err_msg=f)


@pytest.fixture(scope="module")
def tok():
    """The perturbed tokamak (islands), SE+SE with recovery at h = 0.05: some bare steps fail and are
    recovered through JAX inside the native run; a box that cuts the outer surfaces."""
    prob = problems.get("tokamak")
    m = vpforms.scheme(prob.field, "SE+SE")
    R = np.linspace(0.75, 1.28, 30)
    x0 = np.stack([R, 0 * R, 0 * R], 1)
    return m, x0, Wall.box(0.7, 1.3, -0.15, 0.15)


@native
def test_native_jax_and_chunks_stop_the_same_lines(tok):
    m, x0, wall = tok
    nat = trace_to_wall(m, x0, 0.05, 500, wall, progress=False)
    assert nat.backend == "native" and nat.backend_reason == "auto: native available"
    jx = trace_to_wall(m, x0, 0.05, 500, wall, progress=False, backend="jax")
    assert jx.backend == "jax"
    assert 0 < nat.n_hit < x0.shape[0] and nat.n_failed == 0
    assert_same(nat, jx, atol=1e-10)
    # the exits lie on the polygon: the wall's own signed distance
    rows = np.flatnonzero(nat.hit)
    assert np.abs(np.asarray(wall.signed_distance(*nat.exit_RZ[rows].T))).max() <= 1e-12
    # chunks of 7 lines (one block of 8 lanes each, a remainder of 2): one call, bit for bit
    ch = distributed.trace_to_wall(m, x0, 0.05, 500, wall, chunk_particles=7, progress=False)
    assert ch.backend == "native"
    assert_same(ch, nat, atol=None)
    # JAX: the same stops; the numbers to rounding only, since a JAX run re-traces all its lines with
    # the recovering step when one of them needs it (bare first), and a chunk without such a line
    # keeps the bare step, whose compiled code rounds differently in the last bit
    chj = distributed.trace_to_wall(m, x0, 0.05, 500, wall, chunk_particles=7, progress=False, backend="jax")
    assert_same(chj, jx, atol=1e-12)


def test_recovered_steps_stop_at_the_wall_and_accumulate():
    """Steps taken through JAX in a native run: the one that leaves the box stops its line (mask, exit
    step n, outside point kept); the others add the trapezoid |h|(|B(x)| + |B(X)|)/2 and the wrapped
    angle increment, exactly, and ask for a full test at the next step."""
    wall = Wall.box(0.5, 1.5, -1.0, 1.0)
    run = WallRun(4, ToroidalDomain.axisymmetric(wall), 1e-12, False,
                  lambda R, phi, Z: wall.contains(np.stack([R, Z], 1)), lambda X: np.full(X.shape[0], 2.0), -0.25)
    run.s[:] = 3.0
    run.phi[:] = [0.0, 3.0, 0.0, 0.0]
    run.mg[:] = 0.7
    idx = np.array([0, 1, 3])
    n = np.array([5, 6, 7])
    x = np.array([[1.0, 0.0, 0.0], [np.cos(3.0), np.sin(3.0), 0.0], [1.0, 0.0, 0.9]])
    X = np.array([[np.cos(0.1), np.sin(0.1), 0.0],  # turns by +0.1
                  [np.cos(3.0), -np.sin(3.0), 0.0],  # φ 3 → −3, across φ = π: +2(π − 3), wrapped
                  [1.0, 0.0, 1.1]])  # out through Z = 1
    out = run.recovered(idx, n, x, X)
    np.testing.assert_array_equal(out, [False, False, True])
    assert run.step.tolist() == [-1, -1, -1, 7]
    np.testing.assert_array_equal(run.Xo[3], X[2])
    np.testing.assert_allclose(run.L, [0.625, 0.625, 0.0, 0.0], rtol=0, atol=1e-15)  # 0.25 (3 + 2)/2
    np.testing.assert_allclose(run.dphi, [0.1, 2 * (np.pi - 3.0), 0.0, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.phi[:2], [0.1, -3.0], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(run.s, [2.0, 2.0, 3.0, 3.0])
    np.testing.assert_array_equal(run.mg, [0.0, 0.0, 0.7, 0.7])


def test_native_refused_says_why():
    """backend="native" for a method the wall kernel cannot run: one clear error, not a JAX run."""
    class Toy:  # a user method: no SymPy field, not generated
        field = staticmethod(lambda x: x)

        def step_with_status(self, x, h):
            return x, 0

    with pytest.raises(NativeUnavailableError, match="native backend cannot run"):
        trace_to_wall(Toy(), np.array([[1.0, 0.0, 0.0]]), 0.1, 3, Wall.box(0.5, 1.5, -1, 1), backend="native")
    res = trace_to_wall(Toy(), np.array([[1.0, 0.0, 0.0]]), 0.1, 3, Wall.box(0.5, 1.5, -1, 1), progress=False)
    assert res.backend == "jax" and res.backend_reason.startswith("auto: native not used")
    assert res.status.tolist() == [RESULTS.successful]


@native
@pytest.mark.slow  # a Dask LocalCluster of 2 worker processes (~20 s to start and compile there)
def test_dask_workers_equal_one_call(tok):
    m, x0, wall = tok
    one = trace_to_wall(m, x0, 0.05, 500, wall, progress=False)
    par = distributed.trace_to_wall(m, x0, 0.05, 500, wall, chunk_particles=8, client="local", workers=2,
                                    progress=False)
    assert par.backend == "native"
    assert_same(par, one, atol=None)


@native
@pytest.mark.slow  # JAX compiles SE+SE on the spline field (~10 s), the kernel another ~20 s
def test_toroidal_spline_field_native_equals_jax():
    """The coil stellarator's spline field in (u, φ, Z) (run-time spline data, the grid's own
    left_domain), a circular wall: the same statuses and steps on both backends, numbers ≤ 1e-10."""
    from vpforms.problems.coil_fields import make_stellarator

    field = make_stellarator(n_R=12, n_phi=8, n_Z=12).field
    m = vpforms.scheme(field, "SE+SE", recover=False)
    R = np.linspace(0.99, 1.1, 12)  # from near the axis (R ≈ 0.983) outwards
    x0 = np.stack([R**2 / 2, 0 * R, 0 * R], 1)
    wall = Wall.circle(0.983, 0.0, 0.125, n=48)
    nat = trace_to_wall(m, x0, 0.02, 400, wall, progress=False, backend="native")
    jx = trace_to_wall(m, x0, 0.02, 400, wall, progress=False, backend="jax")
    assert 0 < nat.n_hit < R.size, nat.summary()
    assert_same(nat, jx, atol=1e-10)


# ------------------------------------------------------------------ default walls of the problems
def test_default_walls_of_the_problems():
    """The tokamak's wall is the flux surface ψ = 0.11 R₀⁴ (inside the separatrix ψ = R₀⁴/8), the
    Stokes flow's the half disc r ≤ 1.01 about its invariant unit ball; both hold the problems'
    default and sampled starting points, in either coordinates of the tokamak."""
    for R0 in (1.0, 1.3):
        wall = problems.get("tokamak", R0=R0).wall
        R, Z = wall.vertices.T
        psi = (R**2 - R0**2) ** 2 / 8 + R**2 * Z**2 / 2  # the flux function, by hand
        np.testing.assert_allclose(psi, 0.11 * R0**4, rtol=1e-12)
        assert R.min() > 0.2 * R0 and R.max() < np.sqrt(2) * R0  # inside the separatrix
    for prob in (problems.get("tokamak"), problems.get("tokamak", coordinates="toroidal"),
                 problems.get("stokes_sphere")):
        tor = prob.field.coordinates.startswith("toroidal")
        for x in (prob.x0, prob.initial_conditions(500, seed=1)):
            R = np.sqrt(2 * x[:, 0]) if tor else np.hypot(x[:, 0], x[:, 1])
            assert prob.wall.contains(np.stack([R, x[:, 2]], 1)).all(), prob.name
    R, Z = problems.get("stokes_sphere").wall.vertices.T
    arc = R > 0
    np.testing.assert_allclose(np.hypot(R[arc], Z[arc]), 1.01, rtol=1e-15)
    assert problems.get("abc").wall is None


def test_cli_wall_argument():
    from vpforms.cli.fieldlines import _wall_arg

    assert _wall_arg("default") == "default" and _wall_arg(" Default ") == "default"
    assert _wall_arg("0.6,-0.3,1.4,-0.3") == [0.6, -0.3, 1.4, -0.3]


@native
@pytest.mark.slow  # S1 on the Stokes flow, native and JAX compilations (~30 s)
def test_stokes_lines_stop_at_the_default_wall_instead_of_overflowing():
    """S1 at h = 0.1 on stokes_sphere carries some streamlines out of the invariant ball; without a
    wall they grow until a step fails. With the problem's wall every line either stays inside or stops
    with status left_domain, its exit on the circle r = 1.01 — no failure, no overflow."""
    prob = problems.get("stokes_sphere")
    m = vpforms.scheme(prob.field, "S1")
    x0 = prob.initial_conditions(200, seed=0)
    free = vpforms.integrate(m, x0, 0.1, 2000, progress=False)
    assert np.count_nonzero(np.asarray(free.status) != RESULTS.successful) > 0  # escaped and failed
    hits = trace_to_wall(m, x0, 0.1, 2000, prob.wall, progress=False)
    assert hits.n_failed == 0 and hits.n_hit > 0
    np.testing.assert_array_equal(hits.status, np.where(hits.hit, RESULTS.left_domain, RESULTS.successful))
    rows = np.flatnonzero(hits.hit)
    np.testing.assert_allclose(np.hypot(*hits.exit_RZ[rows].T), 1.01 * np.cos(np.pi / 128), rtol=0,
                               atol=1.01 * (1 - np.cos(np.pi / 128)) + 1e-12)  # on the 64-gon's edges
    assert np.abs(np.asarray(prob.wall.signed_distance(*hits.exit_RZ[rows].T))).max() <= 1e-9
    # the lines that failed without the wall are among those it stops
    assert np.all(hits.hit[np.asarray(free.status) != RESULTS.successful])

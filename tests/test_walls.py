"""Walls (issue #21, item 4): a closed (R, Z) polygon and the field lines traced until they leave it.

Every expected value is computed here independently of vpforms.fieldlines._wall: the polygon by
matplotlib's point-in-path test and a brute-force point–segment distance, the exits by closed
forms (exact toy flows) or by DOP853 with a terminal event on that distance, the flux surfaces by
their closed-form ψ.
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from matplotlib.path import Path
from scipy.integrate import solve_ivp

import vpforms
from vpforms import RESULTS, problems
from vpforms.fieldlines._wall import Wall, WallHits, trace_to_wall
from vpforms.toroidal import box_from_cylindrical, toroidal_field


# ------------------------------------------------------------------ independent polygon geometry
def np_distance(R, Z, wall):
    """Brute force: the least of the distances to every vertex and every perpendicular foot that
    falls inside its edge."""
    p = np.stack([np.ravel(R), np.ravel(Z)], axis=1)
    V = np.stack([wall.R, wall.Z], axis=1)
    d = np.full(p.shape[0], np.inf)
    for a, b in itertools.pairwise(V):
        e = b - a
        s = (p - a) @ e / (e @ e)
        perp = np.abs((p - a) @ np.array([-e[1], e[0]])) / np.hypot(*e)
        foot = np.where((s > 0) & (s < 1), perp, np.inf)
        d = np.minimum.reduce([d, np.hypot(*(p - a).T), np.hypot(*(p - b).T), foot])
    return d.reshape(np.shape(R))


def np_signed_distance(R, Z, wall):
    inside = Path(np.stack([wall.R, wall.Z], axis=1)).contains_points(np.stack([np.ravel(R), np.ravel(Z)], 1))
    return np.where(inside.reshape(np.shape(R)), -1.0, 1.0) * np_distance(R, Z, wall)


def surface_margin(level, R_lo, R_hi, z_of_R, wall, n=4001):
    """max over a closed poloidal curve {Z = ±z(R), R_lo ≤ R ≤ R_hi} of the signed distance: < 0 iff
    the whole curve (a flux surface) is inside the wall."""
    R = np.linspace(R_lo, R_hi, n)
    z = z_of_R(R, level)
    return float(np.max(np_signed_distance(np.r_[R, R], np.r_[z, -z], wall)))


# --------------------------------------------------------------------------------- the polygon
def test_wall_validation_errors_are_one_clear_message_each():
    with pytest.raises(ValueError, match=r"not closed: its last vertex \(1, 1\) differs from its first \(1, 0\); "
                                         r"close it by repeating the first vertex"):
        Wall([1, 2, 2, 1], [0, 0, 1, 1])
    # a bow tie: edge 0 (1,0)→(2,1) crosses edge 2 (2,0)→(1,1)
    with pytest.raises(ValueError, match=r"intersects itself: edge 0 \(vertex 0 \(1, 0\) → vertex 1 \(2, 1\)\) and "
                                         r"edge 2 \(vertex 2 \(2, 0\) → vertex 3 \(1, 1\)\)"):
        Wall([1, 2, 2, 1, 1], [0, 1, 0, 1, 0])
    # a vertex touching a non-adjacent edge, and an edge folding back on the previous one
    with pytest.raises(ValueError, match=r"itself: edge 0 .* and edge 2 .*→ vertex 3 \(1, 0\)\) cross or touch"):
        Wall([0, 2, 2, 1, 0, 0], [0, 0, 2, 0, 2, 0])
    with pytest.raises(ValueError, match=r"intersects itself: edge 1 .* and edge 2 .* fold back"):
        Wall([0, 2, 3, 1, 0, 0], [0, 0, 0, 0, 1, 0])
    with pytest.raises(ValueError, match=r"at least 3 distinct vertices .* got 2 distinct"):
        Wall([1, 2, 1], [0, 0, 0])
    with pytest.raises(ValueError, match=r"at least 3 distinct vertices .* got 2 distinct"):
        Wall([1, 1, 2, 2, 1], [0, 0, 1, 1, 0])  # repeated vertices are dropped, then counted
    with pytest.raises(ValueError, match=r"must be finite: vertex 1 is \(R, Z\) = \(nan, 0\)"):
        Wall([1, np.nan, 2, 1], [0, 0, 1, 0])
    with pytest.raises(ValueError, match=r"half-plane R ≥ 0: vertex 1"):
        Wall([1, -1, 2, 1], [0, 0, 1, 0])
    with pytest.raises(ValueError, match=r"at least 3 distinct vertices .* got 1"):
        Wall([1.0], [0.0])
    with pytest.raises(ValueError, match="same length"):
        Wall([1, 2, 1], [0, 0, 1, 0])
    with pytest.raises(ValueError, match="R_min < R_max"):
        Wall.box(1.0, 1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="integer n ≥ 3"):
        Wall.circle(1.0, 0.0, 0.2, n=2)
    with pytest.raises(ValueError, match="radius > 0"):
        Wall.circle(1.0, 0.0, -0.2)
    # closed to 1e-12 relative is closed; the closing vertex and repeats are not kept twice
    w = Wall([1, 2, 2, 2, 1, 1 + 1e-13], [0, 0, 1, 1, 1, 0])
    assert w.n_vertices == 4 and w.R[-1] == w.R[0] and w.area == pytest.approx(1.0)


@pytest.fixture(scope="module")
def notched():
    """A non-convex wall: a D shape with a notch (the even-odd rule and the distance at concave corners)."""
    t = np.linspace(-np.pi / 2, np.pi / 2, 40)
    R = np.r_[0.6 + 0.6 * np.cos(t), 0.6, 0.6, 0.9, 0.6]
    Z = np.r_[0.8 * np.sin(t), 0.8, 0.1, 0.0, -0.1]
    return Wall(np.r_[R, R[0]], np.r_[Z, Z[0]])


@pytest.mark.parametrize("which", ["notched", "clockwise", "box", "circle"])
def test_inside_and_signed_distance_match_matplotlib_and_brute_force(which, notched):
    """At random points, on the polygon and 1e-7 off it on either side: inside = matplotlib's
    point-in-path, signed distance = the brute-force distance, negative inside, zero on the polygon."""
    wall = {"notched": notched, "clockwise": Wall(notched.R[::-1], notched.Z[::-1]),
            "box": Wall.box(0.5, 1.5, -0.3, 0.4), "circle": Wall.circle(1.0, 0.1, 0.3, n=17)}[which]
    r0, r1, z0, z1 = wall.bounds
    rng = np.random.default_rng(7)
    R = rng.uniform(r0 - 0.2, r1 + 0.2, 4000)
    Z = rng.uniform(z0 - 0.2, z1 + 0.2, 4000)
    # on the polygon: its vertices and a random point of each edge; off it: ±1e-7 along the outer normal
    s = rng.uniform(0.01, 0.99, wall.n_vertices)
    dR, dZ = np.diff(wall.R), np.diff(wall.Z)
    Re, Ze = wall.R[:-1] + s * dR, wall.Z[:-1] + s * dZ
    ccw = np.sum(wall.R[:-1] * wall.Z[1:] - wall.R[1:] * wall.Z[:-1]) > 0  # shoelace
    nR, nZ = (dZ, -dR) / np.hypot(dR, dZ) * (1 if ccw else -1)
    delta = 1e-7
    R = np.r_[R, wall.R, Re, Re + delta * nR, Re - delta * nR]
    Z = np.r_[Z, wall.Z, Ze, Ze + delta * nZ, Ze - delta * nZ]
    on = slice(4000, 4000 + wall.n_vertices + 1 + Re.size)
    off_out = slice(on.stop, on.stop + Re.size)
    off_in = slice(off_out.stop, None)
    ref_in = Path(np.stack([wall.R, wall.Z], axis=1)).contains_points(np.stack([R, Z], 1))
    assert 0.2 < ref_in[:4000].mean() < 0.8  # both sides sampled
    assert not ref_in[off_out].any() and ref_in[off_in].all()
    inside = np.asarray(wall.inside(R, Z))
    np.testing.assert_array_equal(inside[:4000], ref_in[:4000])
    np.testing.assert_array_equal(inside[off_out.start:], ref_in[off_out.start:])
    off = np.r_[:4000, off_out.start:R.size]  # on the polygon itself either answer is right
    np.testing.assert_array_equal(wall.contains(np.stack([R, Z], 1))[off], inside[off])
    sd = np.asarray(wall.signed_distance(R, Z))
    ref = np_signed_distance(R, Z, wall)
    np.testing.assert_allclose(sd[:4000], ref[:4000], rtol=0, atol=1e-14)
    assert np.all((sd[:4000] < 0) == ref_in[:4000])  # negative inside
    assert np.abs(sd[on]).max() <= 1e-15  # zero on the polygon
    # continuous across it: ±δ either side, to the brute force's rounding
    np.testing.assert_allclose(sd[off_out.start:], ref[off_out.start:], rtol=1e-6, atol=0)
    assert np.all(sd[off_out] > 0) and np.all(sd[off_in] < 0) and np.abs(sd[off_out.start:]).max() <= delta * (1 + 1e-6)
    if which == "notched":  # scalar functions: jit of vmap, and a plain scalar call
        sdv = np.asarray(jax.jit(jax.vmap(wall.signed_distance))(R[:100], Z[:100]))
        np.testing.assert_allclose(sdv, sd[:100], rtol=0, atol=1e-15)
        assert bool(wall.inside(R[0], Z[0])) == inside[0]
        assert abs(float(wall.signed_distance(R[0], Z[0])) - sd[0]) <= 1e-15


# ------------------------------------------------------------------- exact toy flows (bookkeeping)
class _ToyField:
    """a = (−x₂, x₁, v) in Cartesian coordinates, (0, 1, v) in (u, φ, Z): a helix of |B|² = R² + v²."""

    def __init__(self, toroidal, v):
        self.v, self.toroidal = v, toroidal
        self.coordinates = "toroidal (u = R²/2, φ, Z)" if toroidal else "cartesian (x1, x2, x3)"

    def __call__(self, x):
        x = jnp.asarray(x)
        o = jnp.ones_like(x[..., 0])
        if self.toroidal:
            return jnp.stack([0 * o, o, self.v * o], -1)
        return jnp.stack([-x[..., 1], x[..., 0], self.v * o], -1)


class _ExactHelix:
    """The exact flow of _ToyField as a method, except that a step crossing Z = 0.4 upwards at R > 1.45
    fails (not converged)."""

    def __init__(self, toroidal, v):
        self.field = _ToyField(toroidal, v)
        self.toroidal, self.v = toroidal, v

    def step_with_status(self, x, h):
        if self.toroidal:
            X = x + h * jnp.array([0.0, 1.0, self.v])
            R = jnp.sqrt(2 * x[0])
        else:
            c, s = jnp.cos(h), jnp.sin(h)
            X = jnp.stack([c * x[0] - s * x[1], s * x[0] + c * x[1], x[2] + self.v * h])
            R = jnp.hypot(x[0], x[1])
        fail = (R > 1.45) & (x[2] <= 0.4) & (X[2] > 0.4)
        return X, jnp.where(fail, RESULTS.not_converged, RESULTS.successful).astype(jnp.int32)


V = 0.05
HELIX = {False: _ExactHelix(False, V), True: _ExactHelix(True, V)}  # one compilation per module
HELIX_WALL = Wall.box(0.5, 1.5, -0.6, 0.6)
HELIX_R0 = np.array([0.8, 1.0, 1.2, 1.4, 0.9, 1.47])  # the last crosses the failure at Z = 0.4 going up
HELIX_Z0 = np.array([-0.213, 0.0071, 0.3033, 0.5517, 0.5937, -0.0137])  # t*/h not an integer
HELIX_PHI0 = np.array([0.0, 3.0, -3.0, 1.0, 2.0, -1.0])


@pytest.mark.parametrize("toroidal", [False, True], ids=["cartesian", "toroidal"])
def test_exact_helix_exit_time_angle_and_length(toroidal):
    """Lines rising at dZ/dt = v while turning at dφ/dt = 1 leave the box Z ≤ Z1 at t* = (Z1 − Z0)/v:
    n, θ, t_exit, the lifted exit φ = φ0 + t* (several turns), the transits t*/2π and the connection
    length |B|t* (|B| constant: the trapezoid rule is exact) are the closed forms to rounding, forwards
    and backwards (h < 0, to the bottom). A line whose step fails keeps that status, no hit, and the
    length to its last good point (k good steps: |B|·k·h)."""
    h, m, wall = 0.1, HELIX[toroidal], HELIX_WALL
    R0, Z0, phi0 = HELIX_R0, HELIX_Z0, HELIX_PHI0
    x0 = (np.stack([R0**2 / 2, phi0, Z0], 1) if toroidal
          else np.stack([R0 * np.cos(phi0), R0 * np.sin(phi0), Z0], 1))
    B = np.hypot(R0, V)
    for sgn, Zw in ((1, 0.6), (-1, -0.6)):
        res = trace_to_wall(m, x0, sgn * h, 400, wall, t0=1.0, progress=False)
        assert isinstance(res, WallHits) and res.h == sgn * h and res.t0 == 1.0 and res.wall is wall
        ok = np.arange(6) < 5 if sgn > 0 else np.ones(6, bool)
        r = np.flatnonzero(ok)
        t_star = (Zw - Z0[r]) / V  # signed
        np.testing.assert_array_equal(res.hit, ok)
        np.testing.assert_array_equal(res.status, np.where(ok, RESULTS.left_domain, RESULTS.not_converged))
        assert not res.fallback.any()
        np.testing.assert_array_equal(res.step[r], np.floor(t_star / (sgn * h)).astype(int))
        np.testing.assert_allclose(res.step[r] + res.theta[r], t_star / (sgn * h), rtol=1e-13)
        np.testing.assert_allclose(res.t_exit[r], 1.0 + t_star, rtol=1e-13)
        np.testing.assert_allclose(res.exit_RZ[r], np.stack([R0[r], np.full(r.size, Zw)], 1), atol=1e-13)
        np.testing.assert_allclose(res.exit_phi[r], phi0[r] + t_star, atol=1e-12)
        np.testing.assert_allclose(res.transits[r], t_star / (2 * np.pi), atol=1e-12)
        np.testing.assert_allclose(res.connection_length[r], B[r] * np.abs(t_star), rtol=1e-13)
        pe = phi0[r] + t_star
        expect = (np.stack([R0[r] ** 2 / 2, pe, np.full(r.size, Zw)], 1) if toroidal
                  else np.stack([R0[r] * np.cos(pe), R0[r] * np.sin(pe), np.full(r.size, Zw)], 1))
        np.testing.assert_allclose(res.exit_point[r], expect, atol=1e-12)
        np.testing.assert_array_equal(res.last_point[r], res.exit_point[r])
        if sgn > 0:  # the failing line: frozen at its last good point, NaN exit data
            k = np.floor((0.4 - Z0[5]) / (V * h))  # good steps before the failing one
            np.testing.assert_allclose(res.connection_length[5], B[5] * k * h, rtol=1e-13)
            np.testing.assert_allclose(res.last_point[5, 2], Z0[5] + V * h * k, atol=1e-13)
            np.testing.assert_allclose(res.transits[5], k * h / (2 * np.pi), atol=1e-12)
            assert res.step[5] == -1 and np.isnan(res.exit_point[5]).all() and np.isnan(res.theta[5])
            assert res.n_failed == 1 and res.n_hit == 5
            s = res.summary()
            assert "5 of 6 line(s) hit the wall" in s and "1 failed: 1 Newton not converged" in s, s
    assert np.abs(t_star).max() > 2 * 2 * np.pi  # the lifted angle went round more than twice
    if toroidal:
        return
    # chunks of lines give the same; with no steps nobody hits, NaN exactly there
    same = trace_to_wall(m, x0, h, 400, wall, chunk_size=4, progress=False)
    fwd = trace_to_wall(m, x0, h, 400, wall, progress=False)
    for f in ("status", "step", "theta", "exit_point", "connection_length", "transits"):
        np.testing.assert_array_equal(getattr(same, f), getattr(fwd, f))
    short = trace_to_wall(m, x0, h, 0, wall, progress=False)
    assert not short.hit.any() and np.all(short.status == RESULTS.successful) and np.all(short.step == -1)
    assert np.all(np.isnan(short.exit_point)) and np.all(np.isnan(short.theta)) and np.all(np.isnan(short.exit_phi))
    np.testing.assert_array_equal(short.connection_length, 0.0)
    np.testing.assert_array_equal(short.last_point, x0)


def test_bad_arguments():
    m = HELIX[False]
    wall = Wall.circle(1.0, 0.0, 0.3)
    x0 = np.array([[1.0, 0.0, 0.0], [0.0, 1.1, 0.1], [1.4, 0.0, 0.0], [1.5, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"x0\[2\] starts outside the wall: its \(R, Z\) = \(1.4, 0\) .* "
                                         r"\(2 of 4 points outside\)"):
        trace_to_wall(m, x0, 0.1, 10, wall)
    with pytest.raises(TypeError, match="wall must be a vpforms Wall"):
        trace_to_wall(m, x0[:2], 0.1, 10, [[1, 2], [0, 0]])

    class NoField:
        def step_with_status(self, x, h):
            return x, 0

    with pytest.raises(TypeError, match=r"needs a method with a \.field"):
        trace_to_wall(NoField(), x0[:2], 0.1, 10, wall)


# ------------------------------------------------------- the tokamak (Cartesian): flux surfaces
R_START = np.array([0.95, 0.9, 0.8, 0.75])  # inner midplane, Z = 0
T_MAX = 40.0  # > 6 poloidal turns
HS = (0.1, 0.05)


def tok_z(R, psi):  # the surface ψ = (R² − 1)²/8 + R²Z²/2 as Z(R) ≥ 0
    return np.sqrt(np.clip((2 * psi - (R**2 - 1) ** 2 / 4) / R**2, 0, None))


def tok_psi(R, Z):
    return (R**2 - 1) ** 2 / 8 + R**2 * Z**2 / 2


def reference(rhs_B, x0, wall, t_max, cylindrical=False):
    """DOP853 (rtol 1e-12) of the line with ∫|B| dt and the lifted φ, stopped by a terminal event on
    the brute-force signed distance: dict(hit, t, point, L, phi) at the exit, or at t_max."""
    def rhs(t, y):
        b = rhs_B(y[:3])
        if cylindrical:  # y = (R, φ, Z), b = (B_R, B_φ, B_Z)
            return [b[0], b[1] / y[0], b[2], np.linalg.norm(b)]
        return [*b, np.linalg.norm(b), (y[0] * b[1] - y[1] * b[0]) / (y[0] ** 2 + y[1] ** 2)]

    def event(t, y):
        R = y[0] if cylindrical else np.hypot(y[0], y[1])
        return float(np_signed_distance(R, y[2], wall))

    event.terminal, event.direction = True, 1
    y0 = [*x0, 0.0] if cylindrical else [*x0, 0.0, np.arctan2(x0[1], x0[0])]
    sol = solve_ivp(rhs, (0, t_max), y0, method="DOP853", rtol=1e-12, atol=1e-13, events=event)
    hit = bool(sol.t_events[0].size)
    t, y = (sol.t_events[0][0], sol.y_events[0][0]) if hit else (sol.t[-1], sol.y[:, -1])
    return {"hit": hit, "t": t, "point": y[:3], "L": y[3], "phi": y[1] if cylindrical else y[4]}


def stack_refs(refs, key, rows):
    return np.array([refs[i][key] for i in rows])


@pytest.fixture(scope="module")
def tok():
    prob = problems.get("tokamak", eps=0)
    assert prob.params["R0"] == 1.0 and prob.params["eps"] == 0.0
    B0 = prob.params["B0"]
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    wall = Wall.box(0.7, 1.3, -0.15, 0.15)
    x0 = np.stack([R_START, 0 * R_START, 0 * R_START], 1)
    runs = {h: trace_to_wall(m, x0, h, round(T_MAX / h), wall, progress=False) for h in HS}

    def B(x):  # the unperturbed field by its formula (module docstring of problems.tokamak)
        R2 = x[0] ** 2 + x[1] ** 2
        return np.array([-x[0] * x[2] - B0 * x[1], -x[1] * x[2] + B0 * x[0], (R2 - 1) / 2 + x[2] ** 2])

    xs = np.random.default_rng(3).uniform(-1, 1, (5, 3))
    np.testing.assert_allclose(np.asarray(prob.field(xs)), np.array([B(x) for x in xs]), atol=1e-14)
    refs = [reference(B, x, wall, T_MAX) for x in x0]
    return {"m": m, "wall": wall, "x0": x0, "runs": runs, "refs": refs}


def check_surfaces(tok):
    """Lines on the flux surfaces fully inside the box stay inside (status successful after > 6
    poloidal turns); those on surfaces that cross it hit, with NaN exit data exactly where not."""
    wall = tok["wall"]
    psi0 = tok_psi(R_START, 0.0)
    margin = np.array([surface_margin(p, R, np.sqrt(1 + np.sqrt(8 * p)), tok_z, wall) for p, R in zip(psi0, R_START)])
    assert np.all(np.abs(margin) > 0.02)  # the classification is unambiguous at the method's accuracy
    crosses = margin > 0
    assert crosses.any() and (~crosses).any()
    np.testing.assert_array_equal([r["hit"] for r in tok["refs"]], crosses)
    for res in tok["runs"].values():
        np.testing.assert_array_equal(res.hit, crosses)
        np.testing.assert_array_equal(res.status, np.where(crosses, RESULTS.left_domain, RESULTS.successful))
        assert np.all(res.step[~crosses] == -1) and np.all(res.step[crosses] >= 0)
        for f in ("theta", "t_exit", "exit_phi"):
            np.testing.assert_array_equal(np.isnan(getattr(res, f)), ~crosses)
        np.testing.assert_array_equal(np.isnan(res.exit_point).any(1), ~crosses)
        np.testing.assert_array_equal(np.isnan(res.exit_RZ).any(1), ~crosses)
        assert not res.fallback.any()
        assert f"{res.n_hit} of {R_START.size} line(s) hit the wall" in res.summary()


def check_exit_steps(tok):
    """Exit point = Ψ_{θh}(x_n) (x_n by n plain steps), on the polygon to the brute-force distance
    (≤ 1e-12), and on its line's own flux surface to the method's O(h²) (ratio ~4 as h halves)."""
    wall, x0 = tok["wall"], tok["x0"]
    step = jax.jit(jax.vmap(tok["m"].without_recovery().step_with_status))
    dpsi = {}
    for h, res in tok["runs"].items():
        rows = np.flatnonzero(res.hit)
        d = np_distance(res.exit_RZ[rows, 0], res.exit_RZ[rows, 1], wall)
        assert d.max() <= 1e-12, d
        np.testing.assert_array_equal(res.exit_RZ[rows, 0], np.hypot(*res.exit_point[rows, :2].T))
        x = x0[rows]
        for n in range(res.step[rows].max()):  # x_n of each line: n steps of the bare method
            X, st = step(x, np.full(rows.size, h))
            assert np.all(np.asarray(st) == RESULTS.successful)
            x = np.where((res.step[rows] > n)[:, None], np.asarray(X), x)
        Y, st = step(x, res.theta[rows] * h)
        np.testing.assert_allclose(np.asarray(Y), res.exit_point[rows], rtol=0, atol=1e-13)
        dpsi[h] = np.abs(tok_psi(*res.exit_RZ[rows].T) - tok_psi(R_START[rows], 0.0))
    ratio = dpsi[HS[0]] / dpsi[HS[1]]
    assert np.all((3.0 <= ratio) & (ratio <= 5.0)), (dpsi, ratio)


def check_order_two(tok):
    """Against DOP853 with a terminal event on the brute-force distance: the connection length, exit
    time, point and lifted φ, and the transits, of the lines that hit, and the length and transits
    of those traced to T, err by O(h²): the error ratio is ~4 as h halves."""
    x0, refs = tok["x0"], tok["refs"]
    phi0 = np.arctan2(x0[:, 1], x0[:, 0])
    errs = {}
    for h, res in tok["runs"].items():
        hit = np.flatnonzero(res.hit)
        ins = np.flatnonzero(~res.hit)
        e = [np.abs(res.connection_length - stack_refs(refs, "L", range(4))),
             np.abs(2 * np.pi * res.transits - (stack_refs(refs, "phi", range(4)) - phi0))]
        e = [*(a[hit] for a in e), *(a[ins] for a in e),
             np.abs(res.t_exit[hit] - stack_refs(refs, "t", hit)),
             np.abs(res.exit_point[hit] - stack_refs(refs, "point", hit)).max(1),
             np.abs(res.exit_phi[hit] - stack_refs(refs, "phi", hit))]
        errs[h] = np.concatenate(e)
    ratio = errs[HS[0]] / errs[HS[1]]
    assert np.all((3.0 <= ratio) & (ratio <= 5.0)), (errs, ratio)


@pytest.mark.slow
def check_native_is_jax(tok):
    """The default backend ran the tokamak natively (``vp_wall``) where a compiler exists; the JAX scan
    stops the same lines at the same steps with the same statuses, and its exits, lengths and transits
    agree to rounding (≤ 1e-10: the same tests and arithmetic, C against XLA)."""
    h = HS[1]
    nat = tok["runs"][h]
    if not vpforms.native.available()[0]:
        assert nat.backend == "jax"
        return
    assert nat.backend == "native", nat.backend_reason
    jx = trace_to_wall(tok["m"], tok["x0"], h, round(T_MAX / h), tok["wall"], progress=False, backend="jax")
    assert jx.backend == "jax"
    for f in ("status", "hit", "step", "fallback"):
        np.testing.assert_array_equal(getattr(nat, f), getattr(jx, f), err_msg=f)
    assert nat.hit.any() and (~nat.hit).any()
    for f in ("theta", "t_exit", "exit_point", "exit_RZ", "exit_phi", "connection_length", "transits", "last_point"):
        a, b = getattr(nat, f), getattr(jx, f)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=f)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10, equal_nan=True, err_msg=f)


def test_tokamak_wall(tok):
    """SE+SE (composed, order 2) on the unperturbed tokamak, a box that cuts some flux surfaces: the
    four checks above in one test, so that the method compiles once (on one xdist worker)."""
    check_surfaces(tok)
    check_exit_steps(tok)
    check_order_two(tok)
    check_native_is_jax(tok)


# ------------------------------------------------------------- a field in (u, φ, Z) coordinates
KAP, Q0, G = 1.5, 1.2, 1.0
C = 1 / (KAP * Q0)


def sol_psi(R, Z):
    return C / 2 * (R**2 * Z**2 + KAP**2 / 4 * (R**2 - 1) ** 2)


def sol_z(R, psi):
    return np.sqrt(np.clip((2 * psi / C - KAP**2 / 4 * (R**2 - 1) ** 2) / R**2, 0, None))


def A_cart(x):  # Solov'ev, A = Ψ∇φ − g ln R ẑ (tests/test_toroidal.py without its perturbation)
    X, Y, Z = x[0], x[1], x[2]
    R2 = X * X + Y * Y
    psi = C / 2 * (R2 * Z * Z + KAP**2 / 4 * (R2 - 1) ** 2)
    return jnp.stack([-psi * Y / R2, psi * X / R2, -0.5 * G * jnp.log(R2)])


def B_cyl(y):  # B_R = −∂ψ/∂Z / R, B_φ = g/R, B_Z = ∂ψ/∂R / R at y = (R, φ, Z), by hand
    R, Z = y[0], y[2]
    return np.array([-C * R * Z, G / R, C * (Z**2 + KAP**2 / 2 * (R**2 - 1))])


@pytest.mark.slow  # ~10 s: building the toroidal field and compiling RK4 on it (its autodiff curl) are the cost;
# the fast tier checks the (u, φ, Z) bookkeeping on the exact helix above
def test_toroidal_coordinates_exit_on_the_polygon_and_length():
    """RK4 in (u, φ, Z) of the axisymmetric Solov'ev field, wall a 64-gon: the lines on surfaces inside
    never hit; the others exit on the polygon (≤ 1e-12) where a cylindrical DOP853 reference does
    (exit point, φ, time and the transits of every line: RK4's O(h⁴), error ratio ≥ 10 as h halves),
    with its connection length ∫|B| dt (|B| from the contravariant a) to O(h²) (ratio ~4)."""
    field = toroidal_field(A_cart, box_from_cylindrical((0.6, 1.4), (0, 2 * np.pi), (-0.5, 0.5)), name="solovev")
    m = vpforms.RK4(field)
    wall = Wall.circle(1.0, 0.0, 0.25, n=64)
    R0 = np.array([0.95, 0.86, 0.8, 0.77])
    phi0 = np.array([0.0, 1.0, -2.0, 3.0])
    psi0 = sol_psi(R0, 0.0)
    margin = np.array([surface_margin(p, R, np.sqrt(1 + np.sqrt(8 * p / (C * KAP**2))), sol_z, wall)
                       for p, R in zip(psi0, R0)])
    assert np.all(np.abs(margin) > 0.01)
    crosses = margin > 0
    assert crosses.any() and (~crosses).any()
    x0 = np.stack([R0**2 / 2, phi0, 0 * R0], 1)
    refs = [reference(B_cyl, (R, p, 0.0), wall, T_MAX, cylindrical=True) for R, p in zip(R0, phi0)]
    np.testing.assert_array_equal([r["hit"] for r in refs], crosses)
    rows = np.flatnonzero(crosses)
    errL, errX = {}, {}
    for h in HS:
        res = trace_to_wall(m, x0, h, round(T_MAX / h), wall, progress=False)
        np.testing.assert_array_equal(res.hit, crosses)
        np.testing.assert_array_equal(res.status, np.where(crosses, RESULTS.left_domain, RESULTS.successful))
        assert np_distance(res.exit_RZ[rows, 0], res.exit_RZ[rows, 1], wall).max() <= 1e-12
        np.testing.assert_array_equal(res.exit_RZ[rows, 0], np.sqrt(2 * res.exit_point[rows, 0]))
        np.testing.assert_allclose(res.exit_phi[rows], res.exit_point[rows, 1], rtol=0, atol=1e-12)  # lifted φ
        ref_RZ = stack_refs(refs, "point", rows)[:, [0, 2]]
        errX[h] = np.concatenate([np.abs(res.exit_RZ[rows] - ref_RZ).max(1),
                                  np.abs(res.exit_phi[rows] - stack_refs(refs, "phi", rows)),
                                  np.abs(res.t_exit[rows] - stack_refs(refs, "t", rows)),
                                  np.abs(2 * np.pi * res.transits - (stack_refs(refs, "phi", range(4)) - phi0))])
        errL[h] = np.abs(res.connection_length - stack_refs(refs, "L", range(4)))
    ratio = errL[HS[0]] / errL[HS[1]]
    assert np.all((3.5 <= ratio) & (ratio <= 4.5)), (errL, ratio)
    assert np.all(errX[HS[0]] / errX[HS[1]] >= 10), errX

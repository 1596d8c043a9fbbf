"""Spline fields on the native backend (issue #20 item 4): the spline of A evaluated in generated C
with its knots and coefficients passed at run time (``vpforms.backends.native.codegen.splines``).

Native and JAX run the same map (the same exact antiderivatives, the same derivatives of the cell
polynomials), so they agree to rounding after 100 steps, with the same statuses — also for a line
that leaves the grid (``RESULTS.left_domain``, not NaN). A second grid of the same structure and
other data reuses the compiled kernel.

One tmp cache directory per module (env ``VPFORMS_NATIVE_CACHE``).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import vpforms as vp
from vpforms._quadrature import DEFAULT_N
from vpforms import RESULTS
from vpforms.backends import select_backend
from vpforms.backends.native.codegen import kernel_parts
from vpforms.backends.native.runner import run_points
from vpforms.grids import cartesian_grid_field
from vpforms.problems.coil_fields import make_stellarator

from ._kernel_reuse import assert_reuses_kernel

_OK, _WHY = vp.native.available()
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


@pytest.fixture(scope="module", autouse=True)
def _cache(isolated_native_cache):
    return isolated_native_cache


def _cartesian(n: int = 8, half: float = 2.0, scale: float = 1.0, shift: float = 0.0):
    """∇×A of a spline of A = (sin(y + 0.3z), cos z + 0.5xz, sin x + 0.2y)·scale on an n³ grid of
    [shift − half, shift + half]³."""
    g = shift + np.linspace(-half, half, n)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"))
    A = scale * np.stack([np.sin(X[1] + 0.3 * X[2]), np.cos(X[2]) + 0.5 * X[0] * X[2],
                          np.sin(X[0]) + 0.2 * X[1]])
    return cartesian_grid_field((g, g, g), A)


@pytest.fixture(scope="module")
def cart():
    return _cartesian()


@pytest.fixture(scope="module")
def stell():
    return make_stellarator(n_R=12, n_phi=8, n_Z=12)


#: three lines inside the Cartesian grid for 100 steps of 0.01, one that leaves it through z = 2
#: (there a_z = z/2 − cos(y + 0.3z) > 0)
CART_X0 = np.array([[0.1, 0.2, 0.3], [-0.3, 0.1, 0.5], [0.4, -0.5, -0.2], [0.0, 0.0, 1.99]])


def _native_vs_jax(m, x0, h, n=100):
    sn = vp.integrate(m, x0, h, n, progress=False, backend="native")
    sj = vp.integrate(m, x0, h, n, progress=False, backend="jax")
    assert sn.stats["backend"] == "native" and sj.stats["backend"] == "jax"
    assert np.array_equal(np.asarray(sn.status), np.asarray(sj.status))
    assert np.array_equal(np.asarray(sn.failed_step), np.asarray(sj.failed_step))
    assert np.all(np.isfinite(np.asarray(sn.xs)))
    return sn, float(np.max(np.abs(np.asarray(sn.xs) - np.asarray(sj.xs))))


def _methods(field):
    se = vp.scheme(field, "SE+SE", recover=False)
    relabelled = next(c for c in vp.cases() if c.cls == "SE+SE" and c != se.case)
    return {
        "SE+SE": se,
        f"SE+SE {relabelled}": vp.scheme(field, relabelled, recover=False),
        "SE+SE order 2": vp.compose(se, order=2),
        "DL+DL fast": vp.scheme(field, "DL+DL", recover=False, fast=True),
        "SE+DL fast": vp.scheme(field, "SE+DL", recover=False, fast=True),
        "RK4": vp.RK4(field),
    }


@pytest.mark.slow  # JAX compiles each method on the spline (~10 s each)
@pytest.mark.parametrize("which", ["cartesian", "toroidal"])
def test_native_equals_jax_after_100_steps_on_spline_fields(which, cart, stell):
    """Every generated class on a Cartesian and a toroidal (coil stellarator) spline field: native
    = JAX ≤ 1e-10 after 100 steps, same statuses and failed steps (the Cartesian line leaving
    the grid: left_domain on both; RK4, which has no domain test, nonfinite on both)."""
    field, x0, h = (cart, CART_X0, 0.01) if which == "cartesian" else (stell.field, stell.x0[:3], 0.02)
    for name, m in _methods(field).items():
        assert select_backend(m, "auto")[0] == "native", name
        sn, err = _native_vs_jax(m, x0, h)
        assert err <= 1e-10, (name, err)
        st = np.asarray(sn.status)
        if which == "cartesian":  # RK4 has no domain test (as on JAX): the NaN step is nonfinite
            out = RESULTS.nonfinite if name == "RK4" else RESULTS.left_domain
            assert list(st) == [RESULTS.successful] * 3 + [out], name
        else:
            assert np.all(st == RESULTS.successful), name


@pytest.mark.slow  # JAX compiles the quadrature correction on the spline (~17 s each)
@pytest.mark.parametrize("cls", ["S1", "S2"])
def test_correction_maps_run_natively_on_a_spline_field_and_equal_jax(cls, cart):
    """S1/S2 (Quispel's correction) on a spline of A: the integrand of f_c evaluates a at
    Q(s) = (x_i + h a_i(P(s)), s, x_k), a spline at a point that holds a spline (evaluated inner
    first in C). 20 native steps = 20 steps of the JAX per-point map ≤ 1e-12, all successful."""
    import jax

    m = vp.scheme(cart, cls, recover=False)
    assert m.integral == f"quadrature(n={DEFAULT_N})" and select_backend(m, "auto")[0] == "native"
    x0, h, n = CART_X0[:3], 0.02, 20
    sn = vp.integrate(m, x0, h, n, progress=False, backend="native")
    step = jax.jit(jax.vmap(lambda p: m._forward(p, h)[:2]))
    x = x0
    for _ in range(n):
        x, st = step(x)
        assert np.all(np.asarray(st) == RESULTS.successful)
    assert np.all(np.asarray(sn.status) == RESULTS.successful)
    assert np.max(np.abs(np.asarray(sn.x_final) - np.asarray(x))) <= 1e-12


def test_a_line_leaving_the_grid_stops_with_left_domain_natively(cart):
    """The native step at the grid's face: the spline is NaN off the grid, the solve fails, and the
    Euler point is off the grid — the lane stops with RESULTS.left_domain at its own step (the
    semantics of ``Method._accept``), its state finite; the other lines run on."""
    m = vp.scheme(cart, "SE+SE", recover=False)
    xs, st, failed, _ = run_points(m, CART_X0, 0.01, np.arange(101))  # the kernel of integrate
    assert list(st) == [RESULTS.successful] * 3 + [RESULTS.left_domain]
    assert 0 <= failed[3] < 100 and list(failed[:3]) == [-1] * 3
    assert np.all(np.isfinite(xs))
    assert cart.grid_potential.contains(xs[:, -1]).all()  # stopped at its last point on the grid
    # the step that fails really leaves: its Euler point x + h a(x) is past z = 2
    x = xs[3, -1]
    assert x[2] + 0.01 * float(np.asarray(cart(x))[2]) > 2.0


@pytest.mark.parametrize("backend", ["native", "jax"])
def test_a_line_leaving_the_grid_is_stopped_not_recovered(cart, backend):
    """Issue #41: ``left_domain`` is a stop, never retried by recovery — every alternative steps the
    same field, which does not exist off the grid (before, each such line went through all ten
    alternatives and the sub-step ladder: 110–150 s of compilations on a coil grid). On both
    backends the recovering method stops the line where the bare one does, and nothing is
    recovered; natively the alternatives are not even built."""
    bare = vp.scheme(cart, "SE+SE", recover=False)
    m = vp.scheme(cart, "SE+SE")
    sol_bare = vp.integrate(bare, CART_X0, 0.01, 100, backend=backend)
    sol = vp.integrate(m, CART_X0, 0.01, 100, backend=backend)
    assert list(sol.status) == [RESULTS.successful] * 3 + [RESULTS.left_domain]
    np.testing.assert_array_equal(sol.status, sol_bare.status)
    np.testing.assert_allclose(sol.xs, sol_bare.xs, rtol=0, atol=1e-12, equal_nan=True)
    assert int(np.asarray(sol.recovered).sum()) == 0
    if backend == "native":
        assert m._built is None  # built on first use (_methods/recover.py): never needed here
    # built when asked: the other SE+SE cases, the other classes' representatives, the sub-step ladder
    others = [c for c in vp.cases() if c.cls == m.case.cls and c != m.case]
    assert len(m.alternatives) == len(others) + len(vp.CLASSES) - 1 + 1 and m._built is not None


def test_a_second_grid_of_the_same_shape_reuses_the_compiled_kernel(cart):
    """Other data (values, extent, hence origin and bounds) of the same structure: the same C
    source, no compilation, the same library — and the kernel steps the second field (one step
    is x + h a₂(x) + O(h²), far from the first field's)."""
    m1 = vp.scheme(cart, "SE+SE", recover=False)
    other = _cartesian(scale=1.7, half=2.5, shift=0.1)
    m2 = vp.scheme(other, "SE+SE", recover=False)
    (s1, d1), (s2, d2) = kernel_parts(m1), kernel_parts(m2)
    assert s1 == s2 and d1.shape == d2.shape and not np.array_equal(d1, d2)
    assert_reuses_kernel(m1, m2, cart, other, CART_X0[:3])


def test_auto_runs_spline_fields_natively_and_says_why_not_otherwise(cart):
    assert select_backend(vp.scheme(cart, "SE+SE", recover=False), "auto") == (
        "native", "auto: native available")
    # a field given as a plain JAX callable: no spline, no SymPy — JAX, with the reason
    f = vp.Field.from_callable(lambda x: x[..., [1, 2, 0]], box=((-1, 1),) * 3, name="shift")
    name, why = select_backend(vp.scheme(f, "SE+SE", recover=False), "auto")
    assert name == "jax" and "JAX callable" in why
    # S1 on a nonlinear field is Quispel's correction map, its integral a quadrature here: native
    assert select_backend(vp.scheme(cart, "S1", recover=False), "auto")[0] == "native"
    # the DL engine form solves L_d through an inner Newton solve: JAX, with the reason
    name, why = select_backend(vp.scheme(cart, "DL+DL", recover=False, fast=False), "auto")
    assert name == "jax" and "engine form" in why


def _torus_points(pot, s):
    """Points on interior knots, on the periodic seam from both sides and far round the torus
    both ways (the grid of ``pot``, the knots of its spline ``s``)."""
    (u0, u1), (p0, p1), (z0, z1) = pot.grid_box
    T = p1 - p0
    tu, tp, tz = (np.asarray(t) for t in s.knots)
    return np.array([
        [tu[6], tp[5], tz[7]],  # interior knots on every axis
        [tu[5], p0, 0.02], [tu[5], p1, 0.02], [tu[6], p1 - 1e-9, tz[6]],  # the seam, both sides
        [tu[8], 0.3 + 1000 * T, 0.03], [tu[8], -0.3 - 50 * T, -0.03],  # far round, both ways
    ])


@pytest.mark.slow  # JAX compiles each case on the spline (~10 s)
@pytest.mark.parametrize("case", [0, 1])
def test_newton_solves_keep_the_cell_exactly_on_seams_knots_and_far_round(stell, case):
    """The implicit SE+SE solves iterate along one axis with the line of the coefficients kept
    while the iterate stays in its cell (``vp_seg``: the cell and the wrap of the periodic axis
    kept, the line's polynomial in y evaluated by Horner). From knots, the seam from both sides
    and a thousand periods round, with a step long enough that iterates cross cells: native = JAX
    to rounding relative to the step, every step successful. Two SE+SE cases whose solves move
    along all three axes between them (u, the periodic φ, Z)."""
    cases = [c for c in vp.cases() if c.cls == "SE+SE"]
    covered = {c.x_plus for c in (cases[0], cases[-1])} | {c.x_circ for c in (cases[0], cases[-1])}
    assert covered == {1, 2, 3}
    f = stell.field
    pot = f.inside.__self__
    x0 = _torus_points(pot, pot.splines[1])
    c = cases[0] if case == 0 else cases[-1]
    m = vp.scheme(f, c, recover=False)
    # the SE step solves for the roles x₊ and x∘ (x₋ explicit): the kept cells move on those axes
    axes = {int(a) for a in re.findall(r"vp_seg\(fd, fd \+ \d+, (\d)", kernel_parts(m)[0])}
    assert axes == {c.x_plus - 1, c.x_circ - 1}
    sn = vp.integrate(m, x0, 0.05, 3, progress=False, backend="native")
    sj = vp.integrate(m, x0, 0.05, 3, progress=False, backend="jax")
    assert sn.stats["backend"] == "native"
    assert np.all(np.asarray(sn.status) == RESULTS.successful)
    assert np.array_equal(np.asarray(sn.status), np.asarray(sj.status))
    dn, dj = np.asarray(sn.xs)[:, -1] - x0, np.asarray(sj.xs)[:, -1] - x0
    # relative to the step, and the resolution of the coordinate itself (φ ≈ 1257 far round:
    # spacing 2.3e-13, where the two backends' sums may round apart)
    assert np.all(np.abs(dn - dj) <= 1e-12 * np.max(np.abs(dj)) + 4 * np.spacing(np.abs(x0) + 1))


@pytest.mark.slow  # JAX compiles RK4 on the spline (~9 s)
def test_c_evaluation_equals_jax_on_knots_faces_and_far_round_the_torus(stell):
    """One RK4 step (four evaluations of a = ∇×A, i.e. of A's first derivatives) from points on
    knots, on the grid's faces, on the periodic seam and a thousand periods round: native = JAX
    to rounding, the same statuses (a step leaving through a face: nonfinite on both)."""
    f = stell.field
    pot = f.inside.__self__  # the SplinePotential (its domain test)
    s = pot.splines[1]
    (u0, u1), (p0, p1), (z0, z1) = pot.grid_box
    T = p1 - p0
    tu, tp, tz = (np.asarray(t) for t in s.knots)
    x0 = np.array([
        [tu[6], tp[5], tz[7]],  # interior knots on every axis
        [u0, 0.1, 0.0], [u1, 0.2, 0.01], [0.5 * (u0 + u1), 0.3, z0], [0.5 * (u0 + u1), 0.0, z1],
        [tu[5], p0, 0.02], [tu[5], p1, 0.02],  # the seam, from both sides
        [tu[8], 0.3 + 1000 * T, 0.03], [tu[8], -0.3 - 50 * T, -0.03],  # far round, both ways
    ])
    m = vp.RK4(f)
    sn = vp.integrate(m, x0, 1e-3, 1, progress=False, backend="native")
    sj = vp.integrate(m, x0, 1e-3, 1, progress=False, backend="jax")
    assert np.array_equal(np.asarray(sn.status), np.asarray(sj.status))
    Xn, Xj = np.asarray(sn.xs)[:, -1], np.asarray(sj.xs)[:, -1]
    dn, dj = Xn - x0, Xj - x0  # the step, h·a(x) + O(h²): compared relative to its own size
    assert np.max(np.abs(dn - dj)) <= 1e-12 * np.max(np.abs(dj))
    assert np.all(np.asarray(sn.status)[[0, 5, 6, 7, 8]] == RESULTS.successful)

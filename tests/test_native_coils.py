"""Filament coils traced directly on the native backend (issue #20, "coils in C"): the coils'
Hanson–Hirshman A as a SymPy atom whose C (one loop over the segments, its derivatives generated
from SymPy) reads the segments at run time (``vpforms.backends.native.codegen.coils``).

The atom's values and derivatives to third order equal ``jax.jacfwd`` of ``segments_A`` to
rounding; native and JAX take the same map (the same Gauss–Legendre gauge integrals, split at whole
periods along φ) and agree to rounding after 20 steps, with the same statuses; a step is volume
preserving to rounding; another coil set — other currents, another number of segments — reuses
the compiled kernel. One tmp cache directory per module (env ``VPFORMS_NATIVE_CACHE``).
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from sympy.core.function import ArgumentIndexError

import vpforms as vp
from vpforms._quadrature import DEFAULT_N
from vpforms import RESULTS
from vpforms.backends import select_backend
from vpforms.backends.native import build as nbuild
from vpforms.backends.native.codegen import data, kernel_parts
from vpforms.backends.native.codegen.assign import _C, _assign
from vpforms.backends.native.codegen.coils import CoilA
from vpforms.backends.native.runner import run_points
from vpforms.coils import Coil, CoilPotential, CoilSet
from vpforms.coils._segments import segments_A
from vpforms.diagnostics.volume import log_det
from vpforms.symbolic import _symbols as G
from vpforms.toroidal import box_from_cylindrical, to_toroidal, toroidal_field

from ._kernel_reuse import assert_reuses_kernel

_OK, _WHY = vp.native.available()
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


@pytest.fixture(scope="module", autouse=True)
def _cache(isolated_native_cache):
    return isolated_native_cache


def _toy(n: int = 8, I_tf: float = 1e6, I_vf: float = 2e5, n_vf: int = 8) -> CoilSet:
    """Four TF coils (n-gons of radius 0.6 about R = 1 in the planes φ = kπ/2) and two vertical-field
    rings (R = 1.8, Z = ±0.8): B_φ ≈ 0.4 T at R = 1 plus a vertical field; nfp = 4."""
    t = 2 * np.pi * np.arange(n) / n
    R, Z = 1.0 + 0.6 * np.cos(t), 0.6 * np.sin(t)
    tf = [Coil(np.c_[R * np.cos(p), R * np.sin(p), Z], I_tf) for p in np.pi / 2 * np.arange(4)]
    s = 2 * np.pi * np.arange(n_vf) / n_vf
    vf = [Coil(np.c_[1.8 * np.cos(s), 1.8 * np.sin(s), np.full(n_vf, z)], I_vf) for z in (0.8, -0.8)]
    return CoilSet(tf + vf, nfp=4)


#: (u, φ, Z) box of R ∈ [0.85, 1.15], |Z| ≤ 0.15 over one period: ≥ 0.45 m from every conductor
_BOX = box_from_cylindrical((0.85, 1.15), (0.0, np.pi / 2), (-0.15, 0.15))
_XYZ0 = np.array([[1.0, 0.0, 0.0], [1.05, 0.01, 0.02], [0.95, -0.02, -0.03]])


def _toroidal(coils):
    return toroidal_field(coils, _BOX, origin=(0.5, 0.0, 0.0), name="toy coils (u, φ, Z)")


@pytest.fixture(scope="module")
def coils():
    return _toy()


@pytest.fixture(scope="module")
def tor(coils):
    return _toroidal(coils)


@pytest.fixture(scope="module")
def cart(coils):
    return vp.Field.from_vector_potential(coils.potential(), box=((0.85, 1.15), (-0.15, 0.15), (-0.15, 0.15)),
                                          origin=(1.0, 0.0, 0.0), name="toy coils (x, y, z)")


# ----------------------------------------------------------------------------- the atom
def _orders(n: int) -> list[tuple[int, int, int]]:
    return [a for a in itertools.product(range(n + 1), repeat=3) if sum(a) <= n]


def _atom_c(coils: CoilSet, alphas: list) -> tuple:
    """A C function vp_eval(N, p, fd, out) evaluating the atoms CoilA(k, α) at N points through the
    emitter's own path (coil_calls, the segment helper, the data array); and its data."""
    with data.collecting() as refs:
        ref = data.DataRef("coils", coils)
        atoms = [CoilA(ref, k, data.code3(a), *G.x) for a in alphas for k in range(3)]
        lines = _assign([f"r{j}" for j in range(len(atoms))], atoms,
                        {G.x[i]: _C[f"x{i + 1}"] for i in range(3)}, "t")
        helpers = "".join(code for _, code in data.emission().helpers.values())
        fd = data.field_data(refs)
    body = "\n        ".join(lines + [f"out[{len(atoms)} * i + {j}] = r{j};" for j in range(len(atoms))])
    src = f"""#include <math.h>
#include <stdint.h>
{helpers}
void vp_eval(int64_t N, const double *p, const double *fd, double *out) {{
    for (int64_t i = 0; i < N; i++) {{
        double x1 = p[3 * i], x2 = p[3 * i + 1], x3 = p[3 * i + 2];
        {body}
    }}
}}
"""
    return src, fd, len(atoms)


def _c_eval(coils: CoilSet, alphas: list, pts: np.ndarray) -> np.ndarray:
    src, fd, n = _atom_c(coils, alphas)
    mod = nbuild.build(src, "void vp_eval(int64_t N, const double *p, const double *fd, double *out);")
    ffi = mod.ffi
    p = np.ascontiguousarray(pts, dtype=np.float64)
    out = np.empty((len(pts), n))
    mod.lib.vp_eval(len(pts), ffi.cast("double *", p.ctypes.data), ffi.cast("double *", fd.ctypes.data),
                    ffi.cast("double *", out.ctypes.data))
    return out.reshape(len(pts), len(alphas), 3)


def test_coil_atom_equals_jax_derivatives_to_third_order(coils):
    """∂^α A_k for every |α| ≤ 3 at points far, near a conductor (1e-3 m), on the extension of a
    segment beyond either end (both branches of each cancellation-free difference), against
    jax.jacfwd of segments_A: ≤ 1e-12 relative to the size of that derivative order at the point."""
    rng = np.random.default_rng(3)
    xi, xf, _ = (np.asarray(a) for a in coils.segments())
    e = (xf - xi) / np.linalg.norm(xf - xi, axis=1)[:, None]
    n = np.cross(e, [0.3, 0.2, 0.9])
    n /= np.linalg.norm(n, axis=1)[:, None]
    s = rng.integers(0, len(xi), 6)
    pts = np.concatenate([
        rng.uniform(-1.5, 1.5, (6, 3)),
        0.5 * (xi[s] + xf[s]) + 1e-3 * n[s],  # near a segment's middle: t, u > 0, ρ small
        xi[s] - 0.05 * e[s] + 1e-4 * n[s],  # behind the start: t < 0
        xf[s] + 0.05 * e[s] + 1e-4 * n[s],  # past the end: u < 0
    ])
    alphas = _orders(3)
    got = _c_eval(coils, alphas, pts)
    segs = coils.segments()

    def A(x):
        return segments_A(x, *segs)

    derivs = [A, jax.jacfwd(A), jax.jacfwd(jax.jacfwd(A)), jax.jacfwd(jax.jacfwd(jax.jacfwd(A)))]
    for i, x in enumerate(pts):
        ref = [np.asarray(d(jnp.asarray(x))) for d in derivs]
        for j, a in enumerate(alphas):
            want = ref[sum(a)][(slice(None), *[ax for ax in range(3) for _ in range(a[ax])])]
            scale = np.max(np.abs(ref[sum(a)]))
            assert np.max(np.abs(got[i, j] - want)) <= 1e-12 * scale, (i, a, got[i, j], want)


# ----------------------------------------------------------------------------- tracing
def _native_vs_jax(m, x0, h, n):
    sn = vp.integrate(m, x0, h, n, progress=False, backend="native")
    sj = vp.integrate(m, x0, h, n, progress=False, backend="jax")
    assert sn.stats["backend"] == "native" and sj.stats["backend"] == "jax"
    assert np.array_equal(np.asarray(sn.status), np.asarray(sj.status))
    assert np.array_equal(np.asarray(sn.failed_step), np.asarray(sj.failed_step))
    return sn, float(np.max(np.abs(np.asarray(sn.xs) - np.asarray(sj.xs))))


@pytest.mark.slow  # JAX compiles the quadrature of the coils' A in each method (~40–180 s each)
# DL+DL in (u, φ, Z) only: its Cartesian twin adds ~2 min of CI and no code path
@pytest.mark.parametrize(("cls", "which"), [("SE+SE", "toroidal"), ("SE+SE", "cartesian"), ("DL+DL", "toroidal")])
def test_native_equals_jax_after_20_steps_on_coils(cls, which, tor, cart):
    """SE+SE and DL+DL (θ-stages, fast=True) on the toy coils, in (u, φ, Z) and in (x, y, z):
    native = JAX ≤ 1e-10 after 20 steps, all successful; in (u, φ, Z) the lines pass φ = 0 into
    the previous period (the gauge integral along φ split at whole periods, w = −1)."""
    field = tor if which == "toroidal" else cart
    x0 = np.asarray(to_toroidal(_XYZ0)) if which == "toroidal" else _XYZ0
    m = vp.scheme(field, cls, recover=False, **({"fast": True} if cls == "DL+DL" else {}))
    assert select_backend(m, "auto") == ("native", "auto: native available")
    sn, err = _native_vs_jax(m, x0, 0.02, 20)
    assert err <= 1e-10, err
    assert np.all(np.asarray(sn.status) == RESULTS.successful)
    if which == "toroidal":
        assert np.asarray(sn.xs)[:, -1, 1].min() < 0  # went round, backwards through φ = 0


@pytest.mark.slow  # JAX compiles one step and its Jacobian (~40 s)
def test_one_step_is_volume_preserving_and_native_takes_it(tor):
    """|det J − 1| ≤ 1e-12 of one SE+SE step (jacfwd of the JAX step), and the native step from
    the same points is that step to rounding."""
    m = vp.scheme(tor, "SE+SE", recover=False)
    x0 = np.asarray(to_toroidal(_XYZ0))
    ld = log_det(m, x0, 0.05, 1)
    assert ld.ok and ld.max_abs <= 1e-12, ld.max_abs
    Xn = run_points(m, x0, 0.05, np.array([0, 1]))[0][:, -1]
    Xj = np.asarray(vp.integrate(m, x0, 0.05, 1, progress=False, backend="jax").xs)[:, -1]
    assert np.max(np.abs(Xn - Xj)) <= 1e-13 * np.max(np.abs(Xj - x0)) + 1e-15


@pytest.mark.slow  # generates and compiles the S1 kernel and RK4's (~20 s)
def test_s1_runs_natively_on_coils_and_is_consistent(tor):
    """S1 (Quispel's correction by quadrature: the coils' A and its derivatives at the Euler point
    Q(s), nested coil evaluations) on the toy coils in C, with no JAX compile: one step differs
    from RK4's by O(h²) (log–log slope of the local error over three h: ≥ 1.8), all succeed, and
    det J = 1 to the central differences' error (≤ 1e-8; without f_c it is 1.2e-4)."""
    m = vp.scheme(tor, "S1", recover=False)
    assert m.integral == f"quadrature(n={DEFAULT_N})" and select_backend(m, "auto")[0] == "native"
    x0 = np.asarray(to_toroidal(_XYZ0))
    hs = np.array([0.04, 0.02, 0.01])
    err = []
    for h in hs:
        X, st = run_points(m, x0, h, np.array([0, 1]))[:2]
        R = run_points(vp.RK4(tor), x0, h, np.array([0, 1]))[0]
        assert np.all(np.asarray(st) == RESULTS.successful)
        err.append(np.max(np.abs(X[:, -1] - R[:, -1])))
    slope = np.polyfit(np.log(hs), np.log(err), 1)[0]
    assert slope >= 1.8, (slope, err)
    for x in x0:  # J by central differences of ε·(|x| + 1e-3) per axis: error O(ε²) ≈ 1e-9
        e = np.diag(1e-5 * (np.abs(x) + 1e-3))
        P = run_points(m, np.concatenate([x + e, x - e]), hs[0], np.array([0, 1]))[0][:, -1]
        J = ((P[:3] - P[3:]) / (2 * np.diag(e))[:, None]).T
        assert abs(np.linalg.det(J) - 1.0) <= 1e-8, np.linalg.det(J) - 1.0


@pytest.mark.slow  # builds two fields (~10 s each) and one kernel
def test_other_coils_reuse_the_compiled_kernel(tor):
    """Other currents, polygons of 6 instead of 8 points (another number of segments): the same C
    source, no compilation, the same library — and the kernel steps the other field (one step is
    x + h a₂(x) + O(h²), far from the first field's)."""
    other = _toroidal(_toy(n=6, I_tf=1.3e6, I_vf=-1e5, n_vf=7))
    m1, m2 = vp.scheme(tor, "SE+SE", recover=False), vp.scheme(other, "SE+SE", recover=False)
    (s1, d1), (s2, d2) = kernel_parts(m1), kernel_parts(m2)
    assert s1 == s2 and d1.shape != d2.shape
    assert_reuses_kernel(m1, m2, tor, other, np.asarray(to_toroidal(_XYZ0)))


def test_auto_picks_native_for_coils_and_says_why_not_otherwise(tor):
    assert select_backend(vp.scheme(tor, "SE+SE", recover=False), "auto") == ("native", "auto: native available")
    # the README's form, toroidal_field(coils.A, …), is the same coil potential
    f = toroidal_field(tor._vector_potentials[0].A_cartesian.coils.A, _BOX, nfp=4, origin=(0.5, 0.0, 0.0))
    assert isinstance(f._vector_potentials[0].A_cartesian, CoilPotential)
    # a Cartesian A given as a plain callable is not coils: JAX, with the reason
    g = toroidal_field(lambda x: jnp.stack([-x[1], x[0], 0.0 * x[2]]) * 0.1, _BOX, nfp=4, origin=(0.5, 0.0, 0.0))
    name, why = select_backend(vp.scheme(g, "SE+SE", recover=False), "auto")
    assert name == "jax" and "neither a spline nor coils" in why


def test_bad_input_is_a_clear_error():
    with pytest.raises(TypeError, match="CoilSet"):
        CoilPotential([[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="orders"):
        data.code3((0, 10, 0))
    with pytest.raises(ArgumentIndexError):
        CoilA(data.DataRef("c", None), 0, data.code3((0, 0, 0)), *G.x).fdiff(2)

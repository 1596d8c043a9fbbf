"""X-points (and O-points) off the scanned line (issue #41 item 5): island_chain finds the chain the
line Z = const crosses, then the chain of the other kind between its consecutive points.

The fast tests use an exactly area-preserving toy map with an m = 2 island chain: each step rotates
(ξ, η) = (R − R0, Z) along the ellipses ξ²/E² + E²η² = r² by ι(r)·h (a twist map, ι = 0.3 + 3.2 r²,
ι = 1/2 at r = 1/4) and then applies the exact flow, for time h, of the resonant perturbation
H₁ = ε Re[(ξ + iη)² e^{−iφ}] (φ frozen at the step's midpoint): a linear map exp(hA) with
A = 2ε [[sin φ, −cos φ], [−cos φ, −sin φ]], A² = 4ε² I, so exp(hA) = cosh(2εh) I + sinh(2εh)/(2ε) A,
det = 1. H₁ has m = 2, n = 1: a 2-island chain where ι = 1/2. Its sign decides which kind the
midplane crosses at φ = 0: with ε > 0 the O-points (so the X-points are off it), with ε < 0 the
X-points (so the O-points are off it). The map commutes with the half-turn (ξ, η) ↦ (−ξ, −η), so
each chain's two points are mirror images through the axis (R0, 0)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, problems
from vpforms.fieldlines import island_chain, magnetic_axis, return_map
from vpforms.fieldlines._axis_search import _value_and_jac
from vpforms.fieldlines._native_map import native_value_and_jac

from .test_fieldlines import TwistField

R0, E = 1.0, 1.3
H = 2 * math.pi / 64


def iota_of(r):
    return 0.3 + 3.2 * r**2


class ToyField(TwistField):
    """The twist field's stand-in (only B^φ is read) on a larger box."""

    box = ((0.5 * 0.4**2, 0.5 * 1.6**2), (0.0, 2 * math.pi), (-0.6, 0.6))


class IslandMethod:
    """The toy map of the module docstring, as a field-line "method" in (u = R²/2, φ, Z)."""

    field = ToyField()
    order = 1

    def __init__(self, eps: float):
        self.eps = eps

    def step_with_status(self, x, h):
        R = jnp.sqrt(2.0 * x[0])
        u, v = (R - R0) / E, x[2] * E
        a = iota_of(jnp.hypot(u, v)) * h
        c, s = jnp.cos(a), jnp.sin(a)
        xi, eta = E * (c * u - s * v), (s * u + c * v) / E
        ph = x[1] + 0.5 * h
        k = 2 * self.eps * h
        sn, cs, ch, sh = jnp.sin(ph), jnp.cos(ph), jnp.cosh(k), jnp.sinh(k)
        xi, eta = ch * xi + sh * (sn * xi - cs * eta), ch * eta + sh * (-cs * xi - sn * eta)
        return jnp.stack([0.5 * (R0 + xi) ** 2, x[1] + h, eta]), jnp.int32(RESULTS.successful)


def _check_chain(m, pts, scanned_kind, off_kind, scan_Z=0.0):
    """Both chains found; every point of the off-line chain is a hyperbolic (X) or elliptic (O)
    fixed point of P² computed here from the map, off the scanned line, interleaved in angle."""
    P = return_map(m, H, guess=(1.2, 0.0))  # the map island_chain used (cached per method): no new compile
    vj = _value_and_jac(P, 2)  # P² and its exact derivative DP² (forward mode through the steps)
    by_kind = {k: [p for p in pts if p.kind == k] for k in ("O", "X")}
    assert len(by_kind[scanned_kind]) == 1 and len(by_kind[off_kind]) == 1  # one chain of each kind
    on, off = by_kind[scanned_kind][0], by_kind[off_kind][0]
    orbit = np.asarray(off.orbit)
    # the chain's points: m = 2 distinct points, each a fixed point of P², the second P(first)
    assert orbit.shape == (2, 2) and np.linalg.norm(orbit[1] - orbit[0]) > 0.1
    z1, st, _ = _value_and_jac(P, 1)(jnp.asarray(orbit[0]))
    assert int(st) == 0 and np.linalg.norm(np.asarray(z1) - orbit[1]) <= 1e-9
    for z in orbit:
        z2, st, J = vj(jnp.asarray(z))
        assert int(st) == 0 and np.linalg.norm(np.asarray(z2) - z) <= 1e-9
        tr = float(np.trace(np.asarray(J)))
        assert (abs(tr) > 2) if off_kind == "X" else (abs(tr) < 2)  # hyperbolic / elliptic
        assert abs(z[1] - scan_Z) > 0.1  # off the scanned line (the chain's half-width is ~0.2)
    # the half-turn symmetry: the two points are mirror images through the axis
    np.testing.assert_allclose(orbit[0] + orbit[1], [2 * R0, 0.0], atol=1e-9)
    # interleaved with the scanned chain: sorted by the angle about the axis, the kinds alternate
    both = [(math.atan2(z[1], z[0] - R0), k) for k, p in ((scanned_kind, on), (off_kind, off)) for z in p.orbit]
    kinds = [k for _, k in sorted(both)]
    assert all(kinds[i] != kinds[(i + 1) % 4] for i in range(4))
    return on, off


def test_x_points_off_the_midplane_are_found_between_the_o_points():
    m = IslandMethod(0.003)
    pts = island_chain(m, 2, H, np.linspace(1.25, 1.4, 16))
    on, off = _check_chain(m, pts, "O", "X")
    assert 0 < on.residue < 1 and (off.residue < 0 or off.residue > 1)
    # without partners: the midplane scan's chain only (the behaviour before issue #41)
    only = island_chain(m, 2, H, np.linspace(1.25, 1.4, 16), partners=False)
    assert [p.kind for p in only] == ["O"]


def test_o_points_off_the_midplane_are_found_between_the_x_points():
    m = IslandMethod(-0.003)
    pts = island_chain(m, 2, H, np.linspace(1.25, 1.4, 16), axis=(R0, 0.0))
    _check_chain(m, pts, "X", "O")


def test_the_axis_is_not_an_island_and_a_bad_axis_is_refused():
    m = IslandMethod(0.003)
    with pytest.raises(ValueError, match=r"axis must be an \(R, Z\) pair"):
        island_chain(m, 2, H, np.linspace(1.25, 1.4, 16), axis=(np.nan, 0.0))
    with pytest.raises(ValueError, match="m must be a positive integer"):
        island_chain(m, 0, H, np.linspace(1.25, 1.4, 16))
    # a scan across the axis finds no 2-chain there (the axis is a fixed point of P, not of period 2)
    assert island_chain(m, 2, H, np.linspace(0.95, 1.05, 5)) == []


# ------------------------------------------------------------------ real methods (verification tier)
@pytest.mark.slow
def test_default_tokamak_m2_x_points_are_found_off_the_midplane():
    """The tokamak problem (ε = 0.01, (m, n) = (2, 1)): at φ = 0 the midplane crosses the O-points;
    the X-points (at φ = 0 above and below the axis) are found between them: fixed points of P²
    with |tr DP²| > 2, two of them, interleaved with the O-points about the axis. Checked on the
    map the search used (native traces through two periods, DP² by central differences), and
    against the JAX map's P² (two restarts at the crossing) within the integrator's own error."""
    prob = problems.get("tokamak", coordinates="toroidal")
    m = vpforms.compose(vpforms.scheme(prob.field, "SE+SE"), order=2)
    axis = magnetic_axis(m, prob.axis_guess, 0.05)
    pts = island_chain(m, 2, 0.05, np.linspace(1.2, 1.36, 17), axis=axis)
    O = [p for p in pts if p.kind == "O"]
    X = [p for p in pts if p.kind == "X"]
    assert len(O) == 1 and len(X) == 1
    P = return_map(m, 0.05, guess=(1.29, 0.0))
    vj = native_value_and_jac(P, 2)
    xs = np.asarray(X[0].orbit)
    assert xs.shape == (2, 2) and np.linalg.norm(xs[0] - xs[1]) > 0.1  # two X-points: the chain's m
    for z in xs:
        z2, st, J = vj(z)
        assert int(st) == 0 and np.linalg.norm(z2 - z) <= 1e-9
        assert abs(np.trace(J)) > 2 and abs(np.linalg.det(J) - 1) <= 1e-5
        # the JAX map's P² (restarted at the first crossing): another O(h²) discretisation of the
        # same P², 3e-6 away at h = 0.05 (order 2) — a fixed point of it to that accuracy
        zj, st = P.power(jnp.asarray(z), 2)
        assert int(st) == 0 and np.linalg.norm(np.asarray(zj) - z) <= 1e-5
        assert abs(z[1] - axis.Z) > 0.1  # off the midplane
    for z in np.asarray(O[0].orbit):  # the O-points too: elliptic fixed points of the same P²
        z2, st, J = vj(z)
        assert int(st) == 0 and np.linalg.norm(z2 - z) <= 1e-9 and abs(np.trace(J)) < 2
    ang = sorted((math.atan2(z[1] - axis.Z, z[0] - axis.R), p.kind) for p in O + X for z in p.orbit)
    assert all(ang[i][1] != ang[(i + 1) % 4][1] for i in range(4))

"""Two coil sets built in code: a circular tokamak and a classical l = 2 stellarator.

Both are vacuum fields of filamentary coils (SI: m, A, T) with regions of closed nested flux
surfaces; the axis positions and rotational transforms quoted in the docstrings were measured by
tracing field lines (tests/test_coils.py: ``python -m tests.test_coils`` prints them again).

Conventions: cylindrical (R, φ, Z), right-handed; the poloidal angle θ about the magnetic axis
(R_ax, Z_ax) of the φ section is θ = atan2(−(Z − Z_ax), R − R_ax), so that (r, θ, φ) is
right-handed, and the rotational transform is ι = lim Δθ/Δφ (q = 1/ι).
"""

from __future__ import annotations

import math

import numpy as np

from ._coilset import Coil, CoilSet
from ._segments import MU0

__all__ = ["circular_tokamak", "l2_stellarator"]


def _tf_coils(R0: float, radius: float, n: int, points: int, current: float) -> list[Coil]:
    """n planar circular coils of ``radius`` centred on the circle R = R0, in the planes φ = 2πk/n,
    oriented so that a positive current gives B_φ > 0 inside (the loop's normal is +e_φ)."""
    th = 2 * np.pi * np.arange(points) / points
    # clockwise in the (R, Z) half-plane: normal e_R × (−e_Z) = +e_φ
    R, Z = R0 + radius * np.cos(th), -radius * np.sin(th)
    coils = []
    for k in range(n):
        phi = 2 * np.pi * k / n
        coils.append(Coil(np.c_[R * np.cos(phi), R * np.sin(phi), Z], current, 1, f"TF{k + 1}"))
    return coils


def _ring(R: float, Z: float, points: int, current: float, group: int, name: str) -> Coil:
    """A horizontal regular polygon inscribed in the circle of radius R at height Z (a vertex at
    φ = 0), current along +e_φ."""
    phi = 2 * np.pi * np.arange(points) / points
    return Coil(np.c_[R * np.cos(phi), R * np.sin(phi), np.full(points, Z)], current, group, name)


def _vf_pair(radius: float, height: float, points: int, current: float) -> list[Coil]:
    """Two rings at Z = ±height with the same current: a vertical field B_Z ≈ μ0 I R²/(R² + Z²)^{3/2}
    near the origin (positive for a positive current)."""
    return [_ring(radius, z, points, current, 3, f"VF{k + 1}") for k, z in enumerate((height, -height))]


def _positive_int(value: int, what: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{what} must be an integer ≥ {minimum}; got {value!r}")
    return int(value)


def _positive(value: float, what: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{what} must be a positive number; got {value!r}")
    return v


def circular_tokamak(*, R0: float = 1.0, B0: float = 1.0, n_coils: int = 16, coil_radius: float = 0.6,
                     points_per_coil: int = 64, plasma_current: float = 70e3, ring_points: int = 128,
                     vf_current: float = 0.0, vf_radius: float = 1.8, vf_height: float = 0.8,
                     vf_points: int = 128) -> CoilSet:
    r"""A circular tokamak: toroidal-field coils, a plasma-current filament ring, optional vertical field.

    * ``n_coils`` planar circular toroidal-field (TF) coils of radius ``coil_radius``, centred on the
      circle R = R0, in the planes φ = 2πk/n_coils, each a regular polygon of ``points_per_coil``
      vertices carrying I_TF = 2πR0·B0/(μ0·n_coils). Ampère's law on a circle R = const inside the
      windings gives the axisymmetric part B_φ = μ0·n_coils·I_TF/(2πR) = B0·R0/R; the finite
      number of coils adds a ripple.
    * A filament ring (``ring_points``-gon inscribed in R = R0, Z = 0) carrying the plasma current
      I_p = ``plasma_current`` along +e_φ. Near it the poloidal field is B_θ ≈ μ0 I_p/(2πr) (r the
      distance from the ring), so the safety factor is q = rB_φ/(R0 B_θ) ≈ 2πr²B0/(μ0 I_p R0)
      (cylindrical estimate; q ∝ r²). In the axisymmetric approximation the field lines lie on the
      surfaces ψ = R·A_φ = const, which are closed and nested around the ring: the magnetic axis is
      the ring itself (a singular filament, the limit of the nested surfaces), and the surfaces
      are shifted outward (the ring's poloidal field is stronger on its inboard side).
    * With ``vf_current`` ≠ 0 a pair of rings of radius ``vf_radius`` at Z = ±``vf_height``
      (``vf_points``-gons, same current): a vertical field B_Z ≈ μ0 I_VF R²/(R² + Z²)^{3/2} at the
      centre. It shifts the surfaces (and, where it cancels the ring's poloidal field, makes an
      X-point); not characterised here, the default is none.

    The set is stellarator symmetric (each coil maps to itself, (R, φ, Z) → (R, −φ, −Z) with the
    current reversed) and periodic with nfp = gcd(n_coils, ring_points[, vf_points]).

    Measured with the defaults (field lines started at (R, Z) = (R0 + r, 0), φ = 0, RK4 in φ with
    16 steps per field period, 20 toroidal turns; θ about the ring and ι fitted to the section
    crossings, module docstring; ``python -m tests.test_coils``):

    ======  =======  ======  ==================================================
    r (m)   ι        q       distance from the ring on that surface, min–max (m)
    ======  =======  ======  ==================================================
    0.10    1.8381   0.544   0.0741–0.1000
    0.15    0.8816   1.134   0.1014–0.1500
    0.20    0.5264   1.900   0.1253–0.2000
    0.25    0.3535   2.829   0.1467–0.2500
    0.30    0.2551   3.920   0.1664–0.3000
    0.40    0.1505   6.646   0.2027–0.4000
    0.45    0.1199   8.338   0.2210–0.4500
    ======  =======  ======  ==================================================

    so q ≈ 1.5–4 for the surfaces through R0 + 0.18 … R0 + 0.30 m (q ∝ r² roughly: a single
    filament cannot give q in 1.5–4 over the whole range 0.1–0.3 m). Every line started at
    r = 0.10–0.45 m lies on a closed curve around the ring in the φ = 0 section (Fourier fit of the
    section points to ≤ 1.3e-4 of the curve's size), the curves are nested, and they are shifted
    outward: the closed nested surfaces fill at least the region within 0.45 m outboard / 0.22 m
    inboard of the ring (the TF coils are at 0.6 m). Lines must be started away from the singular
    filament and need smaller steps near it (r = 0.05: ι = 6.606, q = 0.151 with 64 steps per
    period). B_φ(R0 + 0.2, φ = 0, Z = 0) = 0.847 T in the plane of a coil, against B0·R0/R = 0.833 T: the
    ripple there is ≈ 2 %.

    Parameters
    ----------
    R0, B0 : float
        Major radius (m) of the TF coils' centres and of the plasma ring; the axisymmetric toroidal
        field B0 (T) at R = R0. Defaults 1 m, 1 T.
    n_coils, coil_radius, points_per_coil : int, float, int
        Number of TF coils (16), their radius (0.6 m), vertices per coil (64).
    plasma_current, ring_points : float, int
        The ring's current in A (70 kA) and vertices (128).
    vf_current, vf_radius, vf_height, vf_points : float, float, float, int
        Vertical-field pair: current in A (0: no pair), radius (1.8 m), half-separation (0.8 m),
        vertices (128).

    Returns
    -------
    CoilSet
        TF coils (group 1, names TF1…), the ring (group 2, "plasma"), the VF pair (group 3).
    """
    R0, B0, a = _positive(R0, "R0"), float(B0), _positive(coil_radius, "coil_radius")
    if a >= R0:
        raise ValueError(f"coil_radius must be smaller than R0; got {a} ≥ {R0}")
    n_coils = _positive_int(n_coils, "n_coils")
    points_per_coil = _positive_int(points_per_coil, "points_per_coil", 3)
    ring_points = _positive_int(ring_points, "ring_points", 3)
    I_tf = 2 * math.pi * R0 * B0 / (float(MU0) * n_coils)  # Ampère: μ0 N I_TF = 2π R0 B0
    coils = _tf_coils(R0, a, n_coils, points_per_coil, I_tf)
    coils.append(_ring(R0, 0.0, ring_points, float(plasma_current), 2, "plasma"))
    nfp = math.gcd(n_coils, ring_points)
    if vf_current:
        vf_points = _positive_int(vf_points, "vf_points", 3)
        coils += _vf_pair(_positive(vf_radius, "vf_radius"), float(vf_height), vf_points, float(vf_current))
        nfp = math.gcd(nfp, vf_points)
    return CoilSet(coils, nfp=nfp, stellsym=True)


def l2_stellarator(*, R0: float = 1.0, B0: float = 1.0, m: int = 5, l: int = 2, n_tf: int = 20,
                   tf_radius: float = 0.6, points_per_tf: int = 64, helical_radius: float = 0.3,
                   helical_current: float = 160e3, points_per_period: int = 24, vf_current: float = 0.0,
                   vf_radius: float = 1.8, vf_height: float = 0.8, vf_points: int = 120) -> CoilSet:
    r"""A classical l-pole stellarator (default l = 2, m = 5): TF coils plus helical windings.

    * ``n_tf`` circular toroidal-field coils as in :func:`circular_tokamak` (radius ``tf_radius``,
      I_TF = 2πR0·B0/(μ0·n_tf), B_φ ≈ B0·R0/R); n_tf should be a multiple of m.
    * 2l helical conductors on the torus of minor radius a_h = ``helical_radius`` about the circle
      R = R0, Z = 0: conductor j = 0, …, 2l−1 follows

          θ_j(φ) = ((j + 1)π − mφ)/l,   (R, Z) = (R0 + a_h cos θ, a_h sin θ),

      and carries (−1)^j·I_h along +φ (alternating currents: an l-pole helical field
      ∝ cos(lθ + mφ), m field periods). Going once round the torus moves conductor j to
      j − 2m (mod 2l), of the same sign, so the conductors join into closed windings that go round
      l/gcd(m, l) times (for l = 2, m = 5: two windings, each twice round the torus, with currents
      ±I_h). Half the conductors carry +I_h and half −I_h: the windings' net toroidal current and
      net poloidal current are zero (checked with Ampère's law in the tests).
      Polylines of ``points_per_period`` vertices per field period per toroidal turn.
    * Optionally a vertical-field pair (as in :func:`circular_tokamak`, ``vf_current`` ≠ 0, default
      none) to move the axis: it shifts outward for vf_current > 0.

    The l = 2 field gives a rotational transform of second order in the helical field amplitude,
    finite on the axis (ι(0) grows about as I_h²) with weak shear, and elliptical surfaces rotating with φ. The set
    is periodic with nfp = m and stellarator symmetric ((θ, φ) → (−θ, −φ) maps conductor j to
    −j − 2 (mod 2l), of the same sign, traversed backwards).

    Measured with the defaults (``python -m tests.test_coils``): the magnetic axis (fixed point of
    the φ → φ + 2π/5 return map, DOP853 rtol 1e-10 and scipy.optimize.root) crosses φ = 0 at
    R_ax = 0.983112 m, Z_ax = 0 (inward toroidal shift 1.7 cm; a vertical-field pair with
    vf_current ≈ 8.2 kA centres it on R0). Lines started at (R_ax + r, 0), φ = 0, traced over
    40 turns (RK4, 24 steps per period; ι fitted to the section crossings, module docstring):

    ======  =======  ===================================
    r (m)   ι        distance from the axis, min–max (m)
    ======  =======  ===================================
    0.02    0.31215  0.0119–0.0207
    0.04    0.31328  0.0241–0.0427
    0.08    0.32017  0.0483–0.0908
    0.12    0.34203  0.0707–0.1432
    0.14    0.36540  0.0804–0.1694
    0.16    0.40359  0.0884–0.1944
    ======  =======  ===================================

    ι(0) ≈ 0.312 (close to 5/16) with weak positive shear. At φ = 0 the surfaces are ellipses
    elongated horizontally about 1.7 : 1 (the long axis turns with the helical field). Lines started
    at r ≤ 0.14 m lie on smooth closed curves (Fourier fit of the section points to ≤ 2.2e-3 of the
    curve's size); r = 0.15–0.17 m stay confined but are not on single smooth curves (misfit
    1–5 %: island chains, e.g. near ι = 5/13, 5/12, and a thin stochastic edge); the line started at
    r = 0.18 m escapes towards the coils: the confined region ends between 0.17 and 0.18 m from the
    axis on the outboard midplane (≈ 0.21 m along the long axis of the section).

    Parameters
    ----------
    R0, B0 : float
        Major radius (1 m) and axisymmetric toroidal field at R0 (1 T).
    m, l : int
        Field periods (5) and pole number (2).
    n_tf, tf_radius, points_per_tf : int, float, int
        TF coils: number (20), radius (0.6 m), vertices (64).
    helical_radius, helical_current, points_per_period : float, float, int
        Helical windings: minor radius a_h (0.3 m), current I_h (160 kA), vertices per field period
        per turn (24).
    vf_current, vf_radius, vf_height, vf_points : float, float, float, int
        Optional vertical-field pair (0 A: none; 1.8 m, ±0.8 m, 120 vertices).

    Returns
    -------
    CoilSet
        TF coils (group 1), helical windings (group 2, names HEL…), VF pair (group 3); nfp = m.
    """
    R0, B0 = _positive(R0, "R0"), float(B0)
    a_tf, a_h = _positive(tf_radius, "tf_radius"), _positive(helical_radius, "helical_radius")
    if not a_h < a_tf < R0:
        raise ValueError(f"need helical_radius < tf_radius < R0; got {a_h}, {a_tf}, {R0}")
    m, l = _positive_int(m, "m"), _positive_int(l, "l")
    n_tf = _positive_int(n_tf, "n_tf")
    points_per_tf = _positive_int(points_per_tf, "points_per_tf", 3)
    points_per_period = _positive_int(points_per_period, "points_per_period", 3)
    I_tf = 2 * math.pi * R0 * B0 / (float(MU0) * n_tf)  # Ampère: μ0 N I_TF = 2π R0 B0
    coils = _tf_coils(R0, a_tf, n_tf, points_per_tf, I_tf)
    turns = l // math.gcd(m, l)  # a conductor closes after this many toroidal turns
    P = turns * m * points_per_period
    s = 2 * np.pi * turns * np.arange(P) / P  # the toroidal angle along a winding
    done: set[int] = set()
    for j in range(2 * l):
        if j in done:
            continue
        done |= {(j + 2 * m * k) % (2 * l) for k in range(turns)}  # the conductors this winding joins
        th = ((j + 1) * np.pi - m * s) / l  # θ_j(φ) = ((j + 1)π − mφ)/l, continued over the turns
        R, Z = R0 + a_h * np.cos(th), a_h * np.sin(th)
        current = (-1.0) ** j * float(helical_current)
        coils.append(Coil(np.c_[R * np.cos(s), R * np.sin(s), Z], current, 2, f"HEL{j + 1}"))
    if vf_current:
        vf_points = _positive_int(vf_points, "vf_points", 3)
        coils += _vf_pair(_positive(vf_radius, "vf_radius"), float(vf_height), vf_points, float(vf_current))
    return CoilSet(coils, nfp=m, stellsym=True)

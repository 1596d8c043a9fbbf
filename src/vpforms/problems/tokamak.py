"""A toroidal magnetic-field-line model with magnetic islands (field lines x' = B(x)).

Cartesian x = (x₁, x₂, x₃), R² = x₁² + x₂², the major axis is the x₃ axis, φ the toroidal angle.

    B = B_pol + B_tor + ε ∇×(χ (−x₂, x₁, 0)),
    B_pol = (−x₁x₃, −x₂x₃, (R² − R₀²)/2 + x₃²)          = ∇ψ × ∇φ,
    ψ     = (R² − R₀²)²/8 + R²x₃²/2                       (Solov'ev-type flux function),
    B_tor = (B₀/R₀)(−x₂, x₁, 0),
    χ     = Re[w^m (x₁ − i x₂)^n] / R₀ⁿ,   w = (R² − R₀²)/(2R₀) + i x₃  (≈ ρ e^{iθ} near the axis).

* B_pol is the poloidal field of the Solov'ev flux function ψ (L. S. Solov'ev, Sov. Phys. JETP 26
  (1968) 400; the standard analytic tokamak equilibrium), written so that it is a polynomial:
  nested flux surfaces ψ = const around the magnetic axis R = R₀, x₃ = 0, closed for
  ψ < R₀⁴/8 (the midplane separatrix is at R = √2 R₀).
* B_tor is a toroidal field ∝ R (a rigid-rotation profile) instead of the physical ∝ 1/R, so that
  the whole field is a polynomial, smooth everywhere including the axis R = 0.  div B_tor = 0.
  Near the magnetic axis the safety factor is q₀ = B₀/R₀²; q increases outwards and diverges at
  the separatrix (the poloidal motion is independent of B₀, so q(ψ) ∝ B₀ exactly).
* The perturbation is a helical (m, n) change of poloidal flux, δψ = ε R²χ ∝ ρ^m cos(mθ − nφ);
  as a curl it is divergence free identically.  It is resonant on the surface q = m/n and
  opens a chain of m magnetic islands there.  Defaults: R₀ = 1, B₀ = 1.8, (m, n) = (2, 1),
  ε = 0.01.  The safety factor of the unperturbed field has a closed form (:func:`safety_factor`):
  with u = R²/2 the poloidal motion is Hamiltonian in (u, x₃) with H = ψ, its period is a
  complete elliptic integral, and at R = a = R₀ + ρ in the outer midplane
  q = 2B₀K(m)/(π R₀ a), m = 2(1 − R₀²/a²): q = 1.804, 1.873, 2.024, 2.737 at ρ = 0.05, 0.2, 0.3,
  0.4 (tests/test_problems.py checks it against a traced field line), and a Poincaré
  section x₂ = 0 of the default field shows the two m = 2 islands with O-points near R ≈ 1.29
  and R ≈ 0.56 (x₃ = 0), each roughly 0.1–0.15 R₀ wide, between intact flux surfaces.

div B = 0 identically in Cartesian coordinates (checked symbolically by :class:`vpforms.Field`);
all potentials are polynomial closed forms.  The model is this library's own construction in the
usual flux-function form B = ∇ψ×∇φ + B_tor + δB of tokamak field-line studies.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import sympy as sp
from scipy.special import ellipk

from .._polygon import Wall
from ..fields import SYMBOLS, Field
from ._base import Problem, invariant_callables, real_param

__all__ = ["make", "default", "DEFAULTS", "flux_function", "safety_factor", "toroidal_exprs"]

DEFAULTS = {"R0": sp.Integer(1), "B0": sp.Rational(9, 5), "eps": sp.Rational(1, 100), "m": 2, "n": 1}
SOURCE = (
    "Solov'ev flux function (L. S. Solov'ev, Sov. Phys. JETP 26 (1968) 400) with a polynomial "
    "toroidal field and a helical (m, n) flux perturbation; model constructed in vpforms"
)


def flux_function(R0, symbols=SYMBOLS):
    """The unperturbed poloidal flux ψ (an invariant of the field lines when ε = 0)."""
    x1, x2, x3 = symbols
    R2 = x1**2 + x2**2
    return (R2 - R0**2) ** 2 / 8 + R2 * x3**2 / 2


def safety_factor(rho, R0=1.0, B0=1.8):
    """q of the unperturbed field (ε = 0) on the flux surface through R = R₀ + ρ, x₃ = 0.

    In u = R²/2 the poloidal motion is u' = −∂ψ/∂x₃, x₃' = ∂ψ/∂u with ψ = (2u − R₀²)²/8 + u x₃², and
    φ' = B₀/R₀ (B_tor/R is constant), so q = (B₀/R₀)·T/(2π) with T = ∮ du/(u x₃) the poloidal
    period. On the surface, u x₃² = ψ − (2u − R₀²)²/8 = ½ u (u − u₁)(u₂ − u), u₁,₂ = R₀²/2 ∓ √(2ψ),
    so T = 2√2 K(m)/√u₂ with m = (u₂ − u₁)/u₂ (Byrd–Friedman 233.00); at x₃ = 0, R = a:
    u₂ = a²/2 and q = 2B₀K(m)/(π R₀ a), m = 2(1 − R₀²/a²). Valid for 0 < ρ < (√2 − 1)R₀ (m < 1,
    inside the separatrix)."""
    rho = np.asarray(rho, float)
    a = R0 + rho
    m = 2.0 * (1.0 - R0**2 / a**2)
    if np.any((m <= 0) | (m >= 1)):
        raise ValueError(f"safety_factor needs 0 < ρ < (√2 − 1)·R0 = {(np.sqrt(2) - 1) * R0:.4g}")
    return 2.0 * B0 * ellipk(m) / (np.pi * R0 * a)


def exprs(R0, B0, eps, m, n, symbols=SYMBOLS):
    x1, x2, x3 = symbols
    R2 = x1**2 + x2**2
    Bpol = (-x1 * x3, -x2 * x3, (R2 - R0**2) / 2 + x3**2)
    Btor = (-B0 / R0 * x2, B0 / R0 * x1, 0)
    w = (R2 - R0**2) / (2 * R0) + sp.I * x3
    chi = sp.re(sp.expand(w**m * (x1 - sp.I * x2) ** n)) / R0**n
    chi = sp.expand(chi)
    A = (-chi * x2, chi * x1, sp.Integer(0))
    curlA = (
        sp.diff(A[2], x2) - sp.diff(A[1], x3),
        sp.diff(A[0], x3) - sp.diff(A[2], x1),
        sp.diff(A[1], x1) - sp.diff(A[0], x2),
    )
    return tuple(sp.expand(p + t + eps * c) for p, t, c in zip(Bpol, Btor, curlA))


#: the toroidal coordinates of unit Jacobian of :mod:`vpforms.toroidal`: u = R²/2, φ, Z
TOROIDAL_SYMBOLS = (sp.Symbol("u", positive=True), sp.Symbol("phi", real=True), sp.Symbol("Z", real=True))


def toroidal_exprs(cartesian, symbols=SYMBOLS, toroidal_symbols=TOROIDAL_SYMBOLS):
    """The flow (a¹, a², a³) = (R B_R, B_φ/R, B_Z) in (u = R²/2, φ, Z) of a Cartesian field B
    (:mod:`vpforms.toroidal`: Jacobian 1, so div stays div). For this model with ε = 0 it is the
    polynomial (−2uZ, B₀/R₀, u − R₀²/2 + Z²)."""
    x1, x2, x3 = symbols
    u, ph, Z = toroidal_symbols
    R = sp.sqrt(2 * u)
    sub = {x1: R * sp.cos(ph), x2: R * sp.sin(ph), x3: Z}
    B1, B2, B3 = (b.subs(sub) for b in cartesian)
    a1 = R * sp.cos(ph) * B1 + R * sp.sin(ph) * B2
    a2 = (R * sp.cos(ph) * B2 - R * sp.sin(ph) * B1) / (2 * u)
    return tuple(sp.simplify(sp.expand(a)) for a in (a1, a2, B3))


def make(R0=None, B0=None, eps=None, m=None, n=None, coordinates: str = "cartesian") -> Problem:
    """The field-line model; see the module docstring for the parameters.

    ``coordinates="toroidal"`` gives the same field lines in the coordinates (u = R²/2, φ, Z) of unit
    Jacobian (:mod:`vpforms.toroidal`), where the magnetic axis of ε = 0 is the line u = R₀²/2,
    Z = 0 and the field there (0, B₀/R₀, 0) is a translation in φ that every method steps exactly."""
    if coordinates not in ("cartesian", "toroidal"):
        raise ValueError(f"coordinates must be 'cartesian' or 'toroidal'; got {coordinates!r}")
    p = dict(DEFAULTS)
    p.update({k: v for k, v in dict(R0=R0, B0=B0, eps=eps, m=m, n=n).items() if v is not None})
    R0, B0, eps = (real_param(k, p[k]) for k in ("R0", "B0", "eps"))
    m, n = p["m"], p["n"]
    if not (isinstance(m, (int, np.integer)) and isinstance(n, (int, np.integer)) and m >= 1 and n >= 0):
        raise ValueError(f"mode numbers must be integers m ≥ 1, n ≥ 0; got m={m!r}, n={n!r}")
    for k, v in (("R0", R0), ("B0", B0), ("eps", eps)):
        if v.free_symbols or not v.is_real:
            raise ValueError(f"parameter {k} must be a real number; got {v}")
    if not R0 > 0:
        raise ValueError(f"R0 must be positive; got {R0}")
    r0 = float(R0)
    toroidal = coordinates == "toroidal"
    cart = exprs(R0, B0, eps, int(m), int(n))
    inv = {}
    if toroidal:
        box = ((0.5 * (0.5 * r0) ** 2, 0.5 * (1.5 * r0) ** 2), (0.0, 2 * np.pi), (-0.75 * r0, 0.75 * r0))
        field = Field.from_sympy(toroidal_exprs(cart), TOROIDAL_SYMBOLS, name="tokamak (u, φ, Z)", box=box)
        field.coordinates = "toroidal (u = R²/2, φ, Z)"
        field.periods = (None, 2 * np.pi, None)
        if eps == 0:
            u, _, Z = TOROIDAL_SYMBOLS
            inv["psi"] = (2 * u - R0**2) ** 2 / 8 + u * Z**2  # ψ of flux_function with R² = 2u
    else:
        box = ((-1.5 * r0, 1.5 * r0), (-1.5 * r0, 1.5 * r0), (-0.75 * r0, 0.75 * r0))
        field = Field.from_sympy(cart, SYMBOLS, name="tokamak", box=box)
        if eps == 0:
            inv["psi"] = flux_function(R0)
    rho = np.array([0.1, 0.2, 0.25, 0.3, 0.35]) * r0
    x0 = np.stack([r0 + rho, np.zeros_like(rho), np.zeros_like(rho)], axis=1)
    if toroidal:
        x0[:, 0] = 0.5 * x0[:, 0] ** 2

    def sampler(rng, k):  # inside the flux surfaces: ρ ≤ 0.35 R₀ around the magnetic axis
        rr = 0.35 * r0 * np.sqrt(rng.random(k))
        th = 2 * np.pi * rng.random(k)
        ph = 2 * np.pi * rng.random(k)
        R = r0 + rr * np.cos(th)
        if toroidal:
            return np.stack([0.5 * R * R, ph, rr * np.sin(th)], axis=1)
        return np.stack([R * np.cos(ph), R * np.sin(ph), rr * np.sin(th)], axis=1)

    params = {"R0": r0, "B0": float(B0), "eps": float(eps), "m": int(m), "n": int(n)}
    return Problem(
        name="tokamak",
        field=field,
        params=params,
        x0=x0,
        invariants=invariant_callables(inv, TOROIDAL_SYMBOLS if toroidal else SYMBOLS),
        invariant_exprs=inv,
        source=SOURCE,
        periodic=field.periods if toroidal else None,
        box=box,
        description=f"toroidal field-line model with ({m},{n}) islands",
        sampler=sampler,
        axis_guess=(r0, 0.0),
        wall=default_wall(r0),
    )


#: ψ of the default wall, in units of R₀⁴: inside the separatrix ψ = R₀⁴/8
WALL_PSI = 0.11


def default_wall(R0: float = 1.0, n: int = 48) -> Wall:
    """The default wall: the (R, Z) polygon through 2n points of the unperturbed flux surface
    ψ = 0.11 R₀⁴, just inside the separatrix ψ = R₀⁴/8 (a limiter on the last closed surfaces):
    R from √(R₀² ∓ √(8ψ)) (0.249 R₀ … 1.392 R₀ on the midplane), Z = ±√((2ψ − (R² − R₀²)²/4)/R²)."""
    psi = WALL_PSI * R0**4
    lo, hi = math.sqrt(R0**2 - math.sqrt(8 * psi)), math.sqrt(R0**2 + math.sqrt(8 * psi))
    R = lo + (hi - lo) * 0.5 * (1 - np.cos(np.pi * np.arange(n + 1) / n))  # clustered at the ends
    Z = np.sqrt(np.clip((2 * psi - (R**2 - R0**2) ** 2 / 4) / R**2, 0.0, None))
    Rs = np.concatenate([R, R[-2:0:-1], R[:1]])
    Zs = np.concatenate([Z, -Z[-2:0:-1], Z[:1]])
    return Wall(Rs, Zs)


@lru_cache(maxsize=1)
def default() -> Problem:
    return make()

"""Real stellarators by name: W7-X (standard configuration), NCSX and HSX, from the data simsopt ships.

The coil data were exported once from ``simsopt.configs.get_data(name)`` (simsopt 1.11.1) by
``benchmarks/peers/make_devices.py`` into ``vpforms/coils/data/<name>.json`` (installed with the
package; no simsopt dependency). Each file holds, for one device:

* nfp, stellarator symmetry, and the *base curves* as simsopt defines them (``CurveXYZFourier``):
  with θ ∈ [0, 1),

      x_i(θ) = c_i0 + Σ_{m=1}^{order} (c_im cos 2πmθ + s_im sin 2πmθ),   i = x, y, z  (m),

  and the number n of quadrature points θ_k = k/n simsopt uses per coil;
* the base currents in ampere (as simsopt uses them: W7-X's five non-planar coils carry
  108 turns × 15 kA, its two planar coils nothing; HSX's currents are negative);
* the magnetic axis as ``CurveRZFourier`` data, R(φ) = Σ_m rc_m cos(m·nfp·φ),
  Z(φ) = Σ_{m≥1} zs_m sin(m·nfp·φ). For W7-X the axis simsopt returns is not the axis of its coils
  (its zs are shifted by one mode and negated; the angle between B and that curve reaches 46°): the
  file holds the aligned curve (0.05° off B) and simsopt's as ``axis_simsopt``;
* a cross-check: simsopt's ``BiotSavart`` B of the full coil set at 20 points near the axis, and
  simsopt's own quadrature error there (≤ 8e-7);
* the default domain (``domain``): a boundary in VMEC's form R = Σ rmnc cos(mθ − nφ),
  Z = Σ zmns sin(mθ − nφ) fitted to the Poincaré points of a field line just inside the last closed
  flux surface (simsopt's tracer on its direct ``BiotSavart``), moved outward by a margin (W7-X: to
  hold the 5/5 island chain), with its measured distance to every coil filament
  (:func:`device_domain`; docs/devices.md).

:func:`device` evaluates every base curve at n points θ_k = k/n (default simsopt's n) as a closed
polyline — the straight segments between consecutive points — repeated over the nfp periods and
mirrored by stellarator symmetry with :meth:`CoilSet.from_symmetry` (for each period the rotated base
coils, then their mirror images with the current reversed: simsopt's ``coils_via_symmetries`` order
and signs). simsopt integrates the smooth curve by its quadrature rule, vpforms sums the straight
segments exactly, so the two fields differ by the polyline's O(1/n²) (tests/test_devices.py measures
the rate). Coils without current are left out.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np

from ..domains import ToroidalDomain
from ._coilset import Coil, CoilSet, _finite_scalar
from ._quadrature_coils import QuadratureCoils

__all__ = ["DeviceAxis", "device", "device_axis", "device_data", "device_domain", "device_names"]

_DEVICES = ("w7x", "ncsx", "hsx")


def device_names() -> tuple[str, ...]:
    """The devices :func:`device` knows: ``('w7x', 'ncsx', 'hsx')``."""
    return _DEVICES


def _key(name: Any) -> str:
    key = str(name).strip().lower().replace("-", "").replace("_", "") if isinstance(name, str) else None
    if key not in _DEVICES:
        raise ValueError(f"unknown device {name!r}; known devices: {', '.join(_DEVICES)}")
    return key


@lru_cache(maxsize=None)
def _load(key: str) -> str:
    return (resources.files("vpforms.coils") / "data" / f"{key}.json").read_text(encoding="utf-8")


def device_data(name: str) -> dict:
    """The device's data file as a dict (a fresh copy): ``nfp``, ``stellsym``, ``n_quadpoints``,
    ``base_currents``, ``base_curves`` (each ``order``, ``cos`` (3, order+1), ``sin`` (3, order)),
    ``axis``, ``axis_simsopt``, ``check`` (simsopt's B at points near the axis) and ``provenance``
    (module docstring). ``name`` is case-insensitive (``"W7-X"`` is ``"w7x"``)."""
    return json.loads(_load(_key(name)))


def curve_points(curve: dict, n: int) -> np.ndarray:
    """The base curve's points at θ_k = k/n, k = 0, …, n−1, shape (n, 3) (module docstring)."""
    cos, sin = np.asarray(curve["cos"], float), np.asarray(curve["sin"], float)
    theta = np.arange(n) / n
    m = np.arange(cos.shape[1])
    angles = 2 * np.pi * np.outer(m, theta)
    return (cos @ np.cos(angles) + sin @ np.sin(angles[1:])).T


def curve_tangents(curve: dict, n: int) -> np.ndarray:
    """The derivatives dγ/dθ of the base curve at θ_k = k/n, shape (n, 3): term by term,
    d/dθ (c cos 2πmθ + s sin 2πmθ) = 2πm (s cos 2πmθ − c sin 2πmθ)."""
    cos, sin = np.asarray(curve["cos"], float), np.asarray(curve["sin"], float)
    theta = np.arange(n) / n
    m = np.arange(cos.shape[1])
    angles = 2 * np.pi * np.outer(m, theta)
    w = 2 * np.pi * m[:, None]
    return ((sin * w[1:, 0]) @ np.cos(angles[1:]) - (cos * w[:, 0]) @ np.sin(angles)).T


def _n_points(n_points: Any, default: int) -> int:
    if n_points is None:
        return default
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)) or n_points < 3:
        raise ValueError(f"n_points must be an integer ≥ 3 (points per coil); got {n_points!r}")
    return int(n_points)


def _currents(currents: Any, data: dict, name: str) -> list[float]:
    if currents is None:
        return list(data["base_currents"])
    values = list(np.asarray(currents, dtype=object).reshape(-1)) if np.ndim(currents) else None
    if values is None or len(values) != len(data["base_curves"]):
        raise ValueError(f"{name}: currents must be a sequence of {len(data['base_curves'])} base-coil currents "
                         f"(A); got {currents!r}")
    return [_finite_scalar(v, f"{name} base current {k}") for k, v in enumerate(values)]


def device(name: str, n_points: int | None = None, *, currents: Any = None,
           rule: str = "polyline") -> CoilSet | QuadratureCoils:
    """The coil set of the device ``name`` (:func:`device_names`): its coils as closed polylines
    (``rule="polyline"``), or as the smooth curves by their quadrature (``rule="quadrature"``:
    :class:`~vpforms.coils.QuadratureCoils`, simsopt's ``BiotSavart`` on the same points to rounding).

    Parameters
    ----------
    name : str
        ``"w7x"``, ``"ncsx"`` or ``"hsx"`` (case-insensitive; ``"W7-X"`` works).
    n_points : int, optional
        Points per coil (θ_k = k/n_points on each base curve); default: simsopt's quadrature count
        (W7-X 96, NCSX 250, HSX 160). The polyline's field differs from the smooth curve's by
        O(1/n_points²).
    currents : sequence of float, optional
        Base-coil currents (A) replacing simsopt's (e.g. W7-X's planar coils, the last two).
    rule : str
        ``"polyline"`` (default: straight segments through the points, Hanson–Hirshman; every
        backend, the native one included, traces them directly) or ``"quadrature"`` (the smooth
        curve's Biot–Savart integral by the trapezoidal rule on the points: the field simsopt
        computes, ≈ 1e-6 from the exact curve's near the plasma at simsopt's count, against the
        polyline's 4e-4 for W7-X; JAX only — for grids and references).

    Returns
    -------
    CoilSet or QuadratureCoils
        nfp·2·(base coils with current) coils (module docstring for order and signs), with
        ``nfp`` and ``stellsym`` set; group k+1 and name ``<device>_c<k+1>`` for base coil k.

    Raises
    ------
    ValueError
        An unknown name (listing the known ones), n_points < 3, currents of the wrong length or
        not finite, no coil with current, or an unknown rule.
    """
    key = _key(name)
    if rule not in ("polyline", "quadrature"):
        raise ValueError(f"rule must be 'polyline' or 'quadrature'; got {rule!r}")
    data = device_data(key)
    n = _n_points(n_points, int(data["n_quadpoints"]))
    cur = _currents(currents, data, key)
    if rule == "quadrature":
        kept = [(c, I, f"{key}_c{k + 1}") for k, (c, I) in enumerate(zip(data["base_curves"], cur)) if I != 0]
        if not kept:
            raise ValueError(f"{key}: every base coil has zero current")
        return QuadratureCoils.from_symmetry([curve_points(c, n) for c, _, _ in kept],
                                             [curve_tangents(c, n) for c, _, _ in kept], [I for _, I, _ in kept],
                                             nfp=int(data["nfp"]), stellsym=bool(data["stellsym"]),
                                             names=[nm for _, _, nm in kept])
    base = [Coil(curve_points(c, n), I, k + 1, f"{key}_c{k + 1}")
            for k, (c, I) in enumerate(zip(data["base_curves"], cur)) if I != 0]
    if not base:
        raise ValueError(f"{key}: every base coil has zero current")
    return CoilSet.from_symmetry(base, nfp=int(data["nfp"]), stellsym=bool(data["stellsym"]))


@dataclass(frozen=True)
class DeviceAxis:
    """A stellarator-symmetric closed curve R(φ) = Σ_m rc_m cos(m·nfp·φ), Z(φ) = Σ_{m≥1} zs_{m−1}
    sin(m·nfp·φ) (simsopt's ``CurveRZFourier``; ``zs[0]`` is the m = 1 coefficient), in m."""

    rc: np.ndarray
    zs: np.ndarray
    nfp: int
    note: str = ""

    def __call__(self, phi: Any) -> tuple[np.ndarray, np.ndarray]:
        """(R(φ), Z(φ)) as NumPy arrays of φ's shape."""
        phi = np.asarray(phi, dtype=float)
        m = np.arange(len(self.rc))
        R = np.cos(np.multiply.outer(phi, m * self.nfp)) @ self.rc
        Z = np.sin(np.multiply.outer(phi, m[1:] * self.nfp)) @ self.zs
        return R, Z

    def xyz(self, phi: Any) -> np.ndarray:
        """Cartesian points of the axis at the angles φ, shape φ.shape + (3,)."""
        phi = np.asarray(phi, dtype=float)
        R, Z = self(phi)
        return np.stack([R * np.cos(phi), R * np.sin(phi), Z], axis=-1)


def device_axis(name: str) -> DeviceAxis:
    """The magnetic axis of the device (aligned with its coils' B to 0.1°; module docstring)."""
    a = device_data(name)["axis"]
    rc, zs = np.array(a["rc"], float), np.array(a["zs"], float)
    if len(zs) != len(rc) - 1:
        raise ValueError(f"{name}: axis data have {len(rc)} rc and {len(zs)} zs coefficients; need one fewer zs")
    rc.setflags(write=False)
    zs.setflags(write=False)
    return DeviceAxis(rc, zs, int(a["nfp"]), a.get("note", ""))


def device_domain(name: str, n_theta: int = 128, n_phi: int = 32) -> ToroidalDomain:
    """The device's default domain: the stored boundary R = Σ rmnc cos(m θ − n φ), Z = Σ zmns
    sin(m θ − n φ) (VMEC's convention, xn including nfp) — the last closed flux surface fitted to a
    field line's Poincaré points and moved outward by ``margin_m`` (``device_data(name)["domain"]``
    says how) — as a :class:`~vpforms.domains.ToroidalDomain` of ``n_theta`` vertices on ``n_phi``
    planes per field period (:meth:`~vpforms.domains.ToroidalDomain.from_fourier`; the polygons lie
    within :meth:`~vpforms.domains.ToroidalDomain.fourier_error` of the Fourier surface: 1–4 mm at
    the defaults, 0.3–1.1 mm at 256 × 64). Every coil filament lies outside it, ``min_distance_to_coils_m``
    from it in its plane. Built once per (device, n_theta, n_phi) and shared (a domain is immutable)."""
    return _domain(_key(name), int(n_theta), int(n_phi))


@lru_cache(maxsize=None)
def _domain(key: str, n_theta: int, n_phi: int) -> ToroidalDomain:
    d = device_data(key)["domain"]
    return ToroidalDomain.from_fourier(d["rmnc"], d["zmns"], d["xm"], d["xn"], nfp=int(d["nfp"]),
                                       n_theta=n_theta, n_phi=n_phi, name=f"{key} default domain")

"""Magnetic fields of filamentary coils: closed polylines of straight current segments.

The field and vector potential of one straight segment x_i → x_f carrying the current I are the
closed forms of Hanson & Hirshman, *Compact expressions for the Biot–Savart fields of a filamentary
segment*, Phys. Plasmas 9, 4410 (2002): with L = |x_f − x_i|, ê = (x_f − x_i)/L, R_i = |x − x_i|,
R_f = |x − x_f| (SI units, μ0 = 4π·10⁻⁷ H/m),

    A(x) = (μ0 I/4π) ê ln((R_i + R_f + L)/(R_i + R_f − L)),
    B(x) = (μ0 I/4π) · 2L(R_i + R_f)/(R_i R_f ((R_i + R_f)² − L²)) · ê × (x − x_i),

which are the Biot–Savart integrals (μ0 I/4π) ∫ dl/|r| and (μ0 I/4π) ∫ dl × r/|r|³ (r = x − x')
along the segment. They are evaluated in a cancellation-free form (:mod:`vpforms.coils._segments`),
summed over all segments of a :class:`CoilSet` in one vectorised JAX expression, and are
differentiable: ∇×A = B and ∇·B = 0 hold to rounding for closed coils.

* :class:`Coil`, :class:`CoilSet` — coils and sets (``B(x)``, ``A(x)``, ``from_symmetry``);
* :func:`read_makegrid`, :func:`write_makegrid`, :class:`CoilFileError` — MAKEGRID ``coils.*`` files;
* :func:`circular_tokamak`, :func:`l2_stellarator` — two coil sets with closed flux surfaces;
* :func:`device`, :func:`device_axis`, :func:`device_domain`, :func:`device_names` — real stellarators by name (W7-X, NCSX,
  HSX) from the coil data simsopt ships (:mod:`vpforms.coils.devices`).

``CoilSet.A`` is a Cartesian vector potential of a point (3,), and :class:`CoilPotential` the same
as a vector-potential object, so ``vpforms.toroidal.toroidal_field(coilset, box)`` (in
(u = R²/2, φ, Z)) and ``Field.from_vector_potential(coilset.potential(), box)`` (Cartesian)
integrate the field lines of a coil set directly with the volume-preserving methods — natively
(generated C, the segments passed at run time) where a C compiler exists.

:class:`QuadratureCoils` are smooth closed curves integrated by their quadrature rule (simsopt's
``BiotSavart``, exactly): ``device(name, rule="quadrature")`` (:mod:`vpforms.coils._quadrature_coils`).
"""

from ._coilset import Coil, CoilPotential, CoilSet
from ._quadrature_coils import QuadratureCoils, QuadraturePotential
from ._segments import MU0
from .devices import DeviceAxis, device, device_axis, device_data, device_domain, device_names
from .library import circular_tokamak, l2_stellarator
from .makegrid import CoilFileError, read_makegrid, write_makegrid

__all__ = [
    "MU0",
    "Coil",
    "CoilFileError",
    "CoilPotential",
    "CoilSet",
    "DeviceAxis",
    "QuadratureCoils",
    "QuadraturePotential",
    "circular_tokamak",
    "device",
    "device_axis",
    "device_data",
    "device_domain",
    "device_names",
    "l2_stellarator",
    "read_makegrid",
    "write_makegrid",
]

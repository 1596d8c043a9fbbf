"""The coordinates (u, φ, Z) ↔ (v, φ, Z) of φ-time and the potential C = (0, K, −v) (steps 1–3 of
:mod:`vpforms.phitime`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .. import _config  # noqa: F401  (float64)
from .._hoist import jit_hoisted
from .._potentials import _zero_between
from .._quadrature import DEFAULT_N
from .._vecpot import VectorPotential, _zero
from ..domains import ToroidalDomain, boundary_chord

__all__ = ["PhiTimeCoordinates", "PhiTimeError", "PhiTimePotential"]

Scalar = Callable[..., Any]


class PhiTimeError(ValueError):
    """φ cannot be the time on this box: B^φ vanishes or changes sign (``point``: where, (u, φ, Z))."""

    def __init__(self, message: str, point: Any = None):
        super().__init__(message)
        self.point = None if point is None else np.asarray(point, float)


def _scalarwise(f: Scalar) -> Scalar:
    """f of three scalars → f of three broadcastable arrays (vmap over the raveled points)."""

    def g(x1, x2, x3):
        x1, x2, x3 = jnp.broadcast_arrays(*(jnp.asarray(t, float) for t in (x1, x2, x3)))
        if x1.ndim:
            return jax.vmap(f)(x1.ravel(), x2.ravel(), x3.ravel()).reshape(x1.shape)
        return f(x1, x2, x3)

    g.__name__ = getattr(f, "__name__", "f")
    return g


def _summed(local, offset):
    """A'(u, φ, Z) = local(u, φ, Z) + offset(φ, Z), per component (φ, Z)."""
    def Aprime(u, phi, Z):
        (a_phi, a_Z), (o_phi, o_Z) = local(u, phi, Z), offset(phi, Z)
        return a_phi + o_phi, a_Z + o_Z

    return Aprime


class PhiTimeCoordinates:
    """The change of coordinates (u, φ, Z) ↔ (v, φ, Z), v = −s·A'_Z, and K (module docstring).

    Attributes: ``A`` the (u, φ, Z) potential; ``box`` its (u, φ, Z) box; ``ybox`` the (v, φ, Z)
    box; ``sign`` s = sign B^φ; ``u_ref``; ``gauge`` how A_u was removed ("A_u = 0" or "quadrature");
    ``inverse`` "closed form" or "newton"; ``level_v`` whether the residual gauge χ₀(φ, Z) made
    v(u_ref, φ, Z) = 0 (``level_v`` "yes", or "auto": where A_Z(u_ref, φ, Z) is not constant on the
    check grid; default "no", the v of the closed-form path of :mod:`._symbolic`). Scalar callables
    :meth:`V` (u, φ, Z) ↦ v, :meth:`U` (v, φ, Z) ↦ u, :meth:`K`, :meth:`Aprime` (A'_φ, A'_Z),
    :meth:`B_phi` (a² = B^φ); point maps :meth:`to_y`, :meth:`to_x` (shape (3,), jit/vmap-able).

    ``domain`` (a :class:`~vpforms.domains.ToroidalDomain` inside the box; issue #38): the region
    that follows the plasma instead of the box — B^φ's sign is required on it only, U's Newton
    bracket at (φ, Z) is the domain's chord [R_lo, R_hi] (as u = R²/2) of the line Z in the plane φ
    (each such line must meet the cross-section in one interval), and ``ybox`` bounds the image of
    the domain, which is not a rectangle in (v, Z): U (hence K) is NaN outside it. On a domain the
    gauge χ and the levelling start on its centroid curve (u_c(φ), Z_c(φ))
    (:meth:`~vpforms.domains.ToroidalDomain.centroid_curve`), unless ``u_ref`` is given: their
    paths stay in the plasma, where A is accurate (A must be finite along them: checked). ``box``
    stays the (u, φ, Z) box of A (``u_ref`` defaults to its u midpoint).
    """

    def __init__(self, A: VectorPotential, box: Any, *, u_ref: float | None = None,
                 inverse: Scalar | None = None, a_u: str = "auto", level_v: str = "no",
                 margin: float = 0.02, n_check: int = 17, quadrature_n: int = DEFAULT_N, newton_max_iter: int = 80,
                 domain: ToroidalDomain | None = None):
        if not isinstance(A, VectorPotential):
            raise TypeError("phi-time coordinates need a (u, φ, Z) VectorPotential, e.g. "
                            "vpforms.toroidal.ToroidalPotential(A_cartesian, nfp)")
        box = tuple(tuple(float(t) for t in b) for b in box)
        if len(box) != 3 or any(len(b) != 2 or not b[0] < b[1] for b in box):
            raise ValueError(f"box must be three (low, high) intervals in (u, φ, Z); got {box!r}")
        if not box[0][0] > 0:
            raise ValueError(f"the u interval must satisfy u_min > 0 (u = R²/2); got {box[0]!r}")
        if a_u not in ("auto", "zero", "quadrature"):
            raise ValueError(f"a_u must be 'auto', 'zero' or 'quadrature', not {a_u!r}")
        if level_v not in ("auto", "yes", "no"):
            raise ValueError(f"level_v must be 'auto', 'yes' or 'no', not {level_v!r}")
        if not 0 <= margin < 0.5:
            raise ValueError(f"margin must be in [0, 0.5); got {margin!r}")
        self.A, self.box = A, box
        self.domain = self._check_domain(domain, A.periods[1])
        self.u_ref = 0.5 * (box[0][0] + box[0][1]) if u_ref is None else float(u_ref)
        # the gauge integrals' base: on a domain (u_ref not given) the smooth curve (u_c(φ), Z_c(φ))
        # through its cross-sections — χ's paths along u and χ₀'s along Z then stay in the plasma.
        # From a fixed u_ref they cross, at some φ, where a spline of A that follows the domain is
        # not defined (its coefficients there count as 0) or where a box's coils are: χ's φ- and
        # Z-derivatives, hence K, then change on the scale of A's cells and no grid of K resolves them
        # (the domain's cross-sections are checked convex along R first: the curve needs them, U too)
        faces = self._face_grid(max(n_check, 33))
        self._base = self._base_curve() if self.domain is not None and u_ref is None else None
        self.margin, self.n_check = float(margin), int(n_check)
        self.newton_max_iter = int(newton_max_iter)
        self.period = A.periods[1]
        _, Aphi, AZ = A.components()
        grid = self._grid(n_check)

        # --- 1. the gauge A_u = 0 -------------------------------------------------------------
        if a_u == "auto":  # A_u ≡ 0 to rounding at the grid points: χ = 0, no quadrature
            vals = np.asarray(jit_hoisted(jax.vmap(lambda p: A(p)))(jnp.asarray(grid)))
            scale = float(np.max(np.abs(vals[:, 1:]))) or 1.0
            a_u = "zero" if float(np.max(np.abs(vals[:, 0]))) <= 1e-14 * scale else "quadrature"
        # A' = A − ∇χ − ∇χ₀ is kept as its u-dependent part ``local`` (A − ∇ of χ's u end) plus an
        # ``offset`` that depends on (φ, Z) only (∇ of χ's base end, −∇χ₀): K's samples take the
        # offset once per (φ, Z) line of the grid (phitime/_spline.py)
        def no_offset(phi, Z):
            return 0.0 * phi, 0.0 * Z

        if a_u == "zero":
            self.gauge = "A_u = 0 (χ = 0)"

            def local(u, phi, Z):
                return jnp.asarray(Aphi(u, phi, Z), float), jnp.asarray(AZ(u, phi, Z), float)
            offset = no_offset
        else:
            F = A.antiderivative(0, self.u_ref, quadrature_n)
            dF = jax.grad(F, argnums=(1, 2))
            if self._base is None:
                self.gauge = f"A_u removed by χ = ∫_{{u_ref}}^u A_u du (u_ref = {self.u_ref:.6g}, quadrature n={quadrature_n})"
                offset = no_offset
            else:  # χ = ∫_{u_c(φ)}^u A_u du = F(u) − F(u_c(φ)): the base end's gradient is the offset
                self.gauge = ("A_u removed by χ = ∫_{u_c(φ)}^u A_u du from the domain's centroid curve "
                              f"(antiderivative n={quadrature_n})")
                base = self._base
                offset = jax.grad(lambda phi, Z: F(base(phi)[0], phi, Z), argnums=(0, 1))

            def local(u, phi, Z):
                dphi, dZ = dF(u, phi, Z)
                return (jnp.asarray(Aphi(u, phi, Z), float) - dphi,
                        jnp.asarray(AZ(u, phi, Z), float) - dZ)

        Aprime = _summed(local, offset)

        # --- 1b. the residual gauge χ₀(φ, Z) = ∫_{Z_mid}^Z A_Z(u_ref, φ, Z') dZ' -----------------
        # A'_Z(u_ref, ·) = A_Z(u_ref, ·) (χ vanishes on u = u_ref); subtracting ∇χ₀ makes
        # v(u_ref, φ, Z) = 0, so v is the toroidal flux from the surface u = u_ref and the image of the
        # u interval holds the largest (v, φ, Z) rectangle (a ragged v(u_ref, ·) of A's own gauge
        # — Biot–Savart's, a spline's — would cut it down)
        if level_v == "auto":
            ref = grid.copy()
            ref[:, 0] = self.u_ref if self._base is None else np.asarray(self._base(ref[:, 1])[0])
            vals = np.asarray(jit_hoisted(jax.vmap(lambda p: Aprime(p[0], p[1], p[2])[1]))(jnp.asarray(ref)))
            spread, scale = float(np.ptp(vals)), float(np.max(np.abs(vals))) or 1.0
            level_v = "no" if spread <= 1e-12 * scale else "yes"
        self.level_v = level_v == "yes"
        if self.level_v:
            z_mid = 0.5 * (box[2][0] + box[2][1])
            G = A.antiderivative(2, z_mid, quadrature_n)
            if self._base is None:
                def chi0(phi, Z):
                    return G(self.u_ref, phi, Z)
            else:  # χ₀ = ∫_{Z_c(φ)}^Z A_Z(u_c(φ), φ, Z') dZ' (A'_Z = A_Z on u = u_c(φ): u_c is Z-free)
                base = self._base

                def chi0(phi, Z):
                    u_c, z_c = base(phi)
                    return G(u_c, phi, Z) - G(u_c, phi, z_c)
            dchi0 = jax.grad(chi0, argnums=(0, 1))
            offset_1 = offset

            def offset(phi, Z):
                (o_phi, o_Z), (d_phi, d_Z) = offset_1(phi, Z), dchi0(phi, Z)
                return o_phi - d_phi, o_Z - d_Z

            Aprime = _summed(local, offset)
            self.gauge += ("; v levelled on u = u_ref by χ₀ = ∫_{Z_mid}^Z A_Z(u_ref, φ, Z') dZ'" if self._base is None else
                           "; v levelled on u = u_c(φ) by χ₀ = ∫_{Z_c(φ)}^Z A_Z(u_c(φ), φ, Z') dZ'")
        self._local, self._offset = local, offset
        self._Aprime = Aprime

        def a2(u, phi, Z):  # B^φ = a² = −∂_u A'_Z
            return -jax.grad(lambda uu: Aprime(uu, phi, Z)[1])(u)

        self._a2 = a2

        # --- 2. the sign of B^φ on the box ------------------------------------------------------
        self.sign = self._sign_of_b_phi(n_check)
        s = float(self.sign)

        def V(u, phi, Z):
            return -s * Aprime(u, phi, Z)[1]

        self._V = V
        V_x = jit_hoisted(jax.vmap(V))
        lo_face, hi_face = (np.asarray(a) for a in jit_hoisted(jax.vmap(self._chord))(faces[:, 0], faces[:, 1]))
        v_min_face = np.asarray(V_x(lo_face, faces[:, 0], faces[:, 1]))
        v_max_face = np.asarray(V_x(hi_face, faces[:, 0], faces[:, 1]))
        if self.domain is not None:  # the image of the domain's chords: K's grid is masked to it
            met = np.isfinite(lo_face)
            ok = met & np.isfinite(v_min_face) & np.isfinite(v_max_face)
            if not ok.any() or not np.array_equal(ok, met):
                raise PhiTimeError(f"A is not finite on the chords of the domain {self.domain.name!r}: "
                                   "give a potential that covers the domain (a spline of A that follows it)")
            v0, v1 = float(np.min(v_min_face[ok])), float(np.max(v_max_face[ok]))
            pad = 0.5 * margin * (v1 - v0)  # a margin outside: the grid's edge nodes lie beyond the image
            z0, z1 = self.domain.bounds[2:]
            self.ybox = ((v0 - pad, v1 + pad), box[1], (z0, z1))
        else:
            v0, v1 = float(np.max(v_min_face)), float(np.min(v_max_face))
            if not v0 < v1:
                raise ValueError(
                    f"the (u, φ, Z) box {box} holds no (v, φ, Z) rectangle: v = −s·A'_Z spans "
                    f"[{v_min_face.min():.6g}, {v_min_face.max():.6g}] on u = {box[0][0]:g} and "
                    f"[{v_max_face.min():.6g}, {v_max_face.max():.6g}] on u = {box[0][1]:g}; widen the u interval")
            w = v1 - v0
            self.ybox = ((v0 + margin * w, v1 - margin * w), box[1], box[2])

        # --- 3. the inverse U(v, φ, Z) ------------------------------------------------------------
        if inverse is not None:
            if not callable(inverse):
                raise TypeError("inverse must be a JAX callable U(v, phi, Z) -> u")
            self.inverse = "closed form"
            self._U = lambda v, phi, Z: jnp.asarray(inverse(v, phi, Z), float)
            self._check_inverse()
        else:
            self.inverse = "newton"
            self._U = self._newton_inverse()

        def K(v, phi, Z):
            return s * Aprime(self._U(v, phi, Z), phi, Z)[0]

        self._K = K
        self._to = jit_hoisted(jax.vmap(self.to_y))
        self._from = jit_hoisted(jax.vmap(self.to_x))

    # -- scalar callables ---------------------------------------------------------------------------
    def V(self, u, phi, Z):
        """v = −s·A'_Z(u, φ, Z) (increasing in u)."""
        return self._V(u, phi, Z)

    def U(self, v, phi, Z):
        """u with V(u, φ, Z) = v (NaN where v is outside V's range on the box's u interval)."""
        return self._U(v, phi, Z)

    def K(self, v, phi, Z):
        """The φ-time Hamiltonian K = s·A'_φ(U(v, φ, Z), φ, Z)."""
        return self._K(v, phi, Z)

    def Aprime(self, u, phi, Z):
        """(A'_φ, A'_Z) of the gauge A'_u = 0."""
        return self._Aprime(u, phi, Z)

    def B_phi(self, u, phi, Z):
        """a² = B^φ = −∂_u A'_Z (= B_φ/R)."""
        return self._a2(u, phi, Z)

    def to_y(self, x):
        """(u, φ, Z) → (v, φ, Z), x of shape (3,)."""
        x = jnp.asarray(x, float)
        return jnp.stack([self._V(x[0], x[1], x[2]), x[1], x[2]])

    def to_x(self, y):
        """(v, φ, Z) → (u, φ, Z), y of shape (3,)."""
        y = jnp.asarray(y, float)
        return jnp.stack([self._U(y[0], y[1], y[2]), y[1], y[2]])

    def inside(self, y):
        """Whether U is defined at y = (v, φ, Z) (v within V's range on the u interval, or on the
        domain's chord at (φ, Z))."""
        u_lo, u_hi = self._chord(y[1], y[2])
        lo, hi = self._V(u_lo, y[1], y[2]), self._V(u_hi, y[1], y[2])
        return (y[0] >= lo) & (y[0] <= hi)

    def domain_points(self, n: int, seed: int = 0) -> np.ndarray:
        """n seeded points of the domain (uniform in its volume) in (v, φ, Z): where a φ-time field
        on it is checked (its ``sampler``)."""
        if self.domain is None:
            raise ValueError("these φ-time coordinates have no domain")
        return np.asarray(self._to(jnp.asarray(self.domain.sample_points(n, seed=seed))))

    # -- construction helpers ---------------------------------------------------------------------
    def _base_curve(self, n_points: int = 512, n_path: int = 8):
        """φ ↦ (u_c(φ), Z_c(φ)): the domain's centroid curve (:meth:`ToroidalDomain.centroid_curve`)
        as u = R²/2, the base of the gauge integrals. Checked: A is finite along the paths the
        integrals take — from u_c(φ) to u at (φ, Z), from Z_c(φ) to Z on u = u_c(φ) — for
        ``n_points`` seeded points of the domain (a spline of A that follows a smaller region
        is NaN off it: :class:`PhiTimeError` naming a point)."""
        curve = self.domain.centroid_curve()

        def base(phi):
            R, Z = curve(phi)
            return 0.5 * R * R, Z

        x = self.domain.sample_points(n_points, seed=1)
        u_c, z_c = (np.asarray(a) for a in base(x[:, 1]))
        t = np.linspace(0.0, 1.0, n_path)[:, None]
        shape = (n_path, x.shape[0])
        along_u = np.stack([u_c + t * (x[:, 0] - u_c), np.broadcast_to(x[:, 1], shape), np.broadcast_to(x[:, 2], shape)], -1)
        along_Z = np.stack([np.broadcast_to(u_c, shape), along_u[..., 1], z_c + t * (x[:, 2] - z_c)], -1)
        pts = np.concatenate([along_u, along_Z]).reshape(-1, 3)
        vals = np.asarray(jit_hoisted(jax.vmap(lambda p: self.A(p)))(jnp.asarray(pts)))
        bad = ~np.all(np.isfinite(vals), axis=1)
        if bad.any():
            p = pts[int(np.flatnonzero(bad)[0])]
            raise PhiTimeError(
                f"A is not finite at (u, φ, Z) = {_fmt(p)}, on a path of the gauge integrals from the centroid "
                f"curve of the domain {self.domain.name!r} (along u at fixed (φ, Z), then along Z): give a potential "
                "defined on a larger region (a spline of A that follows a larger domain), or u_ref", p)
        return base

    @staticmethod
    def _check_domain(domain, period):
        if domain is None:
            return None
        if not isinstance(domain, ToroidalDomain):
            raise TypeError(f"domain must be a vpforms.domains.ToroidalDomain; got {type(domain).__name__}")
        if period is None or abs(domain.period - period) > 1e-12 * period:
            raise ValueError(f"the domain {domain.name!r} has the period 2π/{domain.nfp} in φ, the potential "
                             f"{'none' if period is None else f'{period:.6g}'}: they must agree")
        return domain

    def _chord(self, phi, Z):
        """U's Newton bracket (u_lo, u_hi) at (φ, Z): the box's u interval, or the domain's chord
        of the line Z in the plane φ as u = R²/2 (NaN where the line misses the cross-section or
        meets it in more than one interval)."""
        if self.domain is None:
            u_lo, u_hi = self.box[0]
            return jnp.asarray(u_lo, float) + 0.0 * Z, jnp.asarray(u_hi, float) + 0.0 * Z
        R_lo, R_hi, n = boundary_chord(self.domain.geometry, phi, Z)
        one = n == 2
        return jnp.where(one, 0.5 * R_lo * R_lo, jnp.nan), jnp.where(one, 0.5 * R_hi * R_hi, jnp.nan)

    def _grid(self, n):
        """n³ check points: a grid of the box, or seeded points of the domain (as (u, φ, Z))."""
        if self.domain is not None:
            return self.domain.sample_points(n ** 3, seed=0)
        axes = [np.linspace(lo, hi, n) for lo, hi in self.box]
        return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)

    def _face_grid(self, n):
        """(φ, Z) points where the v range is taken: of the box's faces, or of the domain's Z range
        (4n lines in Z: the image's extremes sit at the cross-sections' tops and bottoms)."""
        if self.domain is not None:
            axes = [np.linspace(*self.box[1], n), np.linspace(*self.domain.bounds[2:], 4 * n)]
            g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
            _, _, crossings = (np.asarray(a) for a in jit_hoisted(jax.vmap(
                lambda p, z: boundary_chord(self.domain.geometry, p, z)))(g[:, 0], g[:, 1]))
            if np.any(crossings > 2):
                i = int(np.flatnonzero(crossings > 2)[0])
                raise PhiTimeError(
                    f"the domain {self.domain.name!r} is not convex along R: the line Z = {g[i, 1]:.6g} of the "
                    f"plane φ = {g[i, 0]:.6g} crosses its boundary {int(crossings[i])} times; φ-time needs one "
                    "interval of R per (φ, Z) (U's bracket)", (np.nan, g[i, 0], g[i, 1]))
            return g
        axes = [np.linspace(lo, hi, n) for lo, hi in self.box[1:]]
        return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)

    def _sign_of_b_phi(self, n):
        """+1 / −1 if B^φ has that sign at every point of an n³ grid of the box (faces included);
        else :class:`PhiTimeError` at a zero of B^φ (bisection along u between grid points of
        opposite sign, or a grid point where it vanishes)."""
        a2 = jit_hoisted(jax.vmap(self._a2))
        g = self._grid(n)
        if self.domain is not None:
            return self._sign_on_domain(a2, g)
        val = np.asarray(a2(g[:, 0], g[:, 1], g[:, 2])).reshape(n, n, n)
        if not np.all(np.isfinite(val)):
            i = np.unravel_index(int(np.flatnonzero(~np.isfinite(val.ravel()))[0]), val.shape)
            p = g.reshape(n, n, n, 3)[i]
            raise PhiTimeError(f"B^φ is not finite at (u, φ, Z) = {_fmt(p)} of the box {self.box}: the potential "
                               "is not defined there (a spline of A that follows a domain is NaN off it) — give "
                               "domain=, the region where the lines are", p)
        if np.all(val > 0):
            return 1
        if np.all(val < 0):
            return -1
        pts = g.reshape(n, n, n, 3)
        zero = np.argwhere(val == 0)
        if len(zero):
            p = pts[tuple(zero[0])]
        else:
            # a pair of neighbours of opposite sign: along u if there is one, else any axis
            p = None
            for ax in (0, 1, 2):
                sl0 = [slice(None)] * 3
                sl1 = [slice(None)] * 3
                sl0[ax], sl1[ax] = slice(0, -1), slice(1, None)
                flip = np.argwhere(np.sign(val[tuple(sl0)]) != np.sign(val[tuple(sl1)]))
                if len(flip):
                    i0 = tuple(flip[0])
                    i1 = tuple(i0[k] + (k == ax) for k in range(3))
                    p, _ = _zero_between(lambda q: np.asarray(a2(q[:, 0], q[:, 1], q[:, 2])),
                                         pts[i0], pts[i1])
                    break
        R = np.sqrt(2 * p[0])
        raise PhiTimeError(
            f"B^φ = dφ/dt changes sign in the box {self.box}: it vanishes at (u, φ, Z) = {_fmt(p)} "
            f"(R = {R:.6g}) — a field line turns back toroidally there and φ cannot be the time. "
            "Trace this region by time stepping (vpforms.toroidal.toroidal_field with vpforms.scheme), "
            "or choose a box where B^φ keeps one sign.", p)

    def _sign_on_domain(self, a2, g):
        """:meth:`_sign_of_b_phi` on the domain's check points ``g`` (u, φ, Z): one sign, else
        :class:`PhiTimeError` at a zero of B^φ between the nearest pair of opposite signs."""
        val = np.asarray(a2(g[:, 0], g[:, 1], g[:, 2]))
        where = f"the domain {self.domain.name!r}"
        if not np.all(np.isfinite(val)):
            p = g[int(np.flatnonzero(~np.isfinite(val))[0])]
            raise PhiTimeError(f"B^φ is not finite at (u, φ, Z) = {_fmt(p)} of {where}: the potential does "
                               "not cover the domain", p)
        if np.all(val > 0):
            return 1
        if np.all(val < 0):
            return -1
        pos, neg = g[val > 0], g[val <= 0]
        if len(pos):  # bisect between the nearest pair of opposite signs
            pos, neg = pos[:2000], neg[:2000]
            d = np.linalg.norm(pos[:, None, :] - neg[None, :, :], axis=-1)
            i, j = np.unravel_index(int(np.argmin(d)), d.shape)
            p, _ = _zero_between(lambda q: np.asarray(a2(q[:, 0], q[:, 1], q[:, 2])), pos[i], neg[j])
        else:
            p = neg[0]
        raise PhiTimeError(
            f"B^φ = dφ/dt changes sign in {where}: it vanishes at (u, φ, Z) = {_fmt(p)} (R = {np.sqrt(2 * p[0]):.6g}) "
            "— a field line turns back toroidally there and φ cannot be the time. Use a domain farther from "
            "the coils (a smaller one about the plasma), or trace by time stepping.", p)

    def _check_inverse(self):
        """A closed-form inverse must satisfy V(U(v, φ, Z), φ, Z) = v on the (v, φ, Z) box."""
        rng = np.random.default_rng(0)
        lo, hi = np.array(self.ybox).T
        y = rng.uniform(lo, hi, (256, 3))
        VU = jit_hoisted(jax.vmap(lambda v, p, z: self._V(self._U(v, p, z), p, z)))
        if self.domain is not None:  # the image of the domain only
            y = y[np.asarray(jit_hoisted(jax.vmap(self.inside))(jnp.asarray(y)))]
        got = np.asarray(VU(y[:, 0], y[:, 1], y[:, 2]))
        err = np.abs(got - y[:, 0])
        i = int(np.argmax(np.where(np.isfinite(err), err, np.inf)))
        if not err[i] <= 1e-12 * (1 + np.abs(y[i, 0])):
            raise ValueError(
                f"the given inverse is not the inverse of v = −A'_Z(u, φ, Z): |v(U(y)) − v| = "
                f"{err[i]:.3g} at (v, φ, Z) = {_fmt(y[i])}")

    def _newton_inverse(self):
        """U(v, φ, Z) by Newton safeguarded with bisection on the box's u bracket, as a custom_jvp.

        Not :func:`vpforms._newton.newton_scalar` (the engine's solver): its final live Newton step
        makes *first* derivatives exact, but the steps on this field differentiate K (hence U) up
        to third order, and the custom_jvp below, whose rule calls U again, is exact at every order;
        the bracket also keeps U inside the u interval (NaN outside) instead of diverging."""
        V = self._V
        chord = self._chord
        max_iter = self.newton_max_iter

        def solve(v, phi, Z):
            u_lo, u_hi = chord(phi, Z)
            f_lo, f_hi = V(u_lo, phi, Z) - v, V(u_hi, phi, Z) - v
            ok = (f_lo <= 0) & (f_hi >= 0)
            den = jnp.where(f_hi - f_lo > 0, f_hi - f_lo, 1.0)
            u0 = jnp.clip(u_lo - f_lo * (u_hi - u_lo) / den, u_lo, u_hi)  # the chord's root

            def cond(st):
                _, _, _, it, done = st
                return (~done) & (it < max_iter)

            def body(st):
                u, lo, hi, it, _ = st
                f, fu = jax.value_and_grad(lambda t: V(t, phi, Z) - v)(u)
                lo = jnp.where(f <= 0, u, lo)
                hi = jnp.where(f >= 0, u, hi)
                new = u - f / fu
                bad = ~jnp.isfinite(new) | (new < lo) | (new > hi)
                new = jnp.where(bad, 0.5 * (lo + hi), new)
                # a Newton step (not a bisection) of ≤ 1e-9·|u| leaves an error of about its square:
                # converged (waiting for a step of 2e-16·|u| ran lanes to max_iter at rounding level)
                done = ((~bad & (jnp.abs(new - u) <= 1e-9 * jnp.abs(u))) | (f == 0)
                        | (hi - lo <= 4e-16 * jnp.abs(u)))
                return new, lo, hi, it + 1, done

            init = (u0, jnp.asarray(u_lo, float) + 0.0 * u0, jnp.asarray(u_hi, float) + 0.0 * u0, jnp.int32(0), ~ok)
            u, *_ = lax.while_loop(cond, body, init)
            return jnp.where(ok, u, jnp.nan)

        @jax.custom_jvp
        def U(v, phi, Z):
            return solve(v, phi, Z)

        @U.defjvp
        def U_jvp(primals, tangents):  # implicit function theorem; U is called again: all orders exact
            v, phi, Z = primals
            dv, dphi, dZ = tangents
            u = U(v, phi, Z)
            # forward mode for both (∂_u V by a jvp, not jax.grad: compiles ~1.5× faster at
            # third order); the tangent is linear in (dv, dφ, dZ), so reverse mode transposes it
            _, Vx = jax.jvp(lambda t: V(t, phi, Z), (u,), (jnp.ones_like(u),))
            _, dV = jax.jvp(lambda p, z: V(u, p, z), (phi, Z), (dphi, dZ))
            return u, (dv - dV) / Vx

        def U_array(v, phi, Z):
            v, phi, Z = (jnp.asarray(t, float) for t in (v, phi, Z))
            return U(v, phi, Z)

        return U_array

    def describe(self) -> str:
        return (f"phi-time (v, φ, Z): v = {'−' if self.sign > 0 else '+'}A'_Z (toroidal flux), "
                f"K = {'' if self.sign > 0 else '−'}A'_φ(U(v, φ, Z), φ, Z); gauge {self.gauge}; "
                f"U by {self.inverse}" + ("" if self.domain is None else f" on the domain {self.domain.name!r}"))


class PhiTimePotential(VectorPotential):
    """C = (0, K, −v) in (v, φ, Z): ∇×C = (−∂_ZK, 1, ∂_vK), the field-line flow with φ as time.

    Antiderivatives: of C_v = 0 along v, exactly 0; of C_Z = −v along Z, exactly −v(Z − c); of
    C_φ = K along φ, the contract's (periodic-aware) Gauss–Legendre rule."""

    exact_gauge = False

    def __init__(self, coords: PhiTimeCoordinates):
        self.coords = coords
        self.periods = (None, coords.period, None)
        self.description = "phi-time potential (0, K, −v)"
        self._K = _scalarwise(coords._K)

    def components(self):
        def C_v(v, phi, Z):
            return _zero(v, phi, Z)

        def C_Z(v, phi, Z):
            v, phi, Z = jnp.broadcast_arrays(*(jnp.asarray(t, float) for t in (v, phi, Z)))
            return -v

        K = self._K
        K.__name__ = "K"
        return (C_v, K, C_Z)

    def antiderivative(self, k: int, c: float, n: int = DEFAULT_N) -> Scalar:
        if k == 0:
            return _zero
        if k == 2:
            c = float(c)

            def chi(v, phi, Z):
                v, phi, Z = jnp.broadcast_arrays(*(jnp.asarray(t, float) for t in (v, phi, Z)))
                return -v * (Z - c)

            return chi
        return super().antiderivative(k, c, n)


def _fmt(p: Sequence[float]) -> str:
    return "(" + ", ".join(f"{float(t):.6g}" for t in p) + ")"

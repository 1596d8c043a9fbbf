"""φ as the independent variable, still exactly volume preserving (issue #24, item 1).

In the toroidal coordinates of unit Jacobian x = (u = R²/2, φ, Z) of :mod:`vpforms.toroidal` a field
line is the flow of a = ∇×A, a^i = ε^{ijk} ∂_j A_k (A covariant). Tracing it with φ as the time
(one step = a fixed toroidal angle, so the sections φ = const are step boundaries) is a change of
time, a → a/a², and a change of coordinates, made here so that the result is again a divergence-
free field with a vector potential — and every class, case and composition of vpforms applies.

1. **Gauge A_u = 0.** χ(u, φ, Z) = ∫_{u_ref}^{u} A_u du' (the potential's own antiderivative along
   axis 0), A' = A − ∇χ: A'_u = 0, A'_φ = A_φ − ∂_φχ, A'_Z = A_Z − ∂_Zχ (∂χ by autodiff). Then

       a¹ = ∂_φA'_Z − ∂_ZA'_φ,   a² = B^φ = −∂_uA'_Z,   a³ = ∂_uA'_φ.

2. **The toroidal flux as a coordinate.** Where a² has one sign s = ±1 on the box, v := −s·A'_Z is
   strictly increasing in u (∂_u v = |a²|), so y = (v, φ, Z) are coordinates. u = U(v, φ, Z) is the
   inverse (scalar Newton safeguarded by bisection on the box's u interval, or a closed form
   ``inverse``); U is a :func:`jax.custom_jvp` by the implicit function theorem,

       ∂U/∂v = 1/∂_uv,   ∂U/∂φ = −∂_φv/∂_uv,   ∂U/∂Z = −∂_Zv/∂_uv,

   whose rule calls U again, so every derivative order vpforms takes by autodiff is exact.

3. **The φ-time field.** K(v, φ, Z) := s·A'_φ(U(v, φ, Z), φ, Z). Along a field line

       dZ/dφ = ∂K/∂v,   dv/dφ = −∂K/∂Z

   (Hamilton's equations, (Z, v) canonical; dv ∧ dZ = |B^φ| du ∧ dZ is the toroidal-flux form of
   a section φ = const, so v is a toroidal flux): the flow with φ' = 1 is, in y = (v, φ, Z),

       b = (−∂_ZK, 1, ∂_vK) = ∇_y × C,   C = (C_v, C_φ, C_Z) = (0, K, −v),

   C being s·A' written in the new coordinates (A' = A'_φ dφ + A'_Z dZ = s(K dφ − v dZ)). b is
   divergence free for the volume dv dφ dZ = |a²| du dφ dZ — the invariant volume of the φ-time
   flow (a time change multiplies the invariant density by |a²|) — and the map it induces on a
   section φ = const preserves the toroidal-flux area dv ∧ dZ. A vpforms method on b is therefore
   *exactly* volume preserving in (v, φ, Z) and, where it advances φ by exactly h, its section map
   is exactly area preserving (its Jacobian is block triangular: det ∂(v', Z')/∂(v, Z) = 1).

Orientation: φ' = +1 always. Where B^φ < 0 on the whole box (s = −1) the lines are followed in the
direction of increasing φ, i.e. backwards along B; the traced curves (and sections) are the same.
Where B^φ changes sign (vanishes) in the box a field line turns back toroidally, φ is not a time,
and the construction is impossible: :func:`phi_time_field` raises :class:`PhiTimeError` naming a
point where B^φ = 0; trace such a region by time stepping (:func:`vpforms.toroidal.toroidal_field`
with :func:`vpforms.scheme`).

Which steps advance φ by exactly h: the pair a case is built from splits b into two curls; when the
gauge of that pair sets C_v or C_Z to zero (χ = 0 or χ = −v(Z − c), both exact here), the split is
b = (−∂_ZK, 0, ∂_vK) + (0, 1, 0) and φ advances by h to rounding; a pair gauged along φ
(χ = ∫K dφ by quadrature) mixes the φ-translation into both parts. :func:`advances_phi_exactly`
states the rule for all five classes, :func:`phi_exact_cases` lists the 24 φ-exact cases (checked
against the steps of all 36 by ``tests/test_phitime.py``), :func:`phi_time_scheme` builds one; for
the others a section needs the interpolation of :func:`vpforms.diagnostics.poincare_section`.

Accuracy: b is exactly divergence free whatever the rounding of K; it is the field-line flow to
rounding when A_u ≡ 0 (χ = 0) and to the Gauss–Legendre error of χ otherwise (the gauge drops the
quadrature's residual A'_u ≈ 0).

The (v, φ, Z) box of the field is the largest rectangle inside the image of the (u, φ, Z) box:
v ∈ [max_{φ,Z} v(u_min, φ, Z), min_{φ,Z} v(u_max, φ, Z)] sampled on a grid of the (φ, Z) faces,
shrunk by ``margin`` of its width at both ends (the grid may miss a face's extreme); every point of
it has U in the u interval. Outside the image of the u interval U is NaN (``field.inside`` is false
there, so a step that leaves stops with ``RESULTS.left_domain``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from . import _config  # noqa: F401  (float64)
from ._case import Case, cases
from ._methods import Method, compose, scheme
from ._methods._representatives import REPRESENTATIVES
from ._methods.scheme import class_name
from ._potentials import _zero_between
from ._quadrature import DEFAULT_N
from ._vecpot import VectorPotential, _zero
from .fields import Field

__all__ = [
    "PhiTimeCoordinates",
    "PhiTimeError",
    "PhiTimePotential",
    "advances_phi_exactly",
    "from_phi_time",
    "phi_exact_cases",
    "phi_time_field",
    "phi_time_scheme",
    "to_phi_time",
]

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


class PhiTimeCoordinates:
    """The change of coordinates (u, φ, Z) ↔ (v, φ, Z), v = −s·A'_Z, and K (module docstring).

    Attributes: ``A`` the (u, φ, Z) potential; ``box`` its (u, φ, Z) box; ``ybox`` the (v, φ, Z)
    box; ``sign`` s = sign B^φ; ``u_ref``; ``gauge`` how A_u was removed ("A_u = 0" or "quadrature");
    ``inverse`` "closed form" or "newton". Scalar callables :meth:`V` (u, φ, Z) ↦ v, :meth:`U`
    (v, φ, Z) ↦ u, :meth:`K`, :meth:`Aprime` (A'_φ, A'_Z), :meth:`B_phi` (a² = B^φ); point maps
    :meth:`to_y`, :meth:`to_x` (shape (3,), jit/vmap-able).
    """

    def __init__(self, A: VectorPotential, box: Any, *, u_ref: float | None = None,
                 inverse: Scalar | None = None, a_u: str = "auto", margin: float = 0.02,
                 n_check: int = 17, quadrature_n: int = DEFAULT_N, newton_max_iter: int = 80):
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
        if not 0 <= margin < 0.5:
            raise ValueError(f"margin must be in [0, 0.5); got {margin!r}")
        self.A, self.box = A, box
        self.u_ref = 0.5 * (box[0][0] + box[0][1]) if u_ref is None else float(u_ref)
        self.margin, self.n_check = float(margin), int(n_check)
        self.newton_max_iter = int(newton_max_iter)
        self.period = A.periods[1]
        _, Aphi, AZ = A.components()
        grid = self._grid(n_check)

        # --- 1. the gauge A_u = 0 -------------------------------------------------------------
        if a_u == "auto":  # A_u ≡ 0 to rounding at the grid points: χ = 0, no quadrature
            vals = np.asarray(jax.jit(jax.vmap(lambda p: A(p)))(jnp.asarray(grid)))
            scale = float(np.max(np.abs(vals[:, 1:]))) or 1.0
            a_u = "zero" if float(np.max(np.abs(vals[:, 0]))) <= 1e-14 * scale else "quadrature"
        if a_u == "zero":
            self.gauge = "A_u = 0 (χ = 0)"

            def Aprime(u, phi, Z):
                return jnp.asarray(Aphi(u, phi, Z), float), jnp.asarray(AZ(u, phi, Z), float)
        else:
            self.gauge = f"A_u removed by χ = ∫_{{u_ref}}^u A_u du (u_ref = {self.u_ref:.6g}, quadrature n={quadrature_n})"
            chi = A.antiderivative(0, self.u_ref, quadrature_n)
            dchi = jax.grad(chi, argnums=(1, 2))

            def Aprime(u, phi, Z):
                dphi, dZ = dchi(u, phi, Z)
                return (jnp.asarray(Aphi(u, phi, Z), float) - dphi,
                        jnp.asarray(AZ(u, phi, Z), float) - dZ)

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
        u_lo, u_hi = box[0]
        V_x = jax.jit(jax.vmap(V))
        faces = self._face_grid(max(n_check, 33))
        v_min_face = np.asarray(V_x(np.full(len(faces), u_lo), faces[:, 0], faces[:, 1]))
        v_max_face = np.asarray(V_x(np.full(len(faces), u_hi), faces[:, 0], faces[:, 1]))
        v0, v1 = float(np.max(v_min_face)), float(np.min(v_max_face))
        if not v0 < v1:
            raise ValueError(
                f"the (u, φ, Z) box {box} holds no (v, φ, Z) rectangle: v = −s·A'_Z spans "
                f"[{v_min_face.min():.6g}, {v_min_face.max():.6g}] on u = {u_lo:g} and "
                f"[{v_max_face.min():.6g}, {v_max_face.max():.6g}] on u = {u_hi:g}; widen the u interval")
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
        self._to = jax.jit(jax.vmap(self.to_y))
        self._from = jax.jit(jax.vmap(self.to_x))

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
        """Whether U is defined at y = (v, φ, Z) (v within V's range on the u interval)."""
        u_lo, u_hi = self.box[0]
        lo, hi = self._V(u_lo, y[1], y[2]), self._V(u_hi, y[1], y[2])
        return (y[0] >= lo) & (y[0] <= hi)

    # -- construction helpers ---------------------------------------------------------------------
    def _grid(self, n):
        axes = [np.linspace(lo, hi, n) for lo, hi in self.box]
        return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)

    def _face_grid(self, n):
        axes = [np.linspace(lo, hi, n) for lo, hi in self.box[1:]]
        return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)

    def _sign_of_b_phi(self, n):
        """+1 / −1 if B^φ has that sign at every point of an n³ grid of the box (faces included);
        else :class:`PhiTimeError` at a zero of B^φ (bisection along u between grid points of
        opposite sign, or a grid point where it vanishes)."""
        a2 = jax.jit(jax.vmap(self._a2))
        g = self._grid(n)
        val = np.asarray(a2(g[:, 0], g[:, 1], g[:, 2])).reshape(n, n, n)
        if not np.all(np.isfinite(val)):
            i = np.unravel_index(int(np.flatnonzero(~np.isfinite(val.ravel()))[0]), val.shape)
            p = g.reshape(n, n, n, 3)[i]
            raise PhiTimeError(f"B^φ is not finite at (u, φ, Z) = {_fmt(p)} of the box {self.box}", p)
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

    def _check_inverse(self):
        """A closed-form inverse must satisfy V(U(v, φ, Z), φ, Z) = v on the (v, φ, Z) box."""
        rng = np.random.default_rng(0)
        lo, hi = np.array(self.ybox).T
        y = rng.uniform(lo, hi, (256, 3))
        VU = jax.jit(jax.vmap(lambda v, p, z: self._V(self._U(v, p, z), p, z)))
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
        u_lo, u_hi = self.box[0]
        max_iter = self.newton_max_iter

        def solve(v, phi, Z):
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
                done = (jnp.abs(new - u) <= 2e-16 * jnp.abs(u)) | (f == 0) | (hi - lo <= 4e-16 * jnp.abs(u))
                return new, lo, hi, it + 1, done

            init = (u0, jnp.asarray(u_lo, float), jnp.asarray(u_hi, float), jnp.int32(0), ~ok)
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
                f"U by {self.inverse}")


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


def phi_time_field(A: VectorPotential | Callable[[Any], Any], box: Any, *, nfp: int | None = None,
                   u_ref: float | None = None, inverse: Scalar | None = None, a_u: str = "auto",
                   margin: float = 0.02, n_check: int = 17, name: str = "phi-time field",
                   **kw: Any) -> Field:
    """The field-line flow of ∇×A with φ as the time, as a :class:`~vpforms.Field` in (v, φ, Z).

    ``A``: a (u, φ, Z) :class:`~vpforms._vecpot.VectorPotential` (e.g.
    ``vpforms.toroidal.ToroidalPotential(A_cartesian, nfp)``) or a Cartesian A(x) (wrapped in one,
    with ``nfp``); ``box``: the (u, φ, Z) box (:func:`vpforms.toroidal.box_from_cylindrical`) on which
    B^φ keeps one sign (else :class:`PhiTimeError`, checked on an ``n_check``³ grid) — the Newton
    bracket of U and the domain of the field. ``u_ref``: the base of χ = ∫_{u_ref}^u A_u (default
    the u midpoint); ``a_u``: "auto" (χ = 0 if A_u vanishes to 1e-14 relative on the grid, else
    quadrature), "zero" or "quadrature"; ``inverse``: a closed-form U(v, φ, Z) (checked) instead of
    Newton; ``margin``: the fraction of the v range dropped at each end of the (v, φ, Z) box.
    Further keywords go to :meth:`vpforms.Field.from_vector_potential` (``origin`` defaults to
    (v_mid, φ_min, Z_mid) of the (v, φ, Z) box).

    The result has ``coordinates`` "phi-time (v, φ, Z) …", ``periods`` (None, 2π/nfp, None) for a
    φ-periodic A, ``phi_time`` the :class:`PhiTimeCoordinates` (for :func:`to_phi_time`,
    :func:`from_phi_time`) and ``inside`` (a step that leaves the image of the u interval stops
    with ``RESULTS.left_domain``).
    """
    if not isinstance(A, VectorPotential):
        from .toroidal import ToroidalPotential

        A = ToroidalPotential(A, 1 if nfp is None else nfp)
    elif nfp is not None:
        raise ValueError("nfp is the potential's (ToroidalPotential(A, nfp)); do not pass it again")
    coords = PhiTimeCoordinates(A, box, u_ref=u_ref, inverse=inverse, a_u=a_u, margin=margin,
                                n_check=n_check, quadrature_n=kw.get("quadrature_n", DEFAULT_N))
    C = PhiTimePotential(coords)
    yb = coords.ybox
    kw.setdefault("origin", (0.5 * (yb[0][0] + yb[0][1]), yb[1][0], 0.5 * (yb[2][0] + yb[2][1])))
    field = Field.from_vector_potential(C, box=yb, name=name, **kw)
    field.coordinates = coords.describe()
    field.periods = (None, coords.period, None)
    field.phi_time = coords
    field.inside = coords.inside
    return field


#: per class, the axis (1-based) of the field the class recipe treats specially, on the relabelled
#: field it runs on: the gauge axis of its pair (SE: x₂, DL: x₃) or the role j of Quispel's
#: correction map (S1: x₂, S2: x₃; the recipe of vpforms.scheme for nonlinear fields)
_SPECIAL_AXIS = {"SE+SE": 2, "DL+DL": 3, "SE+DL": 3, "S1": 2, "S2": 3}


def advances_phi_exactly(case: Case | str | tuple) -> bool:
    """Whether the step of ``case`` on a φ-time field advances φ by exactly h (to rounding).

    The rule: the axis its class treats specially (:data:`_SPECIAL_AXIS`), mapped back through the
    relabelling π the case is built with (relabelled x_k is the field's x_{π(k)}; for the SE+DL
    3-cycles τ₀⁻¹, of the switched case whose adjoint it is), must not be φ (axis 2). Then the pair
    is C's own gauge along v (χ = 0) or Z (χ = −v(Z − c)), which splits b into the φ-translation
    (0, 1, 0) and the frozen-φ flow (−∂_ZK, 0, ∂_vK), or the correction map's φ update is explicit
    (X_φ = φ + h·1). Verified on all 36 cases by ``tests/test_phitime.py`` (slow tier): 24 are
    φ-exact — S1 4, S2 4, SE+SE 4, DL+DL 4, SE+DL 8 — and those are also the cheap ones (no
    quadrature of K along φ). The DL classes must run by their θ-stages (``fast=True``): their
    φ-exact pairs contain a potential linear in the momentum, where the engine's DL generating form
    fails its twist condition.
    """
    c = _as_case(case)
    rep = REPRESENTATIVES[c.cls]
    pi = c.sigma * rep.sigma.inverse()
    if pi * rep.Sigma != c.Sigma:  # τ(c) = τ₀⁻¹: the adjoint of the switched case (vpforms.scheme)
        c = c.switched()
        pi = c.sigma * rep.sigma.inverse()
    return pi(_SPECIAL_AXIS[c.cls]) != 2


def phi_exact_cases(cls: str | None = None) -> tuple[Case, ...]:
    """The cases (of class ``cls``, or all) whose steps advance φ by exactly h
    (:func:`advances_phi_exactly`), in the order of :func:`vpforms.cases`."""
    want = None if cls is None else class_name(cls)
    return tuple(c for c in cases() if (want is None or c.cls == want) and advances_phi_exactly(c))


def phi_time_scheme(field: Field, cls: str = "SE+SE", *, order: int | None = None,
                    composition: str | None = None, recover: bool = False, **options: Any) -> Method:
    """A method on a φ-time field whose every step advances φ by exactly h, so that the sections
    φ = φ₀ + k·h are step boundaries: the first φ-exact case of class ``cls``
    (:func:`phi_exact_cases`), by θ-stages for the DL classes (``fast=True``), composed to
    ``order`` (2, 4, 6; :func:`vpforms.compose`, ``composition`` its scheme name) if given.

    ``recover`` defaults to False: a recovered step may switch to a case that is not φ-exact (and
    whose pair is a quadrature of K along φ, expensive to compile); where a step fails, the line
    has usually left the (v, φ, Z) box (``RESULTS.left_domain``)."""
    if not hasattr(field, "phi_time"):
        raise TypeError("phi_time_scheme needs a φ-time field (vpforms.phitime.phi_time_field)")
    key = class_name(cls)
    if key in ("DL+DL", "SE+DL"):
        options.setdefault("fast", True)
    method = scheme(field, phi_exact_cases(key)[0], recover=recover, **options)
    if order is None:
        if composition is not None:
            raise ValueError("composition needs an order")
        return method
    return compose(method, order, composition)


def _as_case(case: Any) -> Case:
    if isinstance(case, Case):
        return case
    if isinstance(case, str):
        return REPRESENTATIVES[class_name(case)]
    return Case(*case)


def _coords_of(obj: Any) -> PhiTimeCoordinates:
    for o in (obj, getattr(obj, "phi_time", None), getattr(getattr(obj, "field", None), "phi_time", None)):
        if isinstance(o, PhiTimeCoordinates):
            return o
        if isinstance(getattr(o, "phi_time", None), PhiTimeCoordinates):
            return o.phi_time
    raise TypeError(f"expected a phi-time field, method or PhiTimeCoordinates; got {type(obj).__name__}")


def to_phi_time(field_or_map: Any, x_uphiz: Any) -> jax.Array:
    """(u, φ, Z) → (v, φ, Z) for points of shape (..., 3) (``field_or_map``: a φ-time field, a method
    on one, or its :class:`PhiTimeCoordinates`); traceable (jit, vmap)."""
    c = _coords_of(field_or_map)
    x = jnp.asarray(x_uphiz, float)
    return c._to(x.reshape(-1, 3)).reshape(x.shape)


def from_phi_time(field_or_map: Any, y_vphiz: Any) -> jax.Array:
    """(v, φ, Z) → (u, φ, Z) for points of shape (..., 3); NaN in u off the box's u interval."""
    c = _coords_of(field_or_map)
    y = jnp.asarray(y_vphiz, float)
    return c._from(y.reshape(-1, 3)).reshape(y.shape)


def _fmt(p: Sequence[float]) -> str:
    return "(" + ", ".join(f"{float(t):.6g}" for t in p) + ")"

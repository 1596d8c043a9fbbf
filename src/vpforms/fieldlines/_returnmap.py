"""The φ-return map of a field-line method, differentiable: P(R, Z) on the section φ = φ₀ (issue #21).

P takes a point (R, Z) of the half-plane φ = φ₀, steps the method until the line reaches the next
half-plane φ₀ ± 2π/nfp (the sign of B^φ at the start), and locates the crossing on the method's own
step family θ ↦ Ψ_{θh}(x_n) (as :func:`~vpforms.diagnostics.poincare_section` does). The crossing
θ* is found by regula falsi (no derivative) and then polished by one Newton step on
g(θ) = φ(Ψ_{θh}(x_n)) − φ_target whose divisor is held constant for AD:

    θ = θ* − g(θ*, x_n) / stop_gradient(g_θ),

so ``jax.jacfwd`` of P is the exact implicit-function derivative dθ/dx = −g_x/g_θ at the crossing
(g(θ*) = 0 to rounding): the Jacobian DP of the *discrete* map, which is what Newton for fixed
points and the tangent-map classification need.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._errors import RESULTS
from .._recovery import bare_method
from ..diagnostics._surfaces import wrap_angle
from ._geometry import is_toroidal

__all__ = ["ReturnMap", "return_map"]

#: status codes of the return map beyond RESULTS (a step failed: its RESULTS code)
NO_RETURN = 100


class ReturnMap:
    """P: (R, Z) on φ = φ₀ → (R, Z) on the next half-plane φ₀ ± 2π/nfp, for one field-line method.

    ``__call__(z)`` → (z′, status) for z of shape (2,) (jit/vmap/jacfwd-able; status 0 success,
    a RESULTS code when a step failed, ``NO_RETURN`` = 100 when the line did not come back within
    ``max_steps``); ``power(z, m)`` is Pᵐ. ``sign`` is the direction of B^φ (+1: φ increasing),
    ``period`` = 2π/nfp.
    """

    def __init__(self, method: Any, h: float, phi: float = 0.0, nfp: int = 1, *, sign: int = 1,
                 max_steps: int = 100_000):
        if isinstance(nfp, bool) or int(nfp) != nfp or int(nfp) < 1:
            raise ValueError(f"nfp must be a positive integer; got {nfp!r}")
        if sign not in (-1, 1):
            raise ValueError(f"sign must be +1 or -1; got {sign!r}")
        if not (h > 0 and math.isfinite(h)):
            raise ValueError(f"h must be a positive number; got {h!r}")
        # the bare method: a fixed point needs one smooth map (a recovered step would switch maps);
        # a failed step is reported by the status instead
        self.method, self.h, self.nfp, self.sign = bare_method(method), float(h), int(nfp), int(sign)
        self.period = 2 * math.pi / self.nfp
        self.phi0 = float(phi)
        self.max_steps = int(max_steps)
        self.toroidal = is_toroidal(getattr(method, "field", None))
        self._call = jax.jit(self._map)

    # -- coordinates of the section ------------------------------------------------------------
    def state(self, z, phi=None):
        """The point of the section at (R, Z) = z, in the field's coordinates."""
        phi = self.phi0 if phi is None else phi
        R, Z = z[0], z[1]
        if self.toroidal:
            return jnp.stack([0.5 * R * R, jnp.asarray(phi, R.dtype) + 0.0 * R, Z])
        return jnp.stack([R * jnp.cos(phi), R * jnp.sin(phi), Z])

    def rz(self, x):
        """(R, Z) of a point in the field's coordinates."""
        if self.toroidal:
            return jnp.stack([jnp.sqrt(2.0 * x[0]), x[2]])
        return jnp.stack([jnp.hypot(x[0], x[1]), x[2]])

    def _dphi(self, X, x):  # the toroidal angle turned from x to X (lifted)
        if self.toroidal:
            return X[1] - x[1]
        return wrap_angle(jnp.arctan2(X[1], X[0]) - jnp.arctan2(x[1], x[0]))

    # -- the map -------------------------------------------------------------------------------
    def _map(self, z):
        step, h, s = self.method.step_with_status, self.h, self.sign
        z = jnp.asarray(z, jnp.float64)
        x = self.state(z)
        target = s * self.period  # φ turned at the next half-plane (relative to the start)

        def cond(c):
            x, xp, ph, php, n, st = c
            return (st == RESULTS.successful) & (s * (ph - target) < 0) & (n < self.max_steps)

        def body(c):
            x, xp, ph, php, n, st = c
            X, sX = step(x, h)
            sX = jnp.where((sX == RESULTS.successful) & ~jnp.all(jnp.isfinite(X)), RESULTS.nonfinite, sX)
            ok = sX == RESULTS.successful
            return (jnp.where(ok, X, x), x, jnp.where(ok, ph + self._dphi(X, x), ph), ph, n + 1, sX)

        zero = jnp.zeros((), jnp.float64)
        x, xp, ph, php, n, st = lax.while_loop(
            cond, body, (x, x, zero, zero, jnp.int32(0), jnp.int32(RESULTS.successful)))
        st = jnp.where((st == RESULTS.successful) & (s * (ph - target) < 0), NO_RETURN, st)

        # locate θ ∈ [0, 1] with φ(Ψ_{θh}(x_n)) = target: Newton on θ from the chord, each iteration
        # one forward-mode step (value and ∂/∂θ together), safeguarded to the bracket [0, 1]
        xs = lax.stop_gradient(xp)
        g0, g1 = lax.stop_gradient(php - target), lax.stop_gradient(ph - target)

        def sub(th, xp):  # Ψ_{θh}(x_n), d/dθ of it, and the sub-step's status
            return jax.jvp(lambda t: step(xp, t * h), (th,), (jnp.ones(()),), has_aux=True)

        def gap(Y, dY, xp):  # angle past the target and its θ-derivative
            if self.toroidal:
                return php + Y[1] - xp[1] - target, dY[1]
            r2 = Y[0] ** 2 + Y[1] ** 2
            return php + self._dphi(Y, xp) - target, (Y[0] * dY[1] - Y[1] * dY[0]) / r2

        def newton(th, _):
            Y, dY, _ = sub(th, xs)
            gv, gd = gap(Y, dY, xs)
            t_new = th - gv / jnp.where(gd == 0, 1.0, gd)
            return jnp.clip(jnp.where(jnp.isfinite(t_new), t_new, th), 0.0, 1.0), None

        th_chord = jnp.clip(g0 / jnp.where(g0 == g1, 1.0, g0 - g1), 0.0, 1.0)
        th0, _ = lax.scan(newton, th_chord, None, length=8)
        th0 = lax.stop_gradient(th0)
        # the polish, differentiable: Y = Ψ_{θ0 h}(x_n) + (θ − θ0)·∂_θΨ with θ = θ0 − g/g_θ (g_θ held
        # constant), so that the derivative of Y in x is the implicit-function one, dθ/dx = −g_x/g_θ
        Y0, dY, sY = sub(th0, xp)
        gv, gd = gap(Y0, dY, xp)
        dY, gd = lax.stop_gradient(dY), lax.stop_gradient(gd)
        Y = Y0 - (gv / gd) * dY
        st = jnp.where((st == RESULTS.successful) & (sY != RESULTS.successful), sY, st)
        return self.rz(Y), st

    def __call__(self, z):
        return self._call(z)

    def power(self, z, m: int):
        """Pᵐ(z) and the first failure status (jit-able; one copy of the map, m iterations)."""
        def body(c, _):
            z, st = c
            z2, s = self._map(z)
            return (z2, jnp.where(st == RESULTS.successful, s, st)), None

        (z, st), _ = lax.scan(body, (jnp.asarray(z, jnp.float64), jnp.int32(RESULTS.successful)), None,
                              length=int(m))
        return z, st

    def orbit(self, z, m: int) -> np.ndarray:
        """(m + 1, 2): z, P(z), …, Pᵐ(z) (host arrays)."""
        out = [np.asarray(z, float)]
        for _ in range(int(m)):
            z, st = self(jnp.asarray(out[-1]))
            if int(st) != RESULTS.successful:
                raise RuntimeError(f"the return map failed after {len(out) - 1} transits from (R, Z) = "
                                   f"{tuple(out[0])}: {status_message(int(st))}")
            out.append(np.asarray(z))
        return np.array(out)


def status_message(st: int) -> str:
    if st == NO_RETURN:
        return "the line did not come back to the section within max_steps steps"
    return RESULTS.messages.get(st, f"status {st}")


def return_map(method: Any, h: float, phi: float = 0.0, nfp: int = 1, *, guess: Any = None,
               max_steps: int | None = None) -> ReturnMap:
    """The φ-return map of ``method`` on the section φ = phi (mod 2π/nfp) (module docstring).

    The direction (sign of B^φ) and, unless given, the step cap (20× the steps of one field period
    at the guess's B^φ) are taken from the field at ``guess`` = (R, Z) (default: the centre of the
    field's box)."""
    field = method.field
    tor = is_toroidal(field)
    if guess is None:
        box = np.asarray(field.box, float)
        c = box.mean(axis=1)
        guess = (math.sqrt(2 * c[0]), c[2]) if tor else (float(np.hypot(box[0, 1], box[1, 1]) / 2), c[2])
    g = np.asarray(guess, float)
    probe = ReturnMap(method, h, phi, nfp, max_steps=1)
    x = np.asarray(probe.state(jnp.asarray(g)))
    a = np.asarray(field(x[None]))[0]
    dphi = a[1] if tor else (x[0] * a[1] - x[1] * a[0]) / (x[0] ** 2 + x[1] ** 2)
    if not np.isfinite(dphi) or dphi == 0:
        raise ValueError(f"B^φ = {dphi} at (R, Z) = {tuple(g)}: the field line does not turn toroidally there, "
                         "so it has no φ-return map")
    if max_steps is None:
        max_steps = int(20 * (2 * math.pi / nfp) / (abs(dphi) * h)) + 100
    # one ReturnMap (and its compiled functions) per method and parameters: studies reuse them
    key = (id(method), float(h), float(phi), int(nfp), int(np.sign(dphi)), int(max_steps))
    hit = _MAPS.get(key)
    if hit is not None and hit[0] is method:
        return hit[1]
    P = ReturnMap(method, h, phi, nfp, sign=int(np.sign(dphi)), max_steps=max_steps)
    if len(_MAPS) >= 32:
        _MAPS.pop(next(iter(_MAPS)))
    _MAPS[key] = (method, P)
    return P


#: (id(method), h, φ₀, nfp, sign, max_steps) → (method, ReturnMap): the method is kept so its id stays valid
_MAPS: dict = {}

"""A bounded, robust search for the magnetic axis (issue #41 item 1): the guess refined by orbit
averages, then a damped Newton with a budget counted in iterations, never in seconds.

Newton on F(z) = P(z) − z converges quadratically only near the fixed point; from a rough guess
(a user's "about here", 5 cm off) its first steps can leave the basin, and each step of a spline
field's map is costly. Two bounded stages make the search robust:

1. **Orbit averages** (at most ``refine`` rounds). The orbit z_k = P^k(z₀), k = 1 … N, of a point
   near an elliptic fixed point a lies on an invariant circle about a; to first order (the tangent
   map M = DP(a), conjugate to a rotation by 2πν) it is an ellipse *centred at a*, and the average
   of z_k − a over the orbit vanishes. Nonlinear terms shift the centre by O(r²), r = |z₀ − a|, so
   the average ẑ is an O(r²) better guess (quadratic, like Newton, but from anywhere inside the
   island of the axis). The average is Birkhoff's weighted one, Σ w((k − ½)/N) z_k / Σ w, w(t) =
   exp(−1/(t(1 − t))) (:func:`~vpforms.fieldlines.birkhoff_weight`): on a quasi-periodic orbit it
   converges faster than any power of 1/N, where the plain mean keeps an O(1/N) error from the
   unfinished last turn. A round is kept only while the orbit's spread s = (Σ w |z_k − ẑ|²/Σ w)^½
   (≈ r, the size of the circle traced) shrinks by at least :data:`REFINE_GAIN`; a line that fails
   (leaves the domain) or a spread that does not shrink ends the rounds.
2. **Damped Newton** (at most ``max_iter`` iterations, each with at most :data:`HALVINGS` step
   halvings). dz = −(DP − I)⁻¹F, its length capped by a trust radius Δ (start: the last spread, or
   a tenth of the field's (R, Z) box; doubled after a full step that hit the cap, set to the
   accepted length after a halving), then halved until Armijo's sufficient decrease
   |F(z + λ dz)| ≤ (1 − 10⁻⁴λ)|F(z)| holds. A trial point outside the field's box or domain, one
   whose line does not return, or one farther from Newton's start than a few refinement spreads
   (at least a tenth of the box) counts as no decrease: far from a fixed point |F| is a poor guide
   (beside a singular axis — a current filament — a point at the box's edge can have the smaller
   residual). Converged when |F| ≤ tol·(1 + |z|).

A failed search answers the refined guess (the orbit's centre: the best estimate there is where
Newton cannot converge, e.g. on a filament where P is not smooth), or Newton's point of least
residual where that residual is below :data:`NEWTON_WIN` times the refined guess's.

The budget is the number of map evaluations that these bounds allow — the same on a loaded and an
idle machine; :class:`AxisSearch` reports the evaluations used (one evaluation: one point carried
one period; a central-difference Jacobian: four more).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS
from ..backends import select_backend
from ._native_map import native_crossings, native_power, native_value_and_jac
from ._returnmap import ReturnMap, status_message

__all__ = ["AxisSearch", "MapEvaluator", "search_axis", "HALVINGS", "REFINE_GAIN", "REFINE_TRANSITS"]

#: step halvings per Newton iteration (the line search of stage 2)
HALVINGS = 8
#: a refinement round is kept only if the orbit's spread falls below this fraction of the previous one
REFINE_GAIN = 0.5
#: transits per refinement orbit (the Birkhoff average of 32 points: far below the O(r²) centre shift)
REFINE_TRANSITS = 32
#: Armijo's constant of the sufficient decrease of |F|
ARMIJO = 1e-4
#: a failed search answers Newton's point of least residual only if that residual is below this
#: fraction of the refined guess's (clear progress towards a fixed point), else the refined guess
NEWTON_WIN = 1e-3


def _value_and_jac(P: ReturnMap, m: int):
    key = ("vj", m)
    cache = P.__dict__.setdefault("_jit_cache", {})
    if key not in cache:
        def both(z):  # Pᵐ(z), its status and DPᵐ(z) (exact, forward mode; one trace of the map)
            def f(y):
                z2, st = P.power(y, m)
                return z2, (z2, st)

            J, (z2, st) = jax.jacfwd(f, has_aux=True)(z)
            return z2, st, J

        cache[key] = jax.jit(both)
    return cache[key]


def _weights(n: int) -> np.ndarray:
    t = (np.arange(n) + 0.5) / n
    return np.exp(-1.0 / (t * (1.0 - t)))


class MapEvaluator:
    """P (one period) and its Jacobian at single points, with the backend chosen once: native
    traces where the native backend runs the method (DP by central differences,
    :mod:`._native_map`), else the JAX map (DP exact by forward mode; its values and orbits come
    from the same compiled function, so the search compiles one JAX program). ``evaluations``
    counts the points carried one period."""

    def __init__(self, P: ReturnMap, backend: str = "auto"):
        if backend not in ("auto", "jax", "native"):
            raise ValueError(f"backend must be 'auto', 'jax' or 'native'; got {backend!r}")
        self.P = P
        self.native = backend != "jax" and select_backend(P.method, "auto")[0] == "native"
        if backend == "native" and not self.native:
            raise ValueError("backend='native': the native backend does not run this method")
        self.evaluations = 0
        self._vj_native = native_value_and_jac(P, 1) if self.native else None

    def _jax(self, z):  # the one compiled JAX program (value and DP)
        z2, st, J = _value_and_jac(self.P, 1)(jnp.asarray(z, jnp.float64))
        return np.asarray(z2), int(st), np.asarray(J)

    def value(self, z) -> tuple[np.ndarray | None, int]:
        """(P(z) − z or None, status)."""
        z = np.asarray(z, float)
        self.evaluations += 1
        if self.native:
            got = native_power(self.P, z[None, :], 1)
            z2, st = got[0][0], int(got[1][0])
        else:
            z2, st, _ = self._jax(z)
        if st != RESULTS.successful or not np.all(np.isfinite(z2)):
            return None, (st if st != RESULTS.successful else RESULTS.nonfinite)
        return z2 - z, st

    def value_and_jac(self, z) -> tuple[np.ndarray | None, int, np.ndarray | None]:
        """(P(z) − z, status, DP(z)); None in place of both arrays where the line fails."""
        z = np.asarray(z, float)
        if self.native:
            self.evaluations += 5
            z2, st, J = self._vj_native(z)
        else:
            self.evaluations += 1
            z2, st, J = self._jax(z)
        if st != RESULTS.successful or J is None or not (np.all(np.isfinite(z2)) and np.all(np.isfinite(J))):
            return None, (st if st != RESULTS.successful else RESULTS.nonfinite), None
        return np.asarray(z2) - z, st, np.asarray(J)

    def orbit(self, z, n: int) -> tuple[np.ndarray, int]:
        """(P¹(z), …, Pⁿ(z)) as (k, 2) with k ≤ n (the points before a failure) and the status."""
        z = np.asarray(z, float)
        if self.native:
            self.evaluations += n
            got = native_crossings(self.P, z[None, :], n)
            pts, st = got[0][0], int(got[1][0])
            ok = np.all(np.isfinite(pts), axis=1)
            k = int(np.argmin(ok)) if not ok.all() else n
            return pts[:k], st if st != RESULTS.successful or k == n else RESULTS.left_domain
        out = []
        for _ in range(n):
            self.evaluations += 1
            z2, st, _ = self._jax(z)
            if st != RESULTS.successful or not np.all(np.isfinite(z2)):
                return np.array(out).reshape(-1, 2), st if st != RESULTS.successful else RESULTS.nonfinite
            out.append(z2)
            z = z2
        return np.array(out), RESULTS.successful


@dataclass(frozen=True)
class AxisSearch:
    """What :func:`search_axis` found: ``z`` the best point (the converged fixed point, or the point
    of least residual seen), ``converged``, ``residual`` |P(z) − z| (NaN where the line from z
    fails), ``jacobian`` DP(z) (NaN where unknown), Newton ``iterations``, map ``evaluations``,
    ``refined`` the guess after the orbit averages, ``rounds`` of them kept, ``native`` whether
    native traces evaluated the map, ``message`` (one line: why not converged, and which point
    ``z`` is then)."""

    z: np.ndarray
    converged: bool
    residual: float
    jacobian: np.ndarray
    iterations: int
    evaluations: int
    refined: np.ndarray
    rounds: int
    native: bool
    message: str = ""


def refine_guess(ev: MapEvaluator, z0: np.ndarray, rounds: int, transits: int,
                 inside: Callable[[np.ndarray], bool]) -> tuple[np.ndarray, float, int]:
    """Stage 1 of the module docstring: (the refined guess, the last kept orbit's spread — inf if
    none —, the rounds kept)."""
    z, spread, kept = np.asarray(z0, float), math.inf, 0
    for _ in range(int(rounds)):
        pts, st = ev.orbit(z, transits)
        if st != RESULTS.successful or len(pts) < transits:
            break  # the line from z leaves the domain: z is not inside the axis's island
        w = _weights(len(pts))
        c = (w[:, None] * pts).sum(0) / w.sum()
        s = math.sqrt(float((w * np.sum((pts - c) ** 2, axis=1)).sum() / w.sum()))
        if not (np.all(np.isfinite(c)) and inside(c)) or not s < REFINE_GAIN * spread:
            break
        z, spread, kept = c, s, kept + 1
    return z, spread, kept


def search_axis(P: ReturnMap, guess: Any, *, inside: Callable[[np.ndarray], bool], scale: float,
                tol: float = 1e-12, max_iter: int = 30, refine: int = 3, transits: int = REFINE_TRANSITS,
                backend: str = "auto") -> AxisSearch:
    """The fixed point of P nearest ``guess`` by the two bounded stages of the module docstring.
    ``inside(z)`` says whether the section point z = (R, Z) lies in the field's box and domain;
    ``scale`` is the (R, Z) size of that box (the first trust radius is a tenth of it when no
    refinement round was kept). Never raises for a search that fails: ``converged`` is False and
    ``message`` says why."""
    if isinstance(max_iter, bool) or int(max_iter) != max_iter or max_iter < 0:
        raise ValueError(f"max_iter must be a non-negative integer; got {max_iter!r}")
    if isinstance(refine, bool) or int(refine) != refine or refine < 0:
        raise ValueError(f"refine must be a non-negative integer (rounds of orbit averages); got {refine!r}")
    if isinstance(transits, bool) or int(transits) != transits or transits < 4:
        raise ValueError(f"transits must be an integer ≥ 4 (points of a refinement orbit); got {transits!r}")
    ev = MapEvaluator(P, backend)
    g = np.asarray(guess, float).reshape(2)
    z, spread, rounds = refine_guess(ev, g, refine, int(transits), inside)
    refined = z.copy()
    nan_j = np.full((2, 2), np.nan)

    def fmt(p):
        return f"({p[0]:.6g}, {p[1]:.6g})"

    where = f"from the guess {fmt(g)}" + (f" (refined by {rounds} orbit average{'s' * (rounds > 1)} to "
                                           f"{fmt(refined)})" if rounds else "")
    def result(zb, conv, res, J, it, msg=""):
        return AxisSearch(z=np.asarray(zb, float), converged=conv, residual=float(res), jacobian=J, iterations=it,
                          evaluations=ev.evaluations, refined=refined, rounds=rounds, native=ev.native,
                          message=msg)

    F, st, J = ev.value_and_jac(z)
    # the answer of a failed search unless Newton gets far lower: the refined guess, even where the
    # map fails at it (beside a filament the orbit's centre is still the best estimate there is)
    answer = (z, float(np.linalg.norm(F)), J) if F is not None else (z, math.nan, nan_j)
    what = "the refined guess" if rounds else "the guess"
    if F is None and rounds:  # Newton needs the map: from the guess, where it may return
        why_refined = f"the return map fails at the refined guess {fmt(z)}: {status_message(st)}"
        z = g.copy()
        F, st, J = ev.value_and_jac(z)
        where = f"from the guess {fmt(g)} [{why_refined}]"
    if F is None:
        return result(answer[0], False, answer[1], answer[2], 0,
                      f"the return map fails {where}: {status_message(st)}; best: {what} {fmt(answer[0])}")
    res = float(np.linalg.norm(F))
    start = (z, res, J)
    best = start
    # Newton stays in a disc about its start: a few refinement spreads, or a tenth of the box (a
    # quarter without refinement); far from a fixed point |F| is a poor guide (near a singular axis,
    # e.g. a filament, a point at the box's edge can have the smaller residual)
    region = 4.0 * spread if math.isfinite(spread) else 0.0
    region = max(region, (0.1 if rounds else 0.25) * scale)
    radius = min(spread, region) if math.isfinite(spread) and spread > 0 else 0.1 * scale
    radius = max(radius, 1e-6 * scale)

    def failed(it, why):
        newton = best[1] <= NEWTON_WIN * start[1]
        zb, rb, Jb = best if newton else answer
        which = "Newton's point of least residual" if newton else what
        rtext = f"residual {rb:.3g}" if math.isfinite(rb) else "where the map fails"
        return result(zb, False, rb, Jb, it, f"{why}; best: {which} {fmt(zb)}, {rtext}")

    it = 0
    while not res <= tol * (1.0 + np.linalg.norm(z)):
        if it >= max_iter:
            return failed(it, f"Newton {where} did not converge in {max_iter} iterations; last residual {res:.3g} "
                              f"at {fmt(z)}")
        it += 1
        try:
            dz = -np.linalg.solve(J - np.eye(2), F)
        except np.linalg.LinAlgError:
            return failed(it, f"Newton {where} stopped at {fmt(z)}: DP − I is singular (a parabolic point); last "
                              f"residual {res:.3g}")
        length = float(np.linalg.norm(dz))
        capped = length > radius
        if capped:
            dz *= radius / length
        lam, accepted = 1.0, None
        for _ in range(HALVINGS + 1):
            zt = z + lam * dz
            if np.linalg.norm(zt - start[0]) <= region and inside(zt):
                Ft, stt = ev.value(zt)
                if Ft is not None and np.linalg.norm(Ft) <= (1.0 - ARMIJO * lam) * res:
                    accepted = zt
                    break
            lam *= 0.5
        if accepted is None:
            return failed(it, f"Newton {where} did not converge: no step within {region:.3g} of its start "
                              f"decreases the residual {res:.3g} at {fmt(z)} ({HALVINGS} halvings)")
        step = lam * float(np.linalg.norm(dz))
        radius = 2.0 * radius if (lam == 1.0 and capped) else (step if lam < 1.0 else radius)
        F2, st2, J2 = ev.value_and_jac(accepted)
        if F2 is None:  # the value was fine a moment ago: a Jacobian line failed (a neighbour left the grid)
            return failed(it, f"Newton {where}: the map's derivative fails at {fmt(accepted)}: {status_message(st2)}")
        z, F, J = accepted, F2, J2
        res = float(np.linalg.norm(F))
        if res < best[1]:
            best = (z, res, J)
    return result(z, True, res, J, it)

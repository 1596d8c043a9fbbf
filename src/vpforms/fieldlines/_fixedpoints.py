"""Magnetic axis and island chains: fixed points of the φ-return map P and of Pᵐ (issue #21, item 2).

A fixed point z* = Pᵐ(z*) is found by Newton's method on F(z) = Pᵐ(z) − z with the exact Jacobian
DPᵐ of the discrete map (forward-mode AD through the steps, :mod:`._returnmap`), with step halving
when the residual grows. Its type comes from the tangent map M = DPᵐ(z*) — det M = 1 at a fixed
point of an area-preserving map, in any coordinates; the discrete section map is area preserving up
to the location of the crossing on the step family, O(h^{p+1}) (det M − 1 = 6e-7 measured for the
m = 2 islands of the tokamak, order 2, h = 0.05) — by Greene's residue

    Res = (2 − tr M)/4:   0 < Res < 1 elliptic (O-point),  Res < 0 or Res > 1 hyperbolic (X-point),

and for an elliptic point the rotation number ν per m periods, cos 2πν = tr M / 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field as dc_field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, ConvergenceError
from ..backends import select_backend
from ..diagnostics._surfaces import wrap_angle
from ._axis_search import REFINE_TRANSITS, _value_and_jac, search_axis
from ._domain import check_radii, check_starts, rz_box
from ._geometry import is_toroidal
from ._native_map import native_crossings, native_value_and_jac, native_winding
from ._returnmap import ReturnMap, return_map, status_message

__all__ = ["FixedPoint", "find_fixed_point", "magnetic_axis"]


@dataclass(frozen=True)
class FixedPoint:
    """A fixed point (R, Z) of Pᵐ on the section φ = φ₀ (module docstring).

    ``m`` the period (1: the magnetic axis); ``residual`` |Pᵐ(z) − z| at the returned point;
    ``iterations`` of Newton; ``jacobian`` DPᵐ (2×2); ``trace``, ``det``; ``residue`` Greene's;
    ``kind`` "O" (elliptic), "X" (hyperbolic) or "parabolic"; ``orbit`` (m, 2) the chain
    z, P(z), …, Pᵐ⁻¹(z); ``iota`` the rotational transform of the linearised motion about the point,
    per toroidal turn (the axis's ι: elliptic points of m = 1 only; NaN otherwise).
    ``converged`` is False only for an axis returned by ``magnetic_axis(…, on_failure="guess")``
    after a failed search (``note`` says why and what R, Z are then); ``evaluations`` counts the
    points carried one period by the search (:mod:`._axis_search`; 0 where not counted).
    """

    R: float
    Z: float
    m: int
    residual: float
    iterations: int
    jacobian: np.ndarray
    residue: float
    kind: str
    orbit: np.ndarray
    phi0: float
    nfp: int
    iota: float = math.nan
    notes: tuple = dc_field(default_factory=tuple)
    converged: bool = True
    evaluations: int = 0

    @property
    def note(self) -> str:
        """The notes in one line ("" for a converged fixed point without remarks)."""
        return "; ".join(self.notes)

    @property
    def trace(self) -> float:
        return float(np.trace(self.jacobian))

    @property
    def det(self) -> float:
        return float(np.linalg.det(self.jacobian))

    @property
    def q(self) -> float:
        """1/ι (the safety factor of the axis)."""
        return 1.0 / self.iota if self.iota else math.inf


def _kind(res: float) -> str:
    if 0.0 < res < 1.0:
        return "O"
    if res < 0.0 or res > 1.0:
        return "X"
    return "parabolic"


def _polished(P: ReturnMap, q: np.ndarray, m: int, tol: float, backend: str) -> np.ndarray:
    """The fixed point of Pᵐ that Newton reaches from q in ≤ 5 iterations (q where it does not)."""
    try:
        fp = find_fixed_point(P, q, m, tol=tol, max_iter=5, backend=backend, _orbit=False)
    except (ConvergenceError, RuntimeError, ValueError):
        return np.asarray(q, float)
    return np.array([fp.R, fp.Z])


def find_fixed_point(P: ReturnMap, guess: Any, m: int = 1, *, tol: float = 1e-12, max_iter: int = 30,
                     backend: str = "auto", _orbit: bool = True) -> FixedPoint:
    """Newton's method for Pᵐ(z) = z from ``guess`` = (R, Z) (module docstring).

    Converged when |Pᵐ(z) − z| ≤ tol·(1 + |z|). Raises :class:`~vpforms.ConvergenceError` (one line,
    with the last residual) when Newton does not converge, and ``RuntimeError`` when the map itself
    fails (a line that does not return, a failed step).

    ``backend``: "auto" (default) evaluates Pᵐ natively where the native backend runs the method,
    DPᵐ by central differences (:mod:`._native_map`: seconds where the JAX map's exact
    forward-mode derivative through m periods compiles for minutes), else by JAX; "jax" or
    "native" forces one.

    The result's ``orbit`` is z, P(z), …, Pᵐ⁻¹(z). On the JAX map these are fixed points of Pᵐ
    as exactly as z (Pᵐ∘P = P∘Pᵐ). Native traces follow the line on through m periods rather than
    restarting at each crossing, so that Pᵐ and P∘…∘P differ by the integrator's own error
    (1e-6 at h = 0.05, order 2): there each Pᵏ(z) is polished by ≤ 5 Newton iterations into a
    fixed point of the same native Pᵐ, to ``tol``."""
    if backend not in ("auto", "jax", "native"):
        raise ValueError(f"backend must be 'auto', 'jax' or 'native'; got {backend!r}")
    if isinstance(m, bool) or int(m) != m or int(m) < 1:
        raise ValueError(f"m must be a positive integer; got {m!r}")
    m = int(m)
    z = np.asarray(guess, float).reshape(-1)
    if z.shape != (2,) or not np.all(np.isfinite(z)):
        raise ValueError(f"guess must be a finite (R, Z) pair; got {guess!r}")
    # native where the native backend runs the method (decided without a trace: a JAX section run
    # only to learn that it is not native would compile the JAX map for nothing)
    use_native = backend != "jax" and select_backend(P.method, "auto")[0] == "native"
    if backend == "native" and not use_native:
        raise ValueError("backend='native': the native backend does not run this method")
    native = [native_value_and_jac(P, m)] if use_native else [None]

    # a guess outside the field's box or domain says so (ValueError); a Newton trial point outside
    # is a failed evaluation (the line search halves the step), never a trace from outside
    _check_section_points(P.method, P.phi0, [z], "the fixed-point guess")
    inside = _inside_test(P.method, P.phi0)

    def evaluate(z):
        if not inside(z):
            return None, RESULTS.left_domain, None
        got = native[0](z) if native[0] is not None else None
        if got is None:  # the JAX map (exact DPᵐ by forward mode)
            if backend == "native":
                raise ValueError("backend='native': the native backend does not run this method")
            native[0] = None
            got = _value_and_jac(P, m)(jnp.asarray(z))
        z2, st, J = got
        st = int(st)
        if st != RESULTS.successful:
            return None, st, None
        return np.asarray(z2) - z, st, np.asarray(J)

    F, st, J = evaluate(z)
    if F is None:
        raise RuntimeError(f"the return map P^{m} failed at the guess (R, Z) = ({z[0]:.6g}, {z[1]:.6g}): "
                           f"{status_message(st)}")
    res = float(np.linalg.norm(F))
    it = 0
    while res > tol * (1.0 + np.linalg.norm(z)) and it < max_iter:
        it += 1
        A = J - np.eye(2)
        try:
            dz = -np.linalg.solve(A, F)
        except np.linalg.LinAlgError:
            raise ConvergenceError(f"Newton for the fixed point of P^{m} stopped at (R, Z) = ({z[0]:.6g}, {z[1]:.6g}): "
                                   f"DP^{m} − I is singular (a parabolic point); last residual {res:.3g}") from None
        lam = 1.0
        for _ in range(12):  # step halving: accept the first step that does not increase |F|
            z_new = z + lam * dz
            F_new, st_new, J_new = evaluate(z_new)
            if F_new is not None and np.linalg.norm(F_new) < max(res, 1e-300) * (1 + 1e-12) + 1e-300:
                break
            lam *= 0.5
        else:
            raise ConvergenceError(f"Newton for the fixed point of P^{m} from (R, Z) = ({guess[0]:.6g}, {guess[1]:.6g}) "
                                   f"did not converge: no step decreases the residual at ({z[0]:.6g}, {z[1]:.6g}); "
                                   f"last residual {res:.3g}")
        z, F, J = z_new, F_new, J_new
        res = float(np.linalg.norm(F))
    if not res <= tol * (1.0 + np.linalg.norm(z)):
        raise ConvergenceError(f"Newton for the fixed point of P^{m} from (R, Z) = ({guess[0]:.6g}, {guess[1]:.6g}) did "
                               f"not converge in {max_iter} iterations; last residual {res:.3g} at "
                               f"({z[0]:.6g}, {z[1]:.6g})")
    residue = (2.0 - float(np.trace(J))) / 4.0
    orbit = z[None, :]
    if m > 1 and _orbit:
        got = native_crossings(P, z, m - 1) if native[0] is not None else None
        orbit = np.vstack([z, got[0][0]]) if got is not None else P.orbit(z, m - 1)
        if got is not None:  # polish each Pᵏ(z) into a fixed point of the native Pᵐ (docstring)
            orbit = np.array([orbit[0]] + [_polished(P, q, m, tol, backend) for q in orbit[1:]])
    return FixedPoint(R=float(z[0]), Z=float(z[1]), m=m, residual=res, iterations=it, jacobian=J, residue=residue,
                      kind=_kind(residue), orbit=orbit, phi0=P.phi0, nfp=P.nfp)


def _tangent_winding(P: ReturnMap, z, n_periods: int) -> float:
    """The angle (in turns, per toroidal turn) that a tangent vector turns about the line from z
    in the (R, Z) plane, averaged over n_periods field periods: a rough ι of the linearised motion,
    used only to pick the branch of arccos(tr/2)."""
    step, h = P.method.step_with_status, P.h
    n = int(round(n_periods * P.period / abs(_mean_dphi(P, z))))

    def rz_tangent(x, v):
        if P.toroidal:
            R = jnp.sqrt(2.0 * x[0])
            return v[0] / R, v[2]
        R = jnp.hypot(x[0], x[1])
        return (x[0] * v[0] + x[1] * v[1]) / R, v[2]

    def body(c, _):
        x, v, ang, phi = c
        X, V = jax.jvp(lambda y: step(y, h)[0], (x,), (v,))
        a0, b0 = rz_tangent(x, v)
        a1, b1 = rz_tangent(X, V)
        ang = ang + wrap_angle(jnp.arctan2(b1, a1) - jnp.arctan2(b0, a0))
        phi = phi + P._dphi(X, x)
        return (X, V / jnp.linalg.norm(V), ang, phi), None

    cache = P.__dict__.setdefault("_jit_cache", {})
    if ("wind", n) in cache:
        return float(cache[("wind", n)](jnp.asarray(z)))

    @jax.jit
    def run(z):
        x = P.state(z)
        # along u (toroidal) or along e_R at φ₀ (Cartesian): transverse to the line
        v = jnp.array([1.0, 0.0, 0.0]) if P.toroidal else jnp.array([math.cos(P.phi0), math.sin(P.phi0), 0.0])
        (x, v, ang, phi), _ = jax.lax.scan(body, (x, v, 0.0, 0.0), None, length=n)
        return ang / phi

    cache[("wind", n)] = run
    return float(run(jnp.asarray(z)))


def _mean_dphi(P: ReturnMap, z) -> float:
    """dφ per step at z (one step)."""
    x = P.state(jnp.asarray(z))
    X, _ = P.method.step_with_status(x, P.h)
    return float(P._dphi(X, x))


def _check_section_points(method: Any, phi: float, rz: Any, what: str) -> None:
    """ValueError unless every (R, Z) of ``rz`` on the section φ = phi has R > 0 and lies in the
    field's box and domain (:mod:`._domain`): a guess outside says so, not "did not converge"."""
    rz = np.asarray(rz, float).reshape(-1, 2)
    if rz.shape[0] == 0 or not np.all(np.isfinite(rz)):
        return  # find_fixed_point names a non-finite guess
    indexed = rz.shape[0] > 1
    check_radii(rz[:, 0], what, indexed)
    field = getattr(method, "field", None)
    if field is None:
        return
    R, Z = rz[:, 0], rz[:, 1]
    if is_toroidal(field):
        pts = np.stack([0.5 * R * R, np.full_like(R, phi), Z], axis=1)
    else:
        pts = np.stack([R * math.cos(phi), R * math.sin(phi), Z], axis=1)
    check_starts(field, pts, what, "is", indexed)


def _inside_test(method: Any, phi: float):
    """z ↦ whether the section point z = (R, Z) has R > 0 and lies in the field's box and domain."""
    def inside(z) -> bool:
        try:
            _check_section_points(method, phi, [z], "point")
        except ValueError:
            return False
        return bool(np.all(np.isfinite(z)))

    return inside


def _box_scale(method: Any) -> float:
    """The (R, Z) size of the field's box (1 where it has none): the search's length scale."""
    box = rz_box(getattr(method, "field", None))
    if box is None:
        return 1.0
    size = max(box[0][1] - box[0][0], box[1][1] - box[1][0])
    return float(size) if math.isfinite(size) and size > 0 else 1.0


def _axis_iota(P: ReturnMap, z: np.ndarray, trace: float, native: bool) -> float:
    """ι of the linearised motion about the elliptic fixed point z of P (magnetic_axis's docstring)."""
    nu0 = math.acos(max(-1.0, min(1.0, trace / 2))) / (2 * math.pi)  # ∈ [0, 1/2]
    wind = native_winding(P, z, 8) if native else None
    rough = (wind if wind is not None else _tangent_winding(P, z, 8)) * P.period / (2 * math.pi)  # turns per period
    if not math.isfinite(rough):
        return math.nan
    k = math.floor(rough)
    cands = [c for kk in (k - 1, k, k + 1) for c in (kk + nu0, kk + 1 - nu0)]
    nu = min(cands, key=lambda c: abs(c - rough))
    return P.sign * nu * P.nfp  # per toroidal turn, signed by the direction of φ along B


def magnetic_axis(method: Any, guess: Any, h: float, phi: float = 0.0, nfp: int = 1, *, tol: float = 1e-12,
                  max_iter: int = 30, return_map_: ReturnMap | None = None, backend: str = "auto",
                  refine: int = 3, transits: int = REFINE_TRANSITS, on_failure: str = "raise") -> FixedPoint:
    """The magnetic axis on the section φ = phi: the fixed point of the return map P (m = 1) of
    ``method`` with step h, from ``guess`` = (R, Z), with its type and its rotational transform.

    The search is bounded and robust (:mod:`._axis_search`): the guess is first refined by at most
    ``refine`` rounds of Birkhoff-weighted averages of the orbit of ``transits`` returns (the centre
    of a closed curve about the axis, O(r²) off the axis for a guess r off), then damped Newton
    (trust radius, step halving on the residual) runs at most ``max_iter`` iterations. The budget is
    counted in map evaluations, never in seconds: the result does not depend on the machine's load.
    When the search fails, ``on_failure="raise"`` (default) raises
    :class:`~vpforms.ConvergenceError` (one line: the guess, the last residual, what to try);
    ``on_failure="guess"`` returns the refined guess (or Newton's point of least residual, where
    that is 1000× below the refined guess's) as a :class:`FixedPoint` with ``converged=False``,
    kind "unknown", ι NaN and a ``note`` saying why and which point it is, so that a study can go
    on from it.

    ι of the axis comes from the tangent map M = DP: cos(2π ι/nfp) = tr M / 2 gives ι up to the branch
    (ι/nfp ↦ k ± ν), which is chosen by the turning of a tangent vector followed for 8 field periods;
    it is the limit of the ι of the lines that approach the axis (the q₀ of a tokamak). A guess with
    R ≤ 0 or outside the field's box or domain is refused up front (ValueError saying "outside").
    ``backend`` as :func:`find_fixed_point` ("auto": native traces where they run — the branch's
    winding too, read at 8 planes per period from a neighbouring line)."""
    if on_failure not in ("raise", "guess"):
        raise ValueError(f"on_failure must be 'raise' or 'guess'; got {on_failure!r}")
    _check_section_points(method, phi, [guess], "the axis guess")
    g = np.asarray(guess, float).reshape(-1)
    if g.shape != (2,) or not np.all(np.isfinite(g)):
        raise ValueError(f"guess must be a finite (R, Z) pair; got {guess!r}")
    P = return_map_ or return_map(method, h, phi, nfp, guess=g)
    found = search_axis(P, g, inside=_inside_test(method, P.phi0), scale=_box_scale(method), tol=tol,
                        max_iter=max_iter, refine=refine, transits=transits, backend=backend)
    if not found.converged and on_failure == "raise":
        raise ConvergenceError(f"the magnetic axis: {found.message}; try a guess nearer the axis (the centre of "
                               "the innermost closed curve of a Poincaré section), a smaller step h, or "
                               "on_failure='guess' to go on from the best point")
    z, J = found.z, found.jacobian
    if found.converged:
        residue = (2.0 - float(np.trace(J))) / 4.0
        kind, notes = _kind(residue), ()
    else:  # not a fixed point: no type, no ι (DP there, where the map returns, stays for inspection)
        residue, kind = math.nan, "unknown"
        notes = (f"axis search not converged: {found.message}; R, Z are that best point",)
    iota = _axis_iota(P, z, float(np.trace(J)), found.native) if kind == "O" else math.nan
    return FixedPoint(R=float(z[0]), Z=float(z[1]), m=1, residual=found.residual, iterations=found.iterations,
                      jacobian=J, residue=residue, kind=kind, orbit=z[None, :], phi0=P.phi0, nfp=P.nfp, iota=iota,
                      notes=notes, converged=found.converged, evaluations=found.evaluations)

"""The abstract one-step method Ψ_h and the two operations of Section 3.3 of the paper.

Solver contract (every :class:`Method`)
---------------------------------------
* ``step(x, h)`` maps x of shape (3,) or (N, 3) to X = Ψ_h(x) of the same shape; ``h`` may be a
  traced JAX scalar, so a step can sit inside ``jax.jit``, ``jax.vmap``, ``lax.scan`` and
  ``jax.jacfwd``. Each method jits its batched step once (``h`` is a dynamic argument).
* ``step_with_status(x, h)`` returns ``(X, status)`` with a per-point ``RESULTS`` code (0 ok,
  1 twist failure, 2 Newton not converged, 3 non-finite); with ``return_iterations=True`` also the
  per-point number of scalar Newton iterations. Nothing raises inside jitted code.
* Every implicit equation is a *scalar* equation solved by the one Newton solver
  (:func:`vpforms._newton.newton_scalar`), so derivatives through a step are the exact
  implicit-function derivatives and ``det DΨ_h = 1`` to rounding.
* Traits are data: ``case`` (a :class:`~vpforms.Case`), ``cls`` (its class), ``order``,
  ``symmetric``.
* A method built on a generating form exposes ``generating_map(h, x)``: the
  :class:`~vpforms.GeneratingMap` of its own case whose solution is the step; its ``residual``
  checks the determining equations (eq:volpot) of that case.
* ``adjoint()`` is Ψ*_h = (Ψ_{−h})⁻¹, evaluated through the inverse map (prop:volpotinv), never
  by a Newton iteration on the whole step.

* ``stages``: the step as data, a tuple of :class:`Stage` (map, coefficient of h, normal form)
  applied left to right; one stage, the method itself, unless it is a composition
  (:mod:`vpforms._methods._stages`).

Relabelling (prop:trivperm) and adjunction (prop:switchperm) act on methods here:
:class:`Relabelled` is (π, π)·Ψ built on the relabelled field (``Method.relabel(π)``),
:class:`Adjoint` is Ψ* (``Method.adjoint()``); on a composition both act stage by stage.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._case import Case
from .._errors import RESULTS, VPFormsError, raise_for_status
from .._guard import KAPPA, guard_status
from .._map import _as_points, _batched
from .._perm import Perm, as_perm
from .._recovery import recover_points
from .._spec_record import method_spec
from ._relabel import relabelled_field

__all__ = ["Method", "GeneratingMethod", "Relabelled", "Adjoint", "RecipeError", "Stage",
           "memo_relabel", "merge_status"]

IDENTITY = Perm((1, 2, 3))


class RecipeError(VPFormsError, ValueError):
    """A class recipe cannot be applied to this field (e.g. a zero coefficient a₁₃ for S1)."""


# the engine's own point helpers: (3,) or (..., 3) arrays, vmapped per point
as_points = _as_points
batched = _batched


def merge_status(*codes):
    """The first non-successful status code of a sequence of solves (int32)."""
    out = jnp.int32(RESULTS.successful)
    for c in codes:
        out = jnp.where(out == RESULTS.successful, jnp.asarray(c, jnp.int32), out)
    return out


@dataclass(frozen=True, eq=False)
class Stage:
    """One stage of a step (issue #19, stages as data): ``method`` at ``coefficient``·h.

    ``method`` is (π, π)·``recipe``, adjoined when ``adjoint`` (prop:trivperm, prop:switchperm):
    its normal form. ``recipe`` is a class recipe, RK4, or a map vpforms does not look into (a
    recovering method, a sub-step ladder, a user's method). :mod:`vpforms._methods._stages` says
    how the operations act on lists of stages.
    """

    method: Any
    coefficient: float
    recipe: Any
    pi: Perm = IDENTITY
    adjoint: bool = False

    def scaled(self, c: float) -> "Stage":
        """The same map at c times the coefficient (a stage of a composition of compositions)."""
        return Stage(self.method, self.coefficient * c, self.recipe, self.pi, self.adjoint)


class Method(ABC):
    """A one-step volume-preserving method Ψ_h for a divergence-free field (see module docstring).

    Subclasses implement the per-point kernels ``_forward(x, h)`` (X = Ψ_h(x)) and
    ``_backward(X, h)`` (x = Ψ_h⁻¹(X)), each returning ``(value, status, iterations)`` for one
    point of shape (3,).
    """

    #: traits (data); subclasses set them in ``__init__``
    case: Case
    order: int = 1
    symmetric: bool = False
    field: Any = None
    name: str = "method"
    #: ``step_with_status`` takes a batch (N, 3) (a user method's contract is one point)
    takes_batches = True

    @property
    def cls(self) -> str:
        """The class of the method's case (fig:triangle)."""
        return self.case.cls

    # -- per-point kernels ----------------------------------------------------------------------
    @abstractmethod
    def _forward(self, x: jax.Array, h: Any):
        """X = Ψ_h(x) on one point: (X, status, iterations)."""

    @abstractmethod
    def _backward(self, X: jax.Array, h: Any):
        """x = Ψ_h⁻¹(X) on one point: (x, status, iterations)."""

    #: κ of the consistency guard (:mod:`vpforms._guard`); None switches it off
    guard_kappa: float | None = KAPPA

    def _accept(self, x, X, status, h):
        """The step's status (batched (N, 3)) as every backend reports it: ``nonfinite`` where X is
        not finite, ``inconsistent`` where the guard of :mod:`vpforms._guard` fails."""
        bad = ~jnp.all(jnp.isfinite(X), axis=-1)
        status = jnp.where((status == RESULTS.successful) & bad, RESULTS.nonfinite, status)
        if self.field is None:
            return status.astype(jnp.int32)
        inside = getattr(self.field, "inside", None)
        if self.guard_kappa is None and inside is None:
            return status.astype(jnp.int32)
        euler = jax.vmap(lambda p: self.euler_guess(p, h))(x)
        if self.guard_kappa is not None:
            status = guard_status(x, X, euler, status, self.guard_kappa)
        if inside is not None:  # a failed step whose Euler point is off the grid left the domain
            out = ~jax.vmap(inside)(euler) | ~jnp.all(jnp.isfinite(euler), axis=-1)
            status = jnp.where((status != RESULTS.successful) & out, RESULTS.left_domain, status)
        return status.astype(jnp.int32)

    #: the pair of potentials the recipe steps with ("se" or "dl"; None: it uses no potentials)
    splitting: str | None = None

    def _submethods(self) -> tuple:
        """The methods this one is built from (compositions, adjoints, recovery)."""
        return ()

    # -- stages as data (issue #19) --------------------------------------------------------------
    def _normal_form(self) -> tuple:
        """(recipe, π, adjoint) with self = ((π, π)·recipe)^(*adjoint) (see :class:`Stage`)."""
        return self, IDENTITY, False

    @property
    def stages(self) -> tuple:
        """The stages of one step, in the order they act (:class:`Stage`): a method that is not a
        composition is one stage, itself at coefficient 1."""
        return (Stage(self, 1.0, *self._normal_form()),)

    def relabel(self, pi: Perm | tuple) -> "Method":
        """(π, π)·Ψ (prop:trivperm): X = Ψ(x·π)·π⁻¹, the method of case (π∘σ, π∘Σ) for the field
        (π, π)·a, a(x) ↦ a(x·π)·π⁻¹ (this method's field relabelled by π⁻¹, as
        :func:`vpforms._methods._relabel.relabelled_field` writes it)."""
        return memo_relabel(self, pi, lambda pi: Relabelled(
            self, pi, relabelled_field(self.field, pi.inverse())))

    def check_domain(self, points: Any = None, what: str | None = None) -> None:
        """Raise :class:`~vpforms.fields.PotentialError` unless every pair of potentials the step
        uses reproduces the field on the field's box and at ``points`` (N, 3) — no singular set of
        a symbolic potential there, a numerical one within 1e-8 (issue #23). The message names the
        case, the potential and a point. :func:`vpforms.scheme` checks the box at construction,
        :func:`vpforms.integrate` the initial conditions at the start of a run."""
        what = what or f"case {self.case} ({self.cls})"
        if self.splitting is not None:
            self.field.check_potentials(self.splitting, points, what=what)
        for sub in self._submethods():
            sub.check_domain(points)

    def generating_map(self, h: Any, x: Any = None):
        """The GeneratingMap of :attr:`case` whose solution is the step (None if not generated).

        ``x`` (one point) only selects the branch of an inner implicit potential (the discrete
        Lagrangian's p̄); explicit potentials ignore it.
        """
        return None

    def residual(self, x: Any, X: Any, h: Any) -> jax.Array:
        """The determining equations (volpot1–3) of :attr:`case` at (x, X); zero on a step.

        Only for methods with a generating map (``generating_map(h) is not None``).
        """
        h = jnp.asarray(h, float)
        x = as_points(x)
        if self.generating_map(h, x if x.ndim == 1 else x[0]) is None:
            raise VPFormsError(f"{self.name} has no explicit generating map; use twist(x, h)")
        fn = self._cached_jit("residual", lambda: lambda x, X, h: _residual(self, x, X, h))
        return fn(x, jnp.broadcast_to(as_points(X), x.shape), h)

    # -- public, jit-compatible evaluation ------------------------------------------------------
    def _batched_step(self, x, h):
        """(X, status, iterations, recovered) on a batch x of shape (N, 3): the bare step is the
        per-point kernel vmapped; recovering methods (``_methods/recover.py``) and compositions
        override this to decide recovery once per batch (an unbatched ``lax.cond``)."""
        X, st, it = jax.vmap(lambda p: self._forward(p, h))(x)
        return X, st, it, jnp.zeros(st.shape, jnp.int32)

    def _jitted(self):
        fn = getattr(self, "_jit_cache", None)
        if fn is None:

            def guarded(x, h):
                X, st, it, rec = self._batched_step(x, h)
                return X, self._accept(x, X, st, h), it, rec

            def run(x, h):
                if x.ndim == 1:
                    out = guarded(x[None], h)
                    return tuple(o[0] for o in out)
                lead = x.shape[:-1]
                out = guarded(x.reshape(-1, 3), h)
                return tuple(o.reshape(*lead, *o.shape[1:]) for o in out)

            fn = jax.jit(run)
            self._jit_cache = fn
        return fn

    def _evaluate(self, x: Any, h: Any):
        """(X, status, iterations, recovered) of the step at x (3,) or (..., 3).

        A method with recovery (``without_recovery() is not self``) called on concrete arrays runs
        its BARE step and recovers only the points that failed, on the host
        (:func:`vpforms._recovery.recover_points`: the same alternatives in the same order), so
        the alternatives are compiled only when some point needs them.  Under tracing (a user's
        ``jit``/``vmap``, diffrax) the whole recovering step is one compiled function.  Either way
        the step taken is the same map; a point that no alternative steps keeps its bare status.
        """
        x = as_points(x)
        h = jnp.asarray(h, dtype=jnp.result_type(float))
        bare = self.without_recovery()
        if bare is self or h.ndim or any(isinstance(a, jax.core.Tracer) for a in (x, h)):
            return self._jitted()(x, h)
        X, st, it, _ = bare._jitted()(x, h)
        st = np.asarray(st)
        st = np.where((st == RESULTS.successful) & ~np.all(np.isfinite(np.asarray(X)), axis=-1),
                      RESULTS.nonfinite, st).astype(np.int32)  # never NaN marked successful
        rec = np.zeros(st.shape, np.int32)
        fail = np.flatnonzero(st.reshape(-1) != RESULTS.successful)
        if fail.size:
            Xr, sr, how = recover_points(self, np.asarray(x).reshape(-1, 3)[fail], float(h))
            ok = sr == RESULTS.successful
            Xf, sf, rf = np.array(X).reshape(-1, 3), st.reshape(-1), rec.reshape(-1)
            Xf[fail[ok]], sf[fail[ok]], rf[fail[ok]] = Xr[ok], RESULTS.successful, how[ok]
            X = Xf.reshape(np.shape(X))
        return jnp.asarray(X), jnp.asarray(st), it, jnp.asarray(rec)

    def step_with_status(self, x: Any, h: Any, *, return_iterations: bool = False):
        """(X, status[, iterations]) for x of shape (3,) or (N, 3); jit/vmap-compatible.

        ``iterations`` counts the scalar Newton iterations of the bare step."""
        X, status, iters, _ = self._evaluate(x, h)
        return (X, status, iters) if return_iterations else (X, status)

    def step_with_recovery(self, x: Any, h: Any):
        """(X, status, recovered) for x of shape (3,) or (N, 3); ``recovered`` is 0 where the bare
        step succeeded, else a :class:`vpforms.RECOVERY` code saying how the step was recovered."""
        X, status, _, rec = self._evaluate(x, h)
        return X, status, rec

    def without_recovery(self) -> "Method":
        """The same method with recovery stripped at every level (``self`` for a bare method).

        Memoised: the same object on every call, so that its compiled steps (keyed by the method's
        identity, e.g. in :func:`vpforms.integrate`) are reused from run to run."""
        memo = self.__dict__.get("_without_recovery")
        if memo is None:
            memo = self._strip_recovery()
            self.__dict__["_without_recovery"] = memo
        return memo

    def _strip_recovery(self) -> "Method":
        """Build :meth:`without_recovery` (subclasses that wrap other methods override this)."""
        return self

    def step(self, x: Any, h: Any) -> jax.Array:
        """X = Ψ_h(x), same shape as x (use :meth:`step_with_status` to see failures)."""
        return self.step_with_status(x, h)[0]

    def __call__(self, x: Any, h: Any) -> jax.Array:
        """X = Ψ_h(x); raises the named error if a point failed (not under jit)."""
        X, status = self.step_with_status(x, h)
        if isinstance(status, jax.core.Tracer):
            raise VPFormsError("Method.__call__ checks the status; under jit use step_with_status")
        if not bool(jnp.all(jnp.isfinite(jnp.asarray(h)))):  # else a misleading ConvergenceError
            raise ValueError(f"h must be finite, got {h}")
        raise_for_status(status, what=f"{self.name}{self.case}")
        return X

    def inverse_step(self, X: Any, h: Any) -> jax.Array:
        """x = Ψ_h⁻¹(X) (through the inverse map, not a Newton on the whole step)."""
        fn = self._cached_jit(
            "inverse", lambda: lambda X, h: batched(lambda p: self._backward(p, h)[0], X)
        )
        return fn(as_points(X), jnp.asarray(h, float))

    def _guess(self, x: jax.Array, h: Any):
        """(initial guess for X = Ψ_h(x), Newton iterations spent on it); only convergence
        depends on the guess."""
        return self.euler_guess(x, h), jnp.int32(0)

    def _guess_inverse(self, X: jax.Array, h: Any):
        """(initial guess for x = Ψ_h⁻¹(X), Newton iterations spent on it)."""
        return self.euler_guess(X, -h), jnp.int32(0)

    def euler_guess(self, x: jax.Array, h: Any) -> jax.Array:
        """x + h·a(x) — the initial guess of every solve (X = x + h a(x) + O(h²) by consistency)."""
        comps = self.field.components
        return x + h * jnp.stack([jnp.asarray(c(x[0], x[1], x[2]), float) for c in comps])

    # -- diagnostics -----------------------------------------------------------------------------
    def _cached_jit(self, key: str, make):
        cache = self.__dict__.setdefault("_jits", {})
        if key not in cache:
            cache[key] = jax.jit(make())
        return cache[key]

    def jacobian(self, x: Any, h: Any) -> jax.Array:
        """DΨ_h(x) by forward-mode AD (exact implicit-function derivatives), (3,3) or (N,3,3).

        The Jacobian of the step actually taken: for a method with recovery, where the bare step
        succeeds at every point (checked eagerly), the bare step's (the recovering step is that
        map there), else through the recovering step's chain of alternatives."""
        bare = self.without_recovery()
        if bare is not self and not any(isinstance(a, jax.core.Tracer) for a in (x, h)):
            if np.all(np.asarray(bare.step_with_status(x, h)[1]) == RESULTS.successful):
                return bare.jacobian(x, h)
        fn = self._cached_jit(
            "jacobian",
            lambda: lambda x, h: batched(
                lambda p: jax.jacfwd(lambda z: self._forward(z, h)[0])(p), x
            ),
        )
        return fn(as_points(x), jnp.asarray(h, float))

    def det(self, x: Any, h: Any) -> jax.Array:
        """det DΨ_h(x): 1 to rounding for every method in vpforms."""
        return jnp.linalg.det(self.jacobian(x, h))

    def twist(self, x: Any, h: Any) -> jax.Array:
        """The twist conditions of :attr:`case` at the step from x, shape (2,) or (N, 2).

        t₁ = ∂X₋/∂x₊ and t₂ = ∂x₋/∂X₊ (the LM table's conditions; ∂₁₂φ ≠ 0 and ∂₂₃Φ ≠ 0 of
        eq:volpot). A generating form of the case exists near (x, Ψ_h(x)) iff both are non-zero.
        For the correction maps this is a diagnostic: where it fails, the form ceases to exist,
        not the map.
        """
        c = self.case
        J = self.jacobian(x, h)
        t1 = J[..., c.X_minus - 1, c.x_plus - 1]
        t2 = jnp.linalg.inv(J)[..., c.x_minus - 1, c.X_plus - 1]
        return jnp.stack([t1, t2], axis=-1)

    # -- the two reductions ----------------------------------------------------------------------
    def adjoint(self) -> "Method":
        """Ψ*_h = (Ψ_{−h})⁻¹ (prop:switchperm): case (Σ, σ), evaluated through the inverse map.

        The same object on every call (its compiled steps are reused; the adjoint of a composition
        shares the maps of the original)."""
        memo = self.__dict__.get("_adjoint")
        if memo is None:
            memo = self.__dict__["_adjoint"] = Adjoint(self)
        return memo

    def spec(self) -> dict:
        """The JSON-able construction record that rebuilds this method (:func:`vpforms.method_from_spec`)."""
        return method_spec(self)

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(name={self.name!r}, case={self.case}, cls={self.cls!r}, "
            f"order={self.order}, symmetric={self.symmetric})"
        )


class GeneratingMethod(Method):
    """A method whose step is one GeneratingMap solve (eq:volpot) for its case.

    Subclasses implement ``generating_map(h, x)``; the step, its inverse (prop:volpotinv) and the
    residual all go through that one engine.
    """

    newton = {"tol": 1e-13, "max_iter": 50, "twist_tol": 1e-12}
    #: whether ``_forward``/``_backward`` are the engine's solve (False for a direct fast path)
    via_engine = True

    @abstractmethod
    def generating_map(self, h: Any, x: Any = None):
        ...

    def _forward(self, x, h):
        return solve_from_guess(self, self.generating_map(h, x), x, self._guess(_sg(x), h))

    def _backward(self, X, h):
        # prop:permactvolpotinv: the inverse is (Σ, σ)·f_{Φ·p, φ·p} with the same sign
        m = self.generating_map(h, X).inverse()
        return solve_from_guess(self, m, X, self._guess_inverse(_sg(X), h))



def memo_relabel(method: Method, pi: Perm | tuple, build) -> Method:
    """``method.relabel(π)`` = ``build(π)``, the same object on every call (as ``adjoint()``): the
    stages of a relabelled composition then share their maps, and Ψ*.relabel(π) is
    Ψ.relabel(π).adjoint(). The identity gives the method itself."""
    pi = as_perm(pi)
    if pi.is_identity:
        return method
    memo = method.__dict__.setdefault("_relabelled", {})
    if pi not in memo:
        out = build(pi)
        out.relabel_of = (method, pi)  # its spec is {"kind": "relabel", "base": …, "pi": …}
        memo[pi] = out
    return memo[pi]


def _sg(x):
    # an initial guess only selects the root: no derivative flows through it
    return jax.lax.stop_gradient(x)


def solve_from_guess(method, m, x, guess_and_iters):
    """``m.solve(x, guess)``; if the method's guess is itself the solution of the same equations in
    another (better conditioned) form, a disagreement beyond 1e-6 relative flags the point as not
    converged (the engine found another branch of an implicit potential). The iterations count
    those spent on the guess too."""
    guess, n_guess = guess_and_iters
    X, status, iters = m.solve(x, guess, return_iterations=True)
    iters = iters + n_guess
    if getattr(method, "guess_is_solution", False):
        far = jnp.max(jnp.abs(X - guess)) > 1e-6 * (1.0 + jnp.max(jnp.abs(X)))
        status = merge_status(status, jnp.where(far, RESULTS.not_converged, 0))
    return X, status, iters


def _residual(method, x, X, h):
    X = jnp.broadcast_to(X, x.shape)
    if x.ndim == 1:
        return method.generating_map(h, x).residual(x, X)
    return jax.vmap(lambda p, P: method.generating_map(h, p).residual(p, P))(
        x.reshape(-1, 3), X.reshape(-1, 3)
    ).reshape(x.shape)


class Relabelled(Method):
    """(π, π)·Ψ (prop:permactalg, prop:trivperm): the method ``base`` — built for the relabelled
    field (π⁻¹, π⁻¹)·a — conjugated by π, so X = Ψ(x·π)·π⁻¹ and the case is (π∘σ, π∘Σ).
    """

    def __init__(self, base: Method, pi: Perm | tuple, field: Any = None):
        self.base = base
        self.pi = as_perm(pi)
        self.case = base.case.relabel(self.pi)
        self.order, self.symmetric = base.order, base.symmetric
        self.field = field if field is not None else base.field
        self.name = base.name
        self.guess_is_solution = getattr(base, "guess_is_solution", False)
        self._pi_idx = jnp.asarray(self.pi.index)
        self._pi_inv_idx = jnp.asarray(self.pi.inverse().index)

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        return self if bare is self.base else Relabelled(bare, self.pi, self.field)

    def _normal_form(self) -> tuple:
        recipe, pi, adj = self.base._normal_form()  # (π, π)·(ρ, ρ)·R = (π∘ρ, π∘ρ)·R
        return recipe, self.pi * pi, adj

    def relabel(self, pi: Perm | tuple) -> Method:
        return memo_relabel(self, pi, lambda pi: Relabelled(
            self.base, pi * self.pi, relabelled_field(self.field, pi.inverse())))

    def check_domain(self, points: Any = None, what: str | None = None) -> None:
        # the base runs on the relabelled field at y = x·π
        y = None if points is None else np.asarray(points, float).reshape(-1, 3)[:, list(self.pi.index)]
        self.base.check_domain(y, what or f"case {self.case} ({self.cls})")

    def _guess(self, x, h):
        g, n = self.base._guess(x[self._pi_idx], h)
        return g[self._pi_inv_idx], n

    def _guess_inverse(self, X, h):
        g, n = self.base._guess_inverse(X[self._pi_idx], h)
        return g[self._pi_inv_idx], n

    def generating_map(self, h, x=None):
        y = None if x is None else jnp.asarray(x)[self._pi_idx]
        m = self.base.generating_map(h, y)
        return None if m is None else m.relabel(self.pi)

    def _forward(self, x, h):
        m = self.generating_map(h, x) if getattr(self.base, "via_engine", False) else None
        if m is not None:  # one engine: the relabelled generating map itself
            return solve_from_guess(self, m, x, self._guess(_sg(x), h))
        Y, st, it = self.base._forward(x[self._pi_idx], h)
        return Y[self._pi_inv_idx], st, it

    def _backward(self, X, h):
        m = self.generating_map(h, X) if getattr(self.base, "via_engine", False) else None
        if m is not None:
            return solve_from_guess(self, m.inverse(), X, self._guess_inverse(_sg(X), h))
        y, st, it = self.base._backward(X[self._pi_idx], h)
        return y[self._pi_inv_idx], st, it


class Adjoint(Method):
    """Ψ*_h = (Ψ_{−h})⁻¹ (prop:switchperm): the case (Σ, σ), potentials φ̃ = Φ(−h)·p,
    Φ̃ = φ(−h)·p, i.e. exactly ``GeneratingMap.inverse()`` of the map at −h."""

    def __init__(self, base: Method):
        self.base = base
        self.adjoint_of = base  # its spec is {"kind": "adjoint", "base": base.spec()}
        self.case = base.case.switched()
        self.order, self.symmetric = base.order, base.symmetric
        self.field = base.field
        self.name = base.name + "*"
        self.guess_is_solution = getattr(base, "guess_is_solution", False)

    def adjoint(self) -> Method:
        return self.base

    def relabel(self, pi: Perm | tuple) -> Method:
        return self.base.relabel(pi).adjoint()  # relabelling commutes with adjunction

    def _normal_form(self) -> tuple:
        recipe, pi, adj = self.base._normal_form()
        return recipe, pi, not adj

    def _submethods(self) -> tuple:
        return (self.base,)

    def check_domain(self, points: Any = None, what: str | None = None) -> None:
        self.base.check_domain(points, what or f"case {self.case} ({self.cls})")

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        return self if bare is self.base else bare.adjoint()

    def _guess(self, x, h):
        return self.base._guess_inverse(x, -h)

    def _guess_inverse(self, X, h):
        return self.base._guess(X, -h)

    def generating_map(self, h, x=None):
        m = self.base.generating_map(-h, x)
        return None if m is None else m.inverse()

    def _forward(self, x, h):
        return self.base._backward(x, -h)

    def _backward(self, X, h):
        return self.base._forward(X, -h)

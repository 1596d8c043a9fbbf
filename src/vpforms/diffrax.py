"""A vpforms method as a :mod:`diffrax` solver (optional extra ``vpforms[diffrax]``).

::

    import diffrax, jax.numpy as jnp, vpforms
    from vpforms import problems
    from vpforms.diffrax import VPSolver, field_term

    abc = problems.get("abc").field
    method = vpforms.compose(vpforms.scheme(abc, "SE+SE", recover=False), order=4)
    ts = jnp.linspace(0.0, 10.0, 81)  # the step times of dt0 = 0.125
    sol = diffrax.diffeqsolve(field_term(method), VPSolver(method), t0=0.0, t1=10.0, dt0=0.125,
                              y0=jnp.array([0.1, 0.2, 0.3]), saveat=diffrax.SaveAt(ts=ts))

What applies and what does not
------------------------------
* **Constant step only.** A step is ``method.step_with_status(y, t1 - t0)`` (so it has the
  method's step recovery, where the method has one); there is no error estimate
  (``error_order`` is None), so an adaptive ``stepsize_controller`` (``PIDController``) is refused
  by diffrax itself with "Cannot use adaptive step sizes with a solver that does not provide error
  estimates".  Use the default ``ConstantStepSize`` with ``dt0`` (or ``StepTo``).  diffrax
  advances time by adding ``dt0``, and a step is taken with h = t_{n+1} − t_n: with a ``dt0``
  that is a binary fraction (0.125) h is exact and the states are ``integrate``'s to rounding;
  with 0.1, h differs from 0.1 in the last bits and a Newton-solved step (all but the SE+SE
  closed form) can differ from ``integrate``'s at the Newton tolerance (~1e-13 per step).
* **The term's vector field does not drive the step.**  The method carries its own field (the
  generating potentials are built from it).  The term is used by diffrax only through
  :meth:`VPSolver.func` (initial-step heuristics, which a constant step never calls).  Pass
  :func:`field_term` (``ODETerm`` of ``method.field``) so that the two agree; diffrax refuses a term
  that is not an ``ODETerm`` (``term_structure``); a different field in the term is NOT detected.
* **Dense output is linear** (``LocalLinearInterpolation``, like diffrax's ``Euler``): exact at
  the step times, O(h²) in between.  ``SaveAt(ts=...)`` and ``SaveAt(dense=True)`` use it.
* **Events** (``diffrax.Event``) apply, on the constant step grid: the condition is evaluated at
  the step times t_n, so an event is detected in the step t_n → t_{n+1} where it changes sign.
  Without a ``root_finder`` the solve ends at t_{n+1} (the state there is the method's, as in
  ``integrate``).  With a ``root_finder`` (e.g. ``optimistix.Newton``) the located time is the
  root on the linear dense output, i.e. the crossing of the chord x_n → x_{n+1} — what
  ``vpforms.diagnostics.poincare_section(..., interpolation="linear")`` computes (error O(h²)),
  not the order-p crossing of its default ``interpolation="step"``.
* **Failures.** A non-zero vpforms status (twist failure, Newton not converged, non-finite, a step
  that fails the consistency guard of :mod:`vpforms._guard`) maps
  to ``diffrax.RESULTS.nonlinear_divergence`` (non-finite to ``RESULTS.nonfinite``; a non-finite
  result reported as a success is non-finite, as in :func:`vpforms.integrate`): with
  ``throw=True`` ``diffeqsolve`` raises, with ``throw=False`` ``sol.result`` says so.  The failed
  step leaves the state where it was (``integrate`` freezes the particle the same way) and diffrax
  stops: ``sol.stats["num_steps"]`` is ``Solution.failed_step + 1``, the save time right after
  the failure holds the frozen state and later save times hold diffrax's fill value ``inf``.
* **Recovery.** A recovering method (``vpforms.scheme``'s default ``recover=True``) recovers a
  failed step inside the diffrax step with the same alternatives in the same order as
  ``integrate`` (the same numbers; tested).  ``integrate`` compiles the alternatives lazily, only
  when a bare step has failed; inside ``diffeqsolve`` they are all compiled into the step up
  front (≈ 10 generating maps: tens of seconds of compilation).  Pass ``recover=False`` (or
  ``recover_classes=False``) when that matters more than recovery.
* **Not applicable:** SDEs / control terms (``term_structure`` is ``ODETerm``), adaptive steps,
  error estimates, ``made_jump`` (the method has no FSAL state), backward-in-time solves with a
  method whose field is not reversible are the method's own business (h < 0 is passed through).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp

from . import _config  # noqa: F401  (float64)
from ._errors import RESULTS as VP_RESULTS

try:
    import diffrax as _dfx
except ImportError as err:  # pragma: no cover - exercised only without the extra
    raise ImportError("vpforms.diffrax needs diffrax: pip install 'vpforms[diffrax]'") from err

__all__ = ["VPSolver", "field_term", "to_diffrax_result"]


def field_term(method: Any) -> "_dfx.ODETerm":
    """``diffrax.ODETerm`` of the method's own field: ``(t, y, args) -> method.field(y)``."""
    field = getattr(method, "field", None)
    if not callable(field):
        raise TypeError(f"{type(method).__name__} has no callable .field to build a term from")
    return _dfx.ODETerm(lambda t, y, args: field(y))


def to_diffrax_result(status) -> "_dfx.RESULTS":
    """The diffrax ``RESULTS`` of a vpforms status code (a scalar int32, possibly traced)."""
    status = jnp.asarray(status, jnp.int32)
    bad = _dfx.RESULTS.where(status == VP_RESULTS.nonfinite, _dfx.RESULTS.nonfinite,
                             _dfx.RESULTS.nonlinear_divergence)
    return _dfx.RESULTS.where(status == VP_RESULTS.successful, _dfx.RESULTS.successful, bad)


class VPSolver(_dfx.AbstractSolver):
    """A vpforms one-step method (anything with ``step_with_status(x, h)``) as a diffrax solver.

    Attributes
    ----------
    method:
        ``vpforms.scheme(...)``, ``vpforms.compose(...)``, :class:`vpforms.RK4` or any object with
        ``step_with_status(x, h) -> (X, status)`` for x of shape (3,), and an ``order`` attribute.

    Notes
    -----
    See the module docstring for what diffrax features apply (constant step, linear dense
    output, events on the chord) and which do not (adaptive steps, error estimates, SDEs).
    """

    method: Any = eqx.field(static=True)

    term_structure: ClassVar = _dfx.ODETerm
    interpolation_cls: ClassVar[Callable[..., _dfx.LocalLinearInterpolation]] = (
        _dfx.LocalLinearInterpolation
    )

    def __check_init__(self):
        if not callable(getattr(self.method, "step_with_status", None)):
            raise TypeError(
                f"VPSolver needs a vpforms method with step_with_status(x, h); got {type(self.method).__name__}"
            )

    def order(self, terms):
        return int(getattr(self.method, "order", 1))

    def strong_order(self, terms):
        return None

    def error_order(self, terms):
        return None  # no embedded error estimate: constant step only

    def init(self, terms, t0, t1, y0, args):
        # diffrax itself checks the term against term_structure (one ODETerm) before init
        if jnp.shape(y0) != (3,):
            raise ValueError(f"VPSolver integrates one point y0 of shape (3,) (vmap for many), "
                             f"got shape {jnp.shape(y0)}")
        return None

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del terms, args, solver_state, made_jump
        # Ψ_h(y0) with h = t1 − t0: the method's implicit generating-map step (eq:volpot1–3)
        y1, status = self.method.step_with_status(y0, t1 - t0)
        status = jnp.asarray(status, jnp.int32)
        # as vpforms.integrate: a non-finite result reported as a success (a user method) is a
        # failure (RESULTS.nonfinite), never a NaN handed on as a good state
        status = jnp.where((status == VP_RESULTS.successful) & ~jnp.all(jnp.isfinite(y1)),
                           VP_RESULTS.nonfinite, status)
        y1 = jnp.where(status == VP_RESULTS.successful, y1, y0)  # never hand NaN to diffrax
        dense_info = dict(y0=y0, y1=y1)
        return y1, None, dense_info, None, to_diffrax_result(status)

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

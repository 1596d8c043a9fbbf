"""Recovery of failing steps (issue #12): a method that, where its bare step fails, takes the
step with a fixed list of volume-preserving alternatives instead of freezing the particle.

Recovery order (first success wins; every alternative is itself a VP map, so the step taken is
volume preserving):

0. for the DL classes in the engine form: the SAME map evaluated by its nested θ-stages
   (``fast=True``), well conditioned at the fold ∂²H/∂p² = 0 where the engine fails;
1. the other cases of the same class (the 36-case order of :func:`vpforms.cases`);
2. the representatives of the other classes (S1, S2, SE+SE, DL+DL, SE+DL order);
3. 2, 4, …, 2^k sub-steps of size h/2^j of the bare method (k = ``recover_substeps``, default 6).

Only then does the step report the bare failure (``integrate`` freezes the particle).  A step
that left the domain (``RESULTS.left_domain``: a wall, a gridded field's box) is a stop, never
retried: every alternative evaluates the same field, which does not exist out there (issue #41: a
line started at a grid's edge went through every alternative, 110–150 s of compilations).  An
alternative is accepted only if it passes the consistency guard (:mod:`vpforms._guard`) and, for
1 and 2, agrees with the RK4 step to ``KAPPA_ALT``·|h a(x)|: it replaces a failed step, so it must be
right.  Alternatives whose potentials are refused on the field's box (:meth:`Method.check_domain`)
are never built; ``Recovering.refused`` lists them with the reason (issue #23).

What recovery does to the order: a composition of a recovering method recovers its COMPOSED step
(:func:`vpforms.compose`): the alternatives are the same composition of each alternative, so a
recovered step has the order of the composition (issue #19, item 5; before, each stage recovered
on its own and a switched stage made the step an order-1 map: tokamak DL+DL composed to order 4
showed observed order 1.56).  Switching between different methods of the same order still moves
the trajectory between their modified invariants (measured on the Solov'ev tokamak: relative flux
error not O(h²) when DL+DL order 2 recovered by other cases/classes); the same-map alternative 0
does not — with it the engine-form run equals the stage-form run (flux error 0.088 → 0.023 as h
halves, tests/test_right_steps.py).

Cost: the decision is made once per BATCH. ``_batched_step`` runs the bare step on all points
(vmap), then ``lax.cond(any(status != 0), recover, identity)`` with an unbatched predicate: when
no step fails nothing else runs. Inside ``recover`` the failing points are gathered into buffers
of K points (``jnp.nonzero(size=K)``, a ``lax.while_loop`` while some remain), the alternatives
are tried in order on the buffer (each behind its own unbatched cond) and the results scattered
back. A point's result depends only on that point: chunk-independent and deterministic.
"""

from __future__ import annotations

import threading
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._case import CLASSES, cases
from .._errors import RECOVERY, RESULTS, VPFormsError
from .._guard import alternative_status
from .._recovery import checked_status, padded_steps
from ._base import Method, memo_relabel, merge_status

__all__ = ["Recovering", "SubstepLadder"]

#: points recovered per buffer pass
_BUFFER = 32


def _retried(status):
    """Where a failed step is retried by the alternatives: every failure but ``left_domain`` — a
    line that left the domain (a wall, a gridded field's box) stopped, and every alternative
    evaluates the same field, which does not exist out there (numpy or JAX status)."""
    return (status != RESULTS.successful) & (status != RESULTS.left_domain)


class SubstepLadder(Method):
    """Ψ_{h/m}^m for m = 2, 4, …, 2^k: the first m whose sub-steps all succeed wins.

    Each rung is a composition of VP maps of the bare method, so the step taken is VP.  The rung
    index is a traced loop variable: the bare step is compiled ONCE for the whole ladder (not once
    per m), which keeps a recovering scheme's compilation close to the bare one's.
    """

    def __init__(self, base: Method, k: int):
        self.base, self.k = base, int(k)
        self.case, self.field = base.case, base.field
        self.order, self.symmetric = base.order, base.symmetric
        self.name = f"{base.name}^(2..2^{self.k})"

    def adjoint(self) -> Method:
        return SubstepLadder(self.base.adjoint(), self.k)

    def relabel(self, pi) -> Method:
        return SubstepLadder(self.base.relabel(pi), self.k)

    def _submethods(self) -> tuple:
        return (self.base,)

    def _strip_recovery(self) -> Method:
        bare = self.base.without_recovery()
        return self if bare is self.base else SubstepLadder(bare, self.k)

    @staticmethod
    def _rung(fn, x, h, j, merge):
        """m = 2^j sub-steps of size h/m of ``fn`` (a traced trip count)."""
        m = jnp.left_shift(jnp.int32(1), j)

        def body(_, c):
            x, st, n = c
            X, s, k = fn(x, h / m)
            return X, merge(st, s), n + k

        z = jnp.zeros(x.shape[:-1], jnp.int32)
        return lax.fori_loop(0, m, body, (x, z, z))

    def _ladder(self, fn, x, h, merge, hg=None):
        """Rungs j = 1…k while some point is still failing; (X, status, iterations). A rung is
        accepted only if it passes the guard of the step over ``hg`` (h; −h for the inverse)."""
        hg = h if hg is None else hg
        batched = x.ndim == 2
        z = jnp.zeros(x.shape[:-1], jnp.int32)
        init = (jnp.int32(0), x, z + RESULTS.not_converged, z)

        def cond(c):
            return (c[0] < self.k) & jnp.any(c[2] != RESULTS.successful)

        def body(c):
            j, X, st, it = c
            Xj, sj, ij = self._rung(fn, x, h, j + 1, merge)
            sj = (self._accept(x, Xj, sj, hg) if batched
                  else self._accept(x[None], Xj[None], sj[None], hg)[0])
            pending = st != RESULTS.successful
            X = jnp.where((pending & (sj == RESULTS.successful))[..., None], Xj, X)
            return j + 1, X, jnp.where(pending, sj, st), it + jnp.where(pending, ij, 0)

        return lax.while_loop(cond, body, init)[1:]

    def _forward(self, x, h):
        return self._ladder(self.base._forward, x, h, merge_status)

    def _backward(self, X, h):
        return self._ladder(self.base._backward, X, h, merge_status, -h)

    def _batched_step(self, x, h):
        X, st, it = self._ladder(lambda p, h: self.base._batched_step(p, h)[:3], x, h,
                                 jax.vmap(merge_status))
        return X, st, it, jnp.zeros(st.shape, jnp.int32)


class Recovering(Method):
    """``bare`` with recovery: ``alternatives`` is a tuple of (method, RECOVERY code) tried in
    order where the bare step fails (see the module docstring).

    ``alternatives`` may also be a zero-argument callable returning (alternatives, refused): they
    are then built on first use — a run whose bare steps never fail (the native backend recovers
    on the host, :mod:`vpforms.backends._advance`) never pays their construction and domain
    checks (≈ 18 s for the ten alternatives of SE+SE on a coil spline field, issue #41)."""

    def __init__(self, bare: Method, alternatives, buffer: int = _BUFFER, refused=()):
        self.bare = bare
        if callable(alternatives):
            self._source, self._built = alternatives, None
        else:
            self._source, self._built = None, (tuple(alternatives), tuple(refused))
        self._lock = threading.Lock()
        self.buffer = int(buffer)
        self.case, self.field = bare.case, bare.field
        self.order, self.symmetric = bare.order, bare.symmetric
        self.name = bare.name
        self.guess_is_solution = getattr(bare, "guess_is_solution", False)

    def __getstate__(self):  # a lock does not pickle (Dask ships methods): a fresh one on arrival
        return {k: v for k, v in self.__dict__.items() if k != "_lock"}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def _alternatives_and_refused(self) -> tuple:
        with self._lock:  # one build, also when Dask worker threads share the method
            if self._built is None:
                # first used inside a trace (a jitted recovering step): the methods are built
                # eagerly all the same — their constants must not be tracers of that trace
                with jax.ensure_compile_time_eval():
                    alts, refused = self._source()
                self._built = (tuple(alts), tuple(refused))
        return self._built

    @property
    def alternatives(self) -> tuple:
        """(method, RECOVERY code) in the order they are tried (built on first use)."""
        return self._alternatives_and_refused()[0]

    @property
    def refused(self) -> tuple:
        """(case or class, reason) of the alternatives that could not be built for this field (e.g.
        potentials singular inside the box): never tried (building them if not yet built)."""
        return self._alternatives_and_refused()[1]

    def _derived(self, bare: Method, each) -> "Recovering":
        """A Recovering of ``bare`` whose alternatives are ``each(alternative)``, as lazy as this one's."""
        return Recovering(bare, lambda: ([(each(a), c) for a, c in self.alternatives], self.refused),
                          self.buffer)

    def __getattr__(self, item):  # traits of the bare method (theta, printed, …)
        if item == "bare" or item.startswith("_"):  # never the bare jit caches
            raise AttributeError(item)
        return getattr(self.__dict__["bare"], item)

    def _strip_recovery(self) -> Method:
        return self.bare.without_recovery()

    def _submethods(self) -> tuple:
        return (self.bare,)  # alternatives were checked on the box when built; only the bare step must run

    def adjoint(self) -> Method:
        out = self._derived(self.bare.adjoint(), lambda a: a.adjoint())
        out.adjoint_of = self  # its spec is {"kind": "adjoint", "base": self.spec()}
        return out

    def relabel(self, pi) -> Method:
        """(π, π)·Ψ with recovery: the bare step and every alternative relabelled (prop:trivperm;
        a relabelled case of the class is a case of the class)."""
        return memo_relabel(self, pi, lambda pi: self._derived(self.bare.relabel(pi), lambda a: a.relabel(pi)))

    def generating_map(self, h, x=None):
        return self.bare.generating_map(h, x)

    def _host_recover(self, x: np.ndarray, h: float, bare_failed: bool = False):
        """(X, status, how) at x (M, 3) on the host (:func:`vpforms._recovery.recover_points`).

        The bare step, then each alternative on the points still failing, in order, stopping as
        soon as none fails: an alternative is compiled only when a point needs it.  The same
        choice as :meth:`_batched_step`.  ``bare_failed``: the bare step is known to have failed
        at every point (skip it)."""
        if bare_failed:
            X, st = x.copy(), np.full(x.shape[0], RESULTS.not_converged, np.int32)
        else:
            X, st = padded_steps(self.bare.step_with_status, x, h)
            st = checked_status(X, st)
        how = np.zeros(x.shape[0], np.int32)
        for alt, code in self.alternatives:
            pend = np.flatnonzero(_retried(st))
            if pend.size == 0:
                break
            Xa, sa = padded_steps(alt.step_with_status, x[pend], h)
            sa = checked_status(Xa, sa)
            if code != RECOVERY.substeps:  # another case or class must agree with RK4 (_guard)
                sa = np.asarray(self.alternative_ok(x[pend], Xa, sa, h), np.int32)
            ok = sa == RESULTS.successful
            X[pend[ok]], how[pend[ok]] = Xa[ok], code
            st[pend] = sa
        return X, st, how

    def alternative_ok(self, x, X, status, h):
        """:func:`vpforms._guard.alternative_status` at x, X (M, 3) (jitted once per method)."""
        fn = self._cached_jit("alternative", lambda: lambda x, X, s, h: alternative_status(
            self.field.components, x, X, h, s))
        return fn(jnp.asarray(x), jnp.asarray(X), jnp.asarray(status, jnp.int32),
                  jnp.asarray(h, float))

    # per-point (jacobian, inverse, use inside a user's vmap): the same choice, by a cond chain
    def _chain(self, kernel, x, h, hg):
        def checked(X, st):  # nonfinite and the guard of the step over hg (h; −h for the inverse)
            return self._accept(x[None], X[None], st[None], hg)[0]

        X, st, it = kernel(self.bare, x, h)
        st = checked(X, st)
        rec = jnp.int32(0)
        for alt, code in self.alternatives:
            def take(c, alt=alt, code=code):
                X, st, it, rec = c
                Xa, sa, ia = kernel(alt, x, h)
                sa = checked(Xa, sa)
                if code != RECOVERY.substeps:  # another case or class: must agree with RK4
                    sa = alternative_status(self.field.components, x[None], Xa[None], hg,
                                            sa[None])[0]
                ok = sa == RESULTS.successful
                return (jnp.where(ok, Xa, X), jnp.where(ok, sa, st), it + ia,
                        jnp.where(ok, jnp.int32(code), rec))

            X, st, it, rec = lax.cond(_retried(st), take, lambda c: c, (X, st, it, rec))
        return X, st, it, rec

    def _forward(self, x, h):
        return self._chain(lambda m, p, h: m._forward(p, h), x, h, h)[:3]

    def _backward(self, X, h):
        return self._chain(lambda m, p, h: m._backward(p, h), X, h, -h)[:3]

    def _recover_buffer(self, xb, valid, h):
        """Alternatives in order on a buffer of K failing points (``valid`` marks real ones)."""
        K = xb.shape[0]
        init = (xb, jnp.full(K, RESULTS.not_converged, jnp.int32), jnp.zeros(K, jnp.int32),
                jnp.zeros(K, jnp.int32))
        c = init
        for alt, code in self.alternatives:
            def take(c, alt=alt, code=code):
                X, st, it, rec = c
                Xa, sa, ia, _ = alt._batched_step(xb, h)
                sa = self._accept(xb, Xa, sa, h)  # accepted only if it passes the guard
                if code != RECOVERY.substeps:  # another case or class: must agree with RK4
                    sa = alternative_status(self.field.components, xb, Xa, h, sa)
                ok = (st != RESULTS.successful) & (sa == RESULTS.successful)
                return (jnp.where(ok[:, None], Xa, X), jnp.where(ok, sa, st), it + ia,
                        jnp.where(ok, jnp.int32(code), rec))

            pending = jnp.any(valid & (c[1] != RESULTS.successful))
            c = lax.cond(pending, take, lambda c: c, c)
        return c

    def _batched_step(self, x, h):
        X, st, it, _ = self.bare._batched_step(x, h)
        st = self._accept(x, X, st, h)
        rec = jnp.zeros(st.shape, jnp.int32)
        N = x.shape[0]
        K = min(self.buffer, N)

        def recover(c):
            def cond(c):
                return jnp.any(c[4])

            def body(c):
                X, st, it, rec, todo = c
                (idx,) = jnp.nonzero(todo, size=K, fill_value=N)
                valid = idx < N
                xb = jnp.take(x, idx, axis=0, mode="clip")
                Xb, sb, ib, rb = self._recover_buffer(xb, valid, h)
                won = sb == RESULTS.successful
                idx_w = jnp.where(won, idx, N)  # only recovered points are written back
                X = X.at[idx_w].set(Xb, mode="drop")
                st = st.at[idx_w].set(sb, mode="drop")
                rec = rec.at[idx_w].set(rb, mode="drop")
                it = it.at[idx].add(ib, mode="drop")
                todo = todo.at[idx].set(False, mode="drop")
                return X, st, it, rec, todo

            return lax.while_loop(cond, body, c + (_retried(c[1]),))[:4]

        return lax.cond(jnp.any(_retried(st)), recover, lambda c: c, (X, st, it, rec))


def recovering(field: Any, case, bare: Method, build, substeps: int = 6, classes: bool = True,
               refused=(), first=()):
    """``Recovering(bare, …)`` with the alternatives of the module docstring, built on first use;
    ``build(case_or_cls)`` makes a bare method (None where the recipe does not apply to the field,
    the reason then in ``refused``, which ``build`` appends to); ``first``: the alternatives tried
    before the other cases (or a callable making them, also on first use)."""

    def alternatives():
        alts = list(first() if callable(first) else first)
        for c in cases():
            if c.cls == case.cls and c != case:
                m = build(c)
                if m is not None:
                    alts.append((m, RECOVERY.other_case))
        if classes:
            for k in CLASSES:
                if k != case.cls:
                    m = build(k)
                    if m is not None:
                        alts.append((m, RECOVERY.other_class))
        if int(substeps) > 0:
            alts.append((SubstepLadder(bare, substeps), RECOVERY.substeps))
        return alts, refused

    return Recovering(bare, alternatives)


def recovering_scheme(scheme, field, case, options, substeps, classes):
    """``scheme(field, case, recover=True, **options)``: the bare scheme wrapped in recovery."""
    bare = scheme(field, case, recover=False, **options)
    newton = {"newton": options["newton"]} if "newton" in options else {}

    refused = []

    def build(c):
        try:
            if isinstance(c, str):  # another class: its representative, class options dropped
                return scheme(field, c, recover=False, **newton)
            return scheme(field, c, recover=False, **options)
        except (VPFormsError, ValueError) as err:  # e.g. potentials singular inside the box
            refused.append((c, str(err)))
            return None

    def first():
        if not (bare.cls in ("SE+DL", "DL+DL") and options.get("fast") is False and not options.get("printed")):
            return []
        # the engine form fails (or loses digits) at the fold of a DL stage where the nested
        # θ-stages of the SAME map do not: that map first, so a recovered step changes nothing but
        # the evaluation (switching methods would cost the composition's order and invariants)
        try:
            return [(scheme(field, bare.case, recover=False, **{**options, "fast": True}), RECOVERY.same_map)]
        except (VPFormsError, ValueError) as err:
            refused.append((bare.case, str(err)))
            return []

    return recovering(field, bare.case, bare, build, substeps=substeps, classes=classes,
                      refused=refused, first=first)

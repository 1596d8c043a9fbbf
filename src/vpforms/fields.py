"""Divergence-free vector fields on R³ and their generating-form potentials (MATH.md §3).

Every generating-form method consumes *potentials*, not the field:

* SE+SE (and the SE stages):  a = vf1(F¹) + vf3(F³)          (eq:vf1, eq:vf3)
* DL classes:                 a = vf1(G¹) + vf2(G²)          (eq:vf1, eq:vf2)

with vf1(F) = (0, ∂₃F, −∂₂F), vf2(F) = (−∂₃F, 0, ∂₁F), vf3(F) = (∂₂F, −∂₁F, 0).  For a
divergence-free a they are built by one-dimensional integrals from a base point c (``origin``,
default 0, which gives exactly the formulas of MATH.md §3):

    F³ = ∫_{c₂}^{x₂} a₁(x₁,s,x₃) ds,
    F¹ = −∫_{c₂}^{x₂} a₃(x₁,s,x₃) ds + ∫_{c₃}^{x₃} a₂(x₁,c₂,t) dt,
    G¹ = ∫_{c₃}^{x₃} a₂(x₁,x₂,t) dt,
    G² = −∫_{c₃}^{x₃} a₁(x₁,x₂,t) dt + ∫_{c₁}^{x₁} a₃(s,x₂,c₃) ds.

(The middle/last components come out right only because div a = 0.)  A :class:`Field` built
from SymPy expressions gets closed forms from ``sympy.integrate`` when that succeeds and the result
verifies symbolically; otherwise — and always for fields given as JAX callables — the potentials are
differentiable Gauss–Legendre quadratures (:mod:`vpforms._quadrature`), so methods that
differentiate them stay exactly volume preserving.

Potentials are computed on first access of :attr:`Field.se_potentials` /
:attr:`Field.dl_potentials` and cached; the divergence check happens at construction.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef

from . import _config  # noqa: F401  (float64)
from ._budget import check_size
from ._errors import NotRealFieldError, SpecError
from ._hoist import jit_hoisted
from ._field_input import (
    DIV_POINTS,
    _detect_linear,
    _param_subs,
    _shown,
    alias_coordinates,
    check_divergence,
    check_real,
    numeric_jacobian,
)
from ._quadrature import DEFAULT_N
from .domains import ToroidalDomain
from ._vecpot import CallablePotential, VectorPotential, curl_of

__all__ = [
    "Field",
    "PotentialError",
    "SYMBOLS",
    "vf1",
    "vf2",
    "vf3",
    "vf1_expr",
    "vf2_expr",
    "vf3_expr",
    "lie_derivative_expr",
    "potential_exprs",
]

from ._fieldops import (  # noqa: F401  (re-exported: the public names and the helpers tests use)
    _DEFAULT_BOX,
    _SPLITTINGS,
    SYMBOLS,
    PotentialError,
    Scalar,
    _as_points,
    _batched,
    _check_box,
    _check_finite_real,
    _decide_zero,
    _div_error,
    _float_scale,
    _fmt_pt,
    _lambdify_numpy,
    _lambdify_scalar,
    _numeric_max,
    _symbolic_zero,
    lie_derivative_expr,
    sample_box,
    uniform_in_box,
    vf1,
    vf1_expr,
    vf2,
    vf2_expr,
    vf3,
    vf3_expr,
)
from ._potentials import (  # noqa: F401
    GAUGE_ZERO,
    check_pair,
    gauge_callables,
    gauge_exprs,
    vector_potential,
    _check_potentials_arg,
    _check_splitting,
    _closed_form_potentials,
    _quadrature_potentials,
    _residual_exprs,
    _split_formula,
    potential_exprs,
)


# ---------------------------------------------------------------------------------------------
# Field
# ---------------------------------------------------------------------------------------------
class Field:
    """A divergence-free vector field a : R³ → R³ with its SE and DL potentials.

    Build it with :meth:`from_sympy` (preferred: exact divergence check, closed-form potentials),
    :meth:`from_callable` (a JAX-traceable function; divergence checked by autodiff at sample points)
    or :meth:`linear`.  See ``docs/ARCHITECTURE.md`` (contract ``Field``).

    Attributes
    ----------
    components:
        ``(a1, a2, a3)``, JAX scalar callables ``(x1, x2, x3) -> scalar``.
    se_potentials:
        ``(F1, F3)`` with a = vf1(F1) + vf3(F3)  (computed on first access).
    dl_potentials:
        ``(G1, G2)`` with a = vf1(G1) + vf2(G2).
    potential_method, potential_methods:
        how the potentials were obtained: ``"closed form"``, ``"quadrature(n=32)"`` or
        ``"user-supplied"``; ``potential_methods`` is the dict per splitting.
    potential_reasons:
        per splitting, why its potentials are (partly) a quadrature — the budget of
        :mod:`vpforms._budget` an integrand is over, or how ``sympy.integrate`` failed — or None
        where no quadrature is involved.  Decided by deterministic budgets, never by the clock.
    linear_matrix:
        numpy (3, 3) A if a(x) = A x, else None.
    exprs, symbols:
        SymPy expressions and symbols (None for callables).
    se_potential_exprs, dl_potential_exprs:
        SymPy expressions of closed-form / user-supplied symbolic potentials, else None.
    box:
        the box used for sample-point checks and error reports.
    """

    def __init__(
        self,
        components: Sequence[Scalar],
        *,
        name: str = "field",
        box: Any = _DEFAULT_BOX,
        exprs: Sequence[Any] | None = None,
        symbols: Sequence[sp.Symbol] | None = None,
        params: Mapping[str, float] | None = None,
        linear_matrix: np.ndarray | None = None,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        quadrature_n: int = DEFAULT_N,
        closed_form: bool = True,
        divergence_check: str = "",
        tol: float = 1e-10,
        seed: int = 0,
        n_samples: int = 256,
    ):
        if len(components) != 3 or not all(callable(c) for c in components):
            raise ValueError("a Field needs exactly three callable components")
        self.components: tuple[Scalar, Scalar, Scalar] = tuple(components)  # type: ignore[assignment]
        self.name = name
        self.box = _check_box(box)
        self.exprs = tuple(exprs) if exprs is not None else None
        self.symbols = tuple(symbols) if symbols is not None else None
        self.params = dict(params or {})
        self.linear_matrix = linear_matrix
        self.origin = tuple(float(c) for c in origin)
        if len(self.origin) != 3:
            raise ValueError(f"origin must have 3 coordinates; got {origin!r}")
        self.quadrature_n = int(quadrature_n)
        self.closed_form = bool(closed_form)
        self.divergence_check = divergence_check
        self.tol = float(tol)
        self.seed = int(seed)
        self.n_samples = int(n_samples)
        # potentials: splitting -> (callables, exprs or None, method)
        self._potentials: dict[str, tuple[tuple[Scalar, Scalar], tuple | None, str]] = {}
        # splitting -> why its potentials are a quadrature (None: no quadrature), set with them
        self._potential_reasons: dict[str, str | None] = {}
        # vector potentials A (∇×A = a) of what the user supplied (issue #23): when present, every
        # missing pair — and every pair of a relabelled field — is derived from them by the gauge
        # of _potentials.gauge_exprs, never from the field itself
        self._vector_potentials: list[tuple] = []
        # per axis the period of the field (φ of a toroidal field), or None
        self.periods: tuple = (None, None, None)
        self.coordinates = "cartesian (x1, x2, x3)"
        # points → None or ValueError for points off the field's domain (a gridded field's grid)
        self.domain_check: Callable[[Any], None] | None = None
        # (n, seed) → n points (its coordinates) where the checks sample, or None (Field.sample_points)
        self.sampler: Callable[[int, int], Any] | None = None
        # x (3,) → bool (JAX): is x in the domain? A failed step whose Euler point is not has
        # RESULTS.left_domain (a stop, not a failure of the method)
        self.inside: Callable[[Any], Any] | None = None

        comps = self.components

        def vec(x):
            return jnp.stack([jnp.asarray(c(x[0], x[1], x[2]), dtype=float) for c in comps])

        self._vec = vec
        self._eval = jit_hoisted(lambda x: _batched(vec, x))
        self._jac = jit_hoisted(lambda x: _batched(jax.jacfwd(vec), x))
        self._div = jit_hoisted(lambda x: _batched(lambda p: jnp.trace(jax.jacfwd(vec)(p)), x))
        self._recon_fns: dict[str, Callable] = {}

    # -- evaluation ----------------------------------------------------------------------------
    def __call__(self, x: Any) -> jax.Array:
        """a(x) for x of shape (3,) or (N, 3); same shape out."""
        return self._eval(_as_points(x))

    def jacobian(self, x: Any) -> jax.Array:
        """Da(x), shape (3, 3) or (N, 3, 3); J[i, j] = ∂a_i/∂x_j (forward-mode autodiff)."""
        return self._jac(_as_points(x))

    def divergence(self, x: Any) -> jax.Array:
        """div a(x) by autodiff, shape () or (N,)."""
        return self._div(_as_points(x))

    @property
    def divergence_expr(self):
        """The SymPy divergence (unsimplified), or None for callable fields."""
        if self.exprs is None:
            return None
        return sum(sp.diff(e, s) for e, s in zip(self.exprs, self.symbols))

    @property
    def is_symbolic(self) -> bool:
        return self.exprs is not None

    @property
    def domain(self) -> ToroidalDomain | None:
        """The region where the field is used (a :class:`vpforms.domains.ToroidalDomain`: a closed
        (R, Z) boundary per φ that follows the plasma), or None: the box. Where it is set, the
        checks of the potentials sample the domain instead of the box (a rectangular box of a real
        stellarator holds coil filaments, where no line of the plasma goes). Setting it checks that
        it lies in the box and forgets the checks made on the box."""
        return self.__dict__.get("_domain")

    @domain.setter
    def domain(self, domain: ToroidalDomain | None) -> None:
        if domain is not None:
            if not isinstance(domain, ToroidalDomain):
                raise TypeError(f"a field's domain must be a vpforms.domains.ToroidalDomain or None; got "
                                f"{type(domain).__name__}")
            (lo1, hi1), _, (lo3, hi3) = self.box
            toroidal = str(self.coordinates).startswith("toroidal")
            if toroidal:  # the box is in (u = R²/2, φ, Z)
                domain.check_within((np.sqrt(2 * max(lo1, 0.0)), np.sqrt(2 * max(hi1, 0.0))), (lo3, hi3),
                                    f"the box of field {self.name!r}")
        self.__dict__["_domain"] = domain
        self.__dict__.pop("_checked_pairs", None)

    def sample_points(self, n: int | None = None, seed: int | None = None) -> np.ndarray:
        """Seeded sample points: the field's ``sampler(n, seed)`` where it has one (a region in its
        own coordinates that no box or (R, Z) domain describes: a φ-time field on a domain), else
        uniform in :attr:`domain` where it has one, else in :attr:`box`."""
        n = self.n_samples if n is None else n
        seed = self.seed if seed is None else seed
        if self.sampler is not None:
            return np.asarray(self.sampler(n, seed), float)
        if self.domain is not None:
            return self.domain.sample_points(n, seed, toroidal=str(self.coordinates).startswith("toroidal"))
        return sample_box(self.box, n, seed)

    def check_real(self, points: Any, what: str = "the given points") -> None:
        """NotRealFieldError (one line, naming the component and a point) unless the field is real
        and finite at every one of ``points`` (N, 3), e.g. the initial conditions of a run (the
        box is checked at construction by :meth:`from_sympy`)."""
        pts = np.asarray(points, float).reshape(-1, 3)
        if self.exprs is not None:
            check_real(self.exprs, self.symbols, pts, self.name, what)
            return
        v = np.asarray(self(jnp.asarray(pts))).reshape(-1, 3)
        bad = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
        if bad.size:
            i = int(bad[0])
            comp = int(np.flatnonzero(~np.isfinite(v[i]))[0]) + 1
            raise NotRealFieldError(f"field {self.name!r}: component a{comp} is not finite at "
                                    f"x = {_fmt_pt(pts[i])} ({what})")

    # -- potentials ----------------------------------------------------------------------------
    @property
    def se_potentials(self) -> tuple[Scalar, Scalar]:
        """(F1, F3) with a = vf1(F1) + vf3(F3)  (eq:vf1, eq:vf3)."""
        return self._get("se")[0]

    @property
    def dl_potentials(self) -> tuple[Scalar, Scalar]:
        """(G1, G2) with a = vf1(G1) + vf2(G2)  (eq:vf1, eq:vf2)."""
        return self._get("dl")[0]

    @property
    def se_potential_exprs(self) -> tuple | None:
        return self._get("se")[1]

    @property
    def dl_potential_exprs(self) -> tuple | None:
        return self._get("dl")[1]

    @property
    def potential_methods(self) -> dict[str, str]:
        return {k: self._get(k)[2] for k in _SPLITTINGS}

    @property
    def potential_reasons(self) -> dict[str, str | None]:
        """Per splitting, why its potentials are (partly) a quadrature, or None (closed form,
        user-supplied, exact gauge)."""
        self.potential_methods  # noqa: B018 - builds the potentials, which records the reasons
        return {k: self._potential_reasons.get(k) for k in _SPLITTINGS}

    @property
    def potential_method(self) -> str:
        m = self.potential_methods
        if m["se"] == m["dl"]:
            return m["se"]
        return "; ".join(f"{k}: {v}" for k, v in m.items())

    def potentials(self, splitting: str) -> tuple[Scalar, Scalar]:
        """``"se"`` → (F1, F3), ``"dl"`` → (G1, G2)."""
        return self._get(_check_splitting(splitting))[0]

    def _get(self, splitting: str):
        if splitting not in self._potentials:
            self._potentials[splitting] = self._build_potentials(splitting)
        return self._potentials[splitting]

    def _build_potentials(self, splitting: str):
        if self._vector_potentials:
            return self._gauge_potentials(splitting)
        if self.exprs is None:
            why = "the field is a callable: no expressions to integrate in closed form"
        elif not self.closed_form:
            why = "closed forms not asked for (closed_form=False)"
        else:
            exprs, why = _closed_form_potentials(self, splitting)
            if exprs is not None:
                fns = tuple(_lambdify_scalar(e, self.symbols) for e in exprs)
                return fns, exprs, "closed form"
        self._potential_reasons[splitting] = why
        fns = _quadrature_potentials(self.components, splitting, self.origin, self.quadrature_n)
        return fns, None, f"quadrature(n={self.quadrature_n})"

    def _gauge_potentials(self, splitting: str):
        """The pair from the supplied vector potentials: one already in the gauge of the splitting
        if there is one (read off), else the gauge integral of the first (closed form if SymPy
        finds one, else by quadrature)."""
        k = GAUGE_ZERO[splitting]
        As = self._vector_potentials
        objs = [A for A in As if isinstance(A, VectorPotential)]
        if objs:  # an object that integrates itself (exactly, for splines)
            A = next((A for A in objs if A.exact_gauge), objs[0])
            how = f"from the {A.description}"
            if not A.exact_gauge:
                how += f" (gauge by quadrature, n={self.quadrature_n})"
                self._potential_reasons[splitting] = f"the {A.description} has no exact gauge integral"
            return A.gauge(splitting, self.origin, self.quadrature_n), None, how
        A = next((A for A in As if _is_zero(A[k])), As[0])
        how = "from the supplied potentials"
        if self.exprs is not None and all(isinstance(c, (sp.Expr, int)) for c in A):
            pair = gauge_exprs(A, self.symbols, splitting, self.origin)
            if pair is not None:
                return tuple(_lambdify_scalar(e, self.symbols) for e in pair), pair, how
            A = tuple(_lambdify_scalar(sp.sympify(c), self.symbols) for c in A)
            self._potential_reasons[splitting] = "sympy.integrate finds no closed-form gauge integral χ"
        else:
            self._potential_reasons[splitting] = "the supplied potentials are callables: the gauge integral χ is a quadrature"
        A = tuple(0 if _is_zero(c) else c for c in A)
        fns = gauge_callables(A, splitting, self.origin, self.quadrature_n)
        return fns, None, f"{how} (gauge by quadrature, n={self.quadrature_n})"

    def check_potentials(self, splitting: str = "se", points: Any = None, what: str = "") -> None:
        """Raise :class:`PotentialError` unless the ``splitting`` pair may step on the domain: the
        box and ``points`` (see :func:`vpforms._potentials.check_pair`: no singular set of a
        symbolic potential inside it; a numerically built pair reproduces a to 1e-8 relative).
        Points off the field's domain (:attr:`domain_check`: a gridded field's grid) are a
        ValueError first."""
        if points is not None and self.domain_check is not None:
            self.domain_check(points)
        check_pair(self, splitting, points, what)

    def potential_vector_field(self, splitting: str = "se") -> Callable[[jax.Array], jax.Array]:
        """x ↦ vf1(F1)(x) + vf3(F3)(x) (``"se"``) or vf1(G1)(x) + vf2(G2)(x) (``"dl"``), x (3,)."""
        splitting = _check_splitting(splitting)
        P, Q = self.potentials(splitting)
        u, v = vf1(P), (vf3(Q) if splitting == "se" else vf2(Q))
        return lambda x: u(x) + v(x)

    def reconstruct(self, x: Any, splitting: str = "se") -> jax.Array:
        """The field rebuilt from its potentials by autodiff, at x of shape (3,) or (N, 3)."""
        splitting = _check_splitting(splitting)
        if splitting not in self._recon_fns:
            fn = self.potential_vector_field(splitting)
            self._recon_fns[splitting] = jit_hoisted(lambda x: _batched(fn, x))
        return self._recon_fns[splitting](_as_points(x))

    def reconstruction_error(
        self, splitting: str = "se", n_points: int = 4096, seed: int = 1, box: Any = None
    ) -> float:
        """max |rebuilt − a|_∞ / max |a|_∞ over n_points seeded uniform points of the box."""
        pts = jnp.asarray(sample_box(self.box if box is None else box, n_points, seed))
        a = np.asarray(self(pts))
        r = np.asarray(self.reconstruct(pts, splitting))
        scale = max(float(np.max(np.abs(a))), np.finfo(float).tiny)
        return float(np.max(np.abs(r - a)) / scale)

    # -- constructors --------------------------------------------------------------------------
    @classmethod
    def from_sympy(
        cls,
        exprs: Sequence[Any],
        symbols: Sequence[sp.Symbol] = SYMBOLS,
        name: str = "field",
        params: Mapping[Any, Any] | None = None,
        potentials: Mapping[str, Sequence[Any]] | None = None,
        *,
        box: Any = _DEFAULT_BOX,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        quadrature_n: int = DEFAULT_N,
        closed_form: bool = True,
        tol: float = 1e-12,
        _relabelled_from: Field | None = None,
    ) -> "Field":
        """A field from three SymPy expressions in ``symbols``.

        ``params`` maps parameter symbols (or their names) to values substituted at construction.
        The components must be real and finite at 512 seeded points of ``box``
        (:class:`~vpforms._errors.NotRealFieldError` otherwise, naming the component).  The
        divergence is checked symbolically within the budgets of :mod:`vpforms._budget` (expand,
        then trigsimp/simplify of small expressions only); what that does not decide is evaluated
        at sample points of ``box`` (float64, relative tolerance ``tol``; for an exact field also in
        60-digit arithmetic), and :attr:`divergence_check` says which: ``"symbolic"`` or
        ``"numerical (…)"`` with the tolerances and the number of points.  ``potentials`` may give ``{"se": (F1, F3)}``
        and/or ``{"dl": (G1, G2)}`` as SymPy expressions; they are verified symbolically.
        """
        if isinstance(exprs, (str, sp.Basic)) or len(exprs) != 3:
            raise ValueError(f"exprs must be three SymPy expressions; got {exprs!r}")
        try:
            exprs = tuple(sp.sympify(e) for e in exprs)
        except (sp.SympifyError, TypeError) as err:
            raise ValueError(f"exprs must be SymPy expressions: {err}") from None
        for i, e in enumerate(exprs, start=1):
            if not isinstance(e, sp.Expr):
                raise ValueError(
                    f"component a{i} must be a scalar SymPy expression, not {type(e).__name__} {e!r}"
                )
        if isinstance(symbols, (str, sp.Basic)) or len(symbols) != 3:
            raise ValueError(f"symbols must be three SymPy symbols; got {symbols!r}")
        symbols = tuple(symbols)
        if not all(isinstance(s, sp.Symbol) for s in symbols) or len(set(symbols)) != 3:
            raise ValueError(f"symbols must be three distinct SymPy symbols; got {symbols!r}")
        subs, pvals = _param_subs(params, exprs, potentials, symbols)
        exprs = alias_coordinates(tuple(e.xreplace(subs) if subs else e for e in exprs), symbols)
        extra = set().union(*(e.free_symbols for e in exprs)) - set(symbols)
        if extra:
            raise ValueError(
                f"field {name!r} has free symbols {sorted(map(str, extra))} besides the "
                f"coordinates {[str(s) for s in symbols]}; give their values in params"
            )
        _check_finite_real(exprs, f"field {name!r}: component a")
        for i, e in enumerate(exprs, start=1):
            check_size(e, f"component a{i} of field {name!r}")
        undefined = set().union(*(e.atoms(AppliedUndef) for e in exprs))
        if undefined:
            raise ValueError(
                f"field {name!r} contains undefined functions {sorted(map(str, undefined))}: "
                "give every component as an explicit expression"
            )
        box = _check_box(box)

        thr = 1e-13 * _float_scale(exprs)
        if _relabelled_from is not None:
            # a relabelling (π⁻¹, π⁻¹)·a of a checked field (vpforms._methods._relabel): real,
            # finite and divergence free as that one is; not linear (those go to Field.linear)
            how, linear = _relabelled_from.divergence_check, None
        else:
            # real and finite on the box (issue #22), before anything else is computed from it
            pts = sample_box(box, DIV_POINTS, 0)
            check_real(exprs, symbols, pts, name, f"a sampled point of the box {box}")
            # the divergence: exactly within budget, else numerically (and then said so); an
            # exactly nonzero one is never accepted
            J = numeric_jacobian(exprs, symbols, pts)
            how = check_divergence(exprs, symbols, box, pts, J, tol, thr, name)
            linear = _detect_linear(exprs, symbols, J)

        comps = tuple(_lambdify_scalar(e, symbols) for e in exprs)
        centre = [0.5 * (lo + hi) for lo, hi in box]
        for i, c in enumerate(comps):
            try:
                c(*(jnp.asarray(v) for v in centre))  # arrays: 1/0 is inf, not an exception
            except Exception as err:  # noqa: BLE001 - e.g. a SymPy function JAX does not know
                raise ValueError(
                    f"component a{i + 1} = {exprs[i]} of field {name!r} cannot be evaluated with "
                    f"JAX ({type(err).__name__}: {str(err).splitlines()[0]})"
                ) from err
        field = cls(
            comps,
            name=name,
            box=box,
            exprs=exprs,
            symbols=symbols,
            params=pvals,
            linear_matrix=linear,
            origin=origin,
            quadrature_n=quadrature_n,
            closed_form=closed_form,
            divergence_check=how,
            tol=tol,
        )
        if potentials is not None:
            for key, pair in _check_potentials_arg(potentials).items():
                try:
                    pair = tuple(sp.sympify(p) for p in pair)
                except (sp.SympifyError, TypeError) as err:
                    raise ValueError(f"{key} potentials must be SymPy expressions: {err}") from None
                if not all(isinstance(p, sp.Expr) for p in pair):
                    raise ValueError(f"{key} potentials must be scalar SymPy expressions; got {pair!r}")
                pair = tuple(p.xreplace(subs) if subs else p for p in pair)
                _check_finite_real(pair, f"{key.upper()} potential ")
                extra = set().union(*(p.free_symbols for p in pair)) - set(symbols)
                if extra:
                    raise ValueError(
                        f"{key} potentials of {name!r} have free symbols {sorted(map(str, extra))}"
                    )
                res = _residual_exprs(exprs, symbols, key, pair)
                if not all(_symbolic_zero(r, symbols, thr) for r in res):
                    raise PotentialError(
                        f"the given {key.upper()} potentials do not reproduce field {name!r}: "
                        f"{_split_formula(key)} − a = {tuple(_shown(r) for r in res)} (not proven "
                        "0 within the budget of vpforms._budget)"
                    )
                if key == "A":
                    field._vector_potentials.append(pair)
                    continue
                fns = tuple(_lambdify_scalar(p, symbols) for p in pair)
                field._potentials[key] = (fns, pair, "user-supplied")
                field._vector_potentials.append(vector_potential(pair, key))
        return field

    @classmethod
    def from_callable(
        cls,
        a: Callable[[jax.Array], jax.Array] | Sequence[Scalar],
        box: Any = _DEFAULT_BOX,
        name: str = "field",
        tol: float = 1e-10,
        potentials: Mapping[str, Sequence[Scalar]] | None = None,
        *,
        n_samples: int = 256,
        seed: int = 0,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        quadrature_n: int = DEFAULT_N,
        domain: ToroidalDomain | None = None,
        coordinates: str | None = None,
        sampler: Callable[[int, int], Any] | None = None,
    ) -> "Field":
        """A field from a JAX-traceable callable ``a(x)`` (x of shape (3,) → shape (3,)), or from
        three scalar callables ``(a1, a2, a3)`` of (x1, x2, x3).

        The divergence is checked by forward-mode autodiff at ``n_samples`` seeded uniform points of
        ``box``: max |div a| ≤ tol · max |∂a_i/∂x_j| (the natural scale of a derivative), else
        :class:`NotDivergenceFreeError` with the largest divergence and where.  Potentials are
        differentiable Gauss–Legendre quadratures unless given as ``{"se": (F1, F3), "dl": (G1, G2)}``
        (scalar callables), which are then checked at the sample points to the same tolerance.
        ``domain`` (toroidal coordinates) or ``sampler`` ((n, seed) → n points in the field's own
        coordinates) replace the box as where these and later checks sample (:meth:`sample_points`).
        """
        box = _check_box(box)
        if callable(a):
            try:
                probe = jax.eval_shape(a, jax.ShapeDtypeStruct((3,), jnp.float64))
            except Exception as err:  # noqa: BLE001 - not traceable: numpy code, wrong arity, …
                raise ValueError(
                    "the callable a must be JAX-traceable, mapping a point of shape (3,) to shape "
                    f"(3,); tracing it failed with {type(err).__name__}: {str(err).splitlines()[0]}"
                ) from err
            shape = getattr(probe, "shape", None)
            if shape != (3,):
                raise ValueError(
                    f"the callable a must map a point of shape (3,) to shape (3,); got {shape!r}"
                )

            def _comp(i):
                def ai(x1, x2, x3):
                    X = jnp.stack(jnp.broadcast_arrays(x1, x2, x3)).astype(float)
                    if X.ndim == 1:
                        return a(X)[i]
                    # batched coordinates: a maps one point (3,) → (3,), so map it over the points
                    return jax.vmap(a)(X.reshape(3, -1).T)[:, i].reshape(X.shape[1:])

                ai.__name__ = f"a{i + 1}"
                return ai

            comps = tuple(_comp(i) for i in range(3))
        else:
            try:
                comps = tuple(a)
            except TypeError:
                raise ValueError("a must be a callable a(x) or three scalar callables") from None
            if len(comps) != 3 or not all(callable(c) for c in comps):
                raise ValueError("a must be a callable a(x) or three scalar callables")
            for i, c in enumerate(comps):
                s = jax.ShapeDtypeStruct((), jnp.float64)
                try:
                    shape = getattr(jax.eval_shape(c, s, s, s), "shape", None)
                except Exception as err:  # noqa: BLE001
                    raise ValueError(
                        f"component a{i + 1} must be a JAX-traceable scalar function of "
                        f"(x1, x2, x3); tracing it failed with {type(err).__name__}: "
                        f"{str(err).splitlines()[0]}"
                    ) from err
                if shape != ():
                    raise ValueError(f"component a{i + 1} must return a scalar; got shape {shape!r}")
        field = cls(
            comps,
            name=name,
            box=box,
            origin=origin,
            quadrature_n=quadrature_n,
            closed_form=False,
            divergence_check="autodiff at sample points",
            tol=tol,
            seed=seed,
            n_samples=n_samples,
        )
        if coordinates is not None:
            field.coordinates = coordinates
        field.domain = domain  # where it is given, the checks below sample it, not the box
        field.sampler = sampler
        pts = jnp.asarray(field.sample_points())
        J = np.asarray(field.jacobian(pts))
        if not np.all(np.isfinite(J)):
            i = int(np.flatnonzero(~np.all(np.isfinite(J.reshape(len(J), -1)), axis=1))[0])
            raise ValueError(f"field {name!r} has a non-finite Jacobian at x = {_fmt_pt(pts[i])}")
        div = np.trace(J, axis1=1, axis2=2)
        scale = max(float(np.max(np.abs(J))), np.finfo(float).tiny)
        i = int(np.argmax(np.abs(div)))
        if abs(div[i]) > tol * scale:
            raise _div_error(
                f"field {name!r} is not divergence free: the largest |div a| at {len(pts)} sample "
                f"points of the box {box} is {abs(div[i]):.6g} at x = {_fmt_pt(pts[i])} "
                f"(tolerance {tol:g} × max|∂a_i/∂x_j| = {tol * scale:.3g})",
                abs(div[i]),
                pts[i],
            )
        if potentials is not None:
            a_vals = np.asarray(field(pts))
            a_scale = max(float(np.max(np.abs(a_vals))), np.finfo(float).tiny)
            for key, pair in _check_potentials_arg(potentials).items():
                if not all(callable(p) for p in pair):
                    raise ValueError(f"{key} potentials must be {len(pair)} scalar callables")
                if key == "A":
                    curl = jit_hoisted(lambda x: _batched(curl_of(pair), x))
                    err, where = _numeric_max(lambda x: curl(x) - field(x), np.asarray(pts))
                else:
                    field._potentials[key] = (tuple(pair), None, "user-supplied")
                    err, where = _numeric_max(
                        lambda x: field.reconstruct(x, key) - field(x), np.asarray(pts)
                    )
                if err <= tol * a_scale:
                    field._vector_potentials.append(
                        tuple(pair) if key == "A" else vector_potential(pair, key))
                else:
                    field._potentials.pop(key, None)
                    field._recon_fns.pop(key, None)
                    raise PotentialError(
                        f"the given {key.upper()} potentials do not reproduce field {name!r}: "
                        f"max |{_split_formula(key)} − a| = {err:.6g} at x = {_fmt_pt(where)} "
                        f"(max |a| = {a_scale:.3g})"
                    )
        return field

    @classmethod
    def from_vector_potential(
        cls,
        A: Any,
        box: Any = _DEFAULT_BOX,
        name: str = "field",
        *,
        periods: Sequence[float | None] | None = None,
        tol: float = 1e-10,
        n_samples: int = 256,
        seed: int = 0,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        quadrature_n: int = DEFAULT_N,
        domain: ToroidalDomain | None = None,
        coordinates: str | None = None,
        sampler: Callable[[int, int], Any] | None = None,
    ) -> "Field":
        """The field a = ∇×A of a vector potential: a :class:`~vpforms._vecpot.VectorPotential`
        (coils, a spline of A on a grid, a toroidal-coordinate potential), three JAX scalar callables
        or a callable A(x).

        a is divergence free as a function (the divergence of a curl; checked by autodiff at sample
        points all the same). Every pair of every case — including the relabelled ones — is built
        from A by its own antiderivative (exact for splines, periodic-aware Gauss–Legendre
        otherwise), never from a: see :mod:`vpforms._vecpot`. ``periods`` (per axis, e.g.
        ``(None, 2π/nfp, None)`` for (u, φ, Z)) defaults to those of ``A``.
        """
        if not isinstance(A, VectorPotential):
            comps = _check_potentials_arg({"A": A})["A"]
            A = CallablePotential(comps, periods if periods is not None else (None,) * 3)
        field = cls.from_callable(
            curl_of(A.components()), box=box, name=name, tol=tol, n_samples=n_samples, seed=seed,
            origin=origin, quadrature_n=quadrature_n, domain=domain, coordinates=coordinates, sampler=sampler,
        )
        field._vector_potentials.append(A)
        field.periods = tuple(A.periods) if periods is None else tuple(periods)
        field.divergence_check = "∇·(∇×A) (curl of a vector potential)"
        return field

    @classmethod
    def linear(cls, A: Any, name: str = "linear", box: Any = _DEFAULT_BOX, tol: float = 1e-12) -> "Field":
        """The linear field a(x) = A x for a traceless 3×3 matrix A (closed-form quadratic potentials).

        |tr A| ≤ tol · max|A_ij| is accepted as traceless (rounding); otherwise ValueError.
        """
        try:
            M = np.asarray(A, dtype=float)
        except (TypeError, ValueError) as err:
            raise ValueError(f"A must be a 3×3 matrix of numbers: {err}") from None
        if M.shape != (3, 3):
            raise ValueError(f"A must be a 3×3 matrix; got shape {M.shape}")
        if not np.all(np.isfinite(M)):
            raise ValueError("A must be finite")
        tr = float(np.trace(M))
        if abs(tr) > tol * float(np.max(np.abs(M))):
            raise ValueError(
                f"a linear field x ↦ A x is divergence free only if tr A = 0; got tr A = {tr!r}"
            )
        Ms = sp.Matrix(3, 3, [sp.Float(float(v), 17) if v != 0 else sp.Integer(0) for v in M.ravel()])
        X = sp.Matrix(SYMBOLS)
        exprs = tuple(Ms * X)
        f = cls.from_sympy(exprs, SYMBOLS, name=name, box=box)
        f.linear_matrix = M.copy()
        return f

    def spec(self) -> dict:
        """The JSON-able spec that rebuilds this field (:func:`vpforms.field_from_spec`)."""
        return field_spec(self)

    def __repr__(self) -> str:
        kind = "sympy" if self.exprs is not None else "callable"
        return f"Field(name={self.name!r}, {kind}, box={self.box})"


def _is_zero(c: Any) -> bool:
    return not callable(c) and sp.sympify(c) == 0


# ---------------------------------------------------------------------------------------------
# specs (issue #10): a field as JSON and back; moved here from _spec.py (issue #19)
# ---------------------------------------------------------------------------------------------
def field_spec(field: Any) -> dict:
    """The JSON-able spec of a :class:`vpforms.Field` (symbolic or linear)."""
    if not isinstance(field, Field):
        raise SpecError(f"cannot ship {type(field).__name__} {field!r}: only a vpforms.Field has a spec")
    if field.linear_matrix is not None:
        return {"kind": "linear", "A": np.asarray(field.linear_matrix, float).tolist(),
                "name": field.name, "box": [list(b) for b in field.box]}
    if field.exprs is None:
        raise SpecError(
            f"field {field.name!r} was given only as a JAX callable: it cannot be shipped to another "
            "process or written to a file; build it with Field.from_sympy (or a vpforms.problems problem)"
        )
    pots = {k: [sp.srepr(p) for p in v[1]] for k, v in field._potentials.items()
            if v[2] == "user-supplied" and v[1] is not None}
    return {
        "kind": "sympy",
        "exprs": [sp.srepr(e) for e in field.exprs],
        "symbols": [sp.srepr(s) for s in field.symbols],
        "params": {str(k): float(v) for k, v in field.params.items()},
        "name": field.name,
        "box": [list(b) for b in field.box],
        "origin": list(field.origin),
        "quadrature_n": field.quadrature_n,
        "closed_form": field.closed_form,
        "tol": field.tol,
        **({"potentials": pots} if pots else {}),
        **_frame_spec(field),
    }


def _frame_spec(field: Any) -> dict:
    """The field's coordinates and periods where they are not the defaults (Cartesian, none): a
    field in (u = R²/2, φ, Z) rebuilt without them would be traced as Cartesian (a Dask worker's
    wall test, sections, |B|)."""
    out = {}
    if field.coordinates != "cartesian (x1, x2, x3)":
        out["coordinates"] = field.coordinates
    if any(p is not None for p in field.periods):
        out["periods"] = [None if p is None else float(p) for p in field.periods]
    return out


@functools.lru_cache(maxsize=64)
def _field_from_json(text: str):
    spec = json.loads(text)
    kind = spec.get("kind")
    box = tuple(tuple(b) for b in spec["box"])
    if kind == "linear":
        return Field.linear(np.asarray(spec["A"], float), name=spec["name"], box=box)
    if kind != "sympy":
        raise SpecError(f"unknown field spec kind {kind!r}")
    exprs = [sp.sympify(e) for e in spec["exprs"]]
    symbols = [sp.sympify(s) for s in spec["symbols"]]
    pots = {k: tuple(sp.sympify(p) for p in v) for k, v in spec.get("potentials", {}).items()} or None
    f = Field.from_sympy(exprs, symbols, name=spec["name"], potentials=pots, box=box,
                         origin=tuple(spec["origin"]), quadrature_n=spec["quadrature_n"],
                         closed_form=spec["closed_form"], tol=spec["tol"])
    f.params = dict(spec.get("params", {}))
    if "coordinates" in spec:
        f.coordinates = spec["coordinates"]
    if "periods" in spec:
        f.periods = tuple(spec["periods"])
    return f


def field_from_spec(spec: dict) -> Any:
    """Rebuild a :class:`vpforms.Field` from :func:`field_spec` (cached per process)."""
    if not isinstance(spec, dict):
        raise SpecError(f"a field spec is a dict, got {type(spec).__name__}")
    try:
        return _field_from_json(json.dumps(spec, sort_keys=True))
    except (KeyError, TypeError) as err:
        raise SpecError(f"malformed field spec: {err!r}") from None

"""A small exterior algebra on R⁶ = {(x1, x2, x3, X1, X2, X3)} (enough for f*ν̃ − ν = dλ).

A k-form is a :class:`Form`: a dict ``{(i1 < … < ik): coefficient}`` of SymPy expressions over the
coordinates :data:`vpforms.symbolic._symbols.COORDS` (0-based indices).  Only what the proofs need
is implemented — wedge, exterior derivative, sums, scalar multiples — and everything is kept as
plain ``expand``-able polynomials in the jet variables (derivatives of undefined functions), so
identities are decided by ``sympy.expand(...) == 0``, never numerically.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import sympy as sp

from ._symbols import COORDS

__all__ = ["Form", "dvar", "d", "wedge"]


def _sort_sign(idx: tuple[int, ...]) -> tuple[int, tuple[int, ...]]:
    """(sign, sorted) for a tuple of distinct indices; sign 0 if an index repeats."""
    if len(set(idx)) < len(idx):
        return 0, idx
    sign, lst = 1, list(idx)
    for i in range(len(lst)):  # bubble sort, counting transpositions
        for j in range(len(lst) - 1 - i):
            if lst[j] > lst[j + 1]:
                lst[j], lst[j + 1] = lst[j + 1], lst[j]
                sign = -sign
    return sign, tuple(lst)


class Form:
    """A differential form Σ c_I dz_I on R⁶ with SymPy coefficients."""

    __slots__ = ("degree", "terms")

    def __init__(self, degree: int, terms: Mapping[tuple[int, ...], sp.Expr] | None = None):
        self.degree = int(degree)
        self.terms: dict[tuple[int, ...], sp.Expr] = {}
        for idx, c in (terms or {}).items():
            if len(idx) != self.degree:
                raise ValueError(f"a {degree}-form cannot have the component {idx}")
            s, key = _sort_sign(tuple(idx))
            if s:
                self.terms[key] = self.terms.get(key, sp.S.Zero) + s * sp.sympify(c)

    @staticmethod
    def scalar(f: sp.Expr) -> "Form":
        return Form(0, {(): f})

    def __add__(self, other: "Form") -> "Form":
        if self.degree != other.degree:
            raise ValueError("cannot add forms of different degrees")
        out = dict(self.terms)
        for k, v in other.terms.items():
            out[k] = out.get(k, sp.S.Zero) + v
        return Form(self.degree, out)

    def __neg__(self) -> "Form":
        return Form(self.degree, {k: -v for k, v in self.terms.items()})

    def __sub__(self, other: "Form") -> "Form":
        return self + (-other)

    def __rmul__(self, c: sp.Expr) -> "Form":
        return Form(self.degree, {k: c * v for k, v in self.terms.items()})

    def __xor__(self, other: "Form") -> "Form":  # α ^ β = α ∧ β
        return wedge(self, other)

    def map_coefficients(self, fn) -> "Form":
        return Form(self.degree, {k: fn(v) for k, v in self.terms.items()})

    def is_zero(self) -> bool:
        """True iff every coefficient expands to exactly 0."""
        return all(sp.expand(v) == 0 for v in self.terms.values())

    def nonzero_components(self) -> dict[tuple[int, ...], sp.Expr]:
        out = {}
        for k, v in self.terms.items():
            e = sp.expand(v)
            if e != 0:
                out[k] = e
        return out

    def __repr__(self) -> str:
        parts = [
            f"({v})*" + "^".join(f"d{COORDS[i]}" for i in k) if k else str(v)
            for k, v in sorted(self.terms.items())
        ]
        return " + ".join(parts) if parts else "0"


def dvar(z: sp.Symbol) -> Form:
    """The coordinate one-form dz for a coordinate symbol z ∈ COORDS."""
    return Form(1, {(COORDS.index(z),): sp.S.One})


def wedge(alpha: Form, beta: Form) -> Form:
    """α ∧ β."""
    out: dict[tuple[int, ...], sp.Expr] = {}
    for I, a in alpha.terms.items():
        for J, b in beta.terms.items():
            s, key = _sort_sign(I + J)
            if s:
                out[key] = out.get(key, sp.S.Zero) + s * a * b
    return Form(alpha.degree + beta.degree, out)


def d(alpha: Form | sp.Expr) -> Form:
    """The exterior derivative dα = Σ_I Σ_j ∂_j c_I dz_j ∧ dz_I (a 0-form may be an expression)."""
    if not isinstance(alpha, Form):
        alpha = Form.scalar(sp.sympify(alpha))
    out: dict[tuple[int, ...], sp.Expr] = {}
    for I, c in alpha.terms.items():
        for j, z in enumerate(COORDS):
            dc = sp.diff(c, z)
            if dc != 0:
                s, key = _sort_sign((j,) + I)
                if s:
                    out[key] = out.get(key, sp.S.Zero) + s * dc
    return Form(alpha.degree + 1, out)


def wedge_all(forms: Iterable[Form]) -> Form:
    forms = list(forms)
    out = forms[0]
    for f in forms[1:]:
        out = wedge(out, f)
    return out

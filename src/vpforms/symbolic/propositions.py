"""Symbolic checks of the reduction propositions on generic (undefined-function) potentials.

* prop:volpotinv — f_{Φ·p, φ·p} is the inverse of f_{φ,Φ}, with the **same** sign;
* prop:permactalg — (π,π)·((σ,Σ)·f) = (π∘σ, π∘Σ)·f, for a generic map f;
* prop:trivperm — the equations of (π∘σ, π∘Σ) are those of (σ,Σ) with every variable relabelled;
* prop:switchperm — with φ̃(h) = Φ(−h)·p, Φ̃(h) = φ(−h)·p, the map of (Σ,σ) is (Ψ_{−h})⁻¹ (the adjoint).

Each check compares systems of defining equations: two maps are equal when their defining
equations are the same up to a non-zero constant factor each (and an ordering), decided by exact
expansion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._case import Case, cases
from .._perm import Perm
from ._symbols import X, Y, h, x, y
from .forms import generic_equations

__all__ = [
    "PropositionCheck",
    "check_volpotinv",
    "check_permactalg",
    "check_trivperm",
    "check_switchperm",
    "same_equations",
]


@dataclass(frozen=True)
class PropositionCheck:
    name: str
    holds: bool
    detail: str = ""


def same_equations(E, F, factors=(1, -1)) -> bool:
    """True if every F_j is c·E_i for a distinct i and a constant c ∈ factors (exact expansion)."""
    E = [sp.expand(e) for e in E]
    used: set[int] = set()
    for f in F:
        f = sp.expand(f)
        hit = next(
            (i for i, e in enumerate(E) if i not in used and any(sp.expand(f - c * e) == 0 for c in factors)),
            None,
        )
        if hit is None:
            return False
        used.add(hit)
    return True


def _flip(P):
    """(P·p)(u1, u2, u3) = P(u3, u2, u1) (eq:defpfl)."""
    return lambda u1, u2, u3: P(u3, u2, u1)


def _volpot(phi, Phi, s, yv, Yv):
    """The three residuals of eq:volpot at (y, Y) for callables φ, Φ (slot derivatives)."""
    a3 = (Yv[2], yv[1], yv[2])
    b3 = (Yv[2], Yv[1], yv[2])
    return (
        sp.diff(phi(*a3), a3[1]) - yv[0],
        sp.diff(Phi(*b3), b3[2]) + s * sp.diff(phi(*a3), a3[0]),
        sp.diff(Phi(*b3), b3[1]) - Yv[0],
    )


def check_volpotinv(sign: int = 1, same_sign: bool = True) -> PropositionCheck:
    """prop:volpotinv on undefined φ, Φ: the equations of f^{s'}_{Φ·p,φ·p} at (z = Y, Z = y) are those
    of f^s_{φ,Φ} at (y, Y) — iff s' = s (with s' = −s the middle equation differs)."""
    f, F = sp.Function("phi", real=True), sp.Function("Phi", real=True)
    phi = lambda *u: f(*u)  # noqa: E731
    Phi = lambda *u: F(*u)  # noqa: E731
    s2 = sign if same_sign else -sign
    E = _volpot(phi, Phi, sign, y, Y)
    E_inv = _volpot(_flip(Phi), _flip(phi), s2, Y, y)  # z := Y, Z := y
    ok = same_equations(E, E_inv)
    return PropositionCheck(
        "prop:volpotinv" + ("" if same_sign else " (opposite sign)"),
        ok,
        f"sign {sign:+d}, inverse sign {s2:+d}",
    )


def _act(sigma: Perm, Sigma: Perm, fmap):
    """((σ,Σ)·f)(x) = f(x·σ)·Σ⁻¹ for a map given as a callable on 3-tuples (the right action
    is :meth:`vpforms.Perm.act`, on object arrays of SymPy expressions)."""
    Sinv = Sigma.inverse()

    def g(v):
        w = fmap(tuple(sigma.act(np.array(v, dtype=object))))
        return tuple(Sinv.act(np.array(w, dtype=object)))

    return g


def check_permactalg() -> PropositionCheck:
    """prop:permactalg for a generic map f = (f1, f2, f3) of undefined functions, all π, σ, Σ."""
    fs = [sp.Function(f"f{i}", real=True) for i in (1, 2, 3)]
    fmap = lambda v: tuple(fi(*v) for fi in fs)  # noqa: E731
    bad = []
    for pi in Perm.all():
        for c in cases():
            lhs = _act(pi, pi, _act(c.sigma, c.Sigma, fmap))(x)
            rhs = _act(pi * c.sigma, pi * c.Sigma, fmap)(x)
            if any(sp.expand(a - b) != 0 for a, b in zip(lhs, rhs)):
                bad.append((pi, c))
    return PropositionCheck("prop:permactalg", not bad, f"{216 - len(bad)}/216 triples (π, σ, Σ)")


def check_trivperm(case: Case, pi: Perm) -> PropositionCheck:
    """prop:trivperm at the level of equations: the equations of (π∘σ, π∘Σ) with the same generic
    potentials are those of (σ, Σ) with x ↦ x·π, X ↦ X·π (so (π,π)·Ψ is the relabelled map)."""
    new = case.relabel(pi)
    E_new = generic_equations(new)
    # (σ,Σ)·f evaluated at x·π: its roles x_{σ(i)} become x_{π(σ(i))}.
    relabel = {x[i - 1]: x[pi(i) - 1] for i in (1, 2, 3)}
    relabel.update({X[i - 1]: X[pi(i) - 1] for i in (1, 2, 3)})
    E_old = [e.xreplace(relabel) for e in generic_equations(case)]
    ok = same_equations(E_old, E_new, factors=(1,))
    return PropositionCheck("prop:trivperm", ok and new.tau == case.tau, f"{case} → {new}")


def check_switchperm(case: Case, *, reverse_time: bool = True, sign: int | None = None
                     ) -> PropositionCheck:
    """prop:switchperm on h-dependent undefined potentials φ(u; h), Φ(u; h).

    The equations of (Σ, σ) with φ̃(h) = Φ(−h)·p, Φ̃(h) = φ(−h)·p at (x → X) are those of (σ, Σ)
    with φ(−h), Φ(−h) at (X → x): the new map is (Ψ_{−h})⁻¹, the adjoint.  Same sign (τ ↦ τ⁻¹).
    """
    f, F = sp.Function("phi", real=True), sp.Function("Phi", real=True)
    phi_mh = lambda u1, u2, u3: f(u1, u2, u3, -h)  # noqa: E731 - φ(−h)
    Phi_mh = lambda u1, u2, u3: F(u1, u2, u3, -h)  # noqa: E731
    sw = case.switched()
    if reverse_time:
        E_new = generic_equations(sw, _flip(Phi_mh), _flip(phi_mh), sign or sw.sign)
    else:
        phi_h = lambda u1, u2, u3: f(u1, u2, u3, h)  # noqa: E731
        Phi_h = lambda u1, u2, u3: F(u1, u2, u3, h)  # noqa: E731
        E_new = generic_equations(sw, _flip(Phi_h), _flip(phi_h), sign or sw.sign)
    swap = {**{a: b for a, b in zip(x, X)}, **{b: a for a, b in zip(x, X)}}
    E_old = [e.xreplace(swap) for e in generic_equations(case, phi_mh, Phi_mh, case.sign)]
    ok = same_equations(E_old, E_new) and sw.sign == case.sign and sw.tau == case.tau.inverse()
    return PropositionCheck("prop:switchperm", ok, f"{case} → {sw}")

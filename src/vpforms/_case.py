"""The 36 permutation cases (sigma, Sigma) of the paper and their five classes.

A case is a pair of permutations acting on the generic map f^±_{φ,Φ} (eq:volpot) by

    ((sigma, Sigma) · f)(x) = f(x · sigma) · Sigma^{-1}            (MATH.md §2)

so that the generic arguments y = x · sigma and Y = X · Sigma carry the *roles*

    x₊ = x_{sigma(1)}, x∘ = x_{sigma(2)}, x₋ = x_{sigma(3)},
    X₊ = X_{Sigma(1)}, X∘ = X_{Sigma(2)}, X₋ = X_{Sigma(3)}.

(eq:notpzm prints sigma^{-1} here, which is wrong unless sigma and Sigma are involutions.)

The class of a case is the class of tau = sigma^{-1} ∘ Sigma (prop:trivperm: relabelling leaves tau
unchanged), read off the triangle of fig:triangle, whose vertices are the roles +, ∘, −:
the identity is S1, the mirror through a vertex is named after that vertex's axis
(through − : S2, through ∘ : SE(+SE), through + : DL(+DL)), and the two rotations are SE+DL.
The sign in (volpot2) must be sgn tau (the sign rule, MATH.md §2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ._perm import Perm, as_perm

__all__ = ["Case", "cases", "CLASSES", "ROLES"]

#: The five classes, in the order used throughout the library.
CLASSES: tuple[str, ...] = ("S1", "S2", "SE+SE", "DL+DL", "SE+DL")

#: Role names, in the order of the generic arguments (y1, y2, y3) = (x₊, x∘, x₋).
ROLES: tuple[str, str, str] = ("+", "∘", "-")

# fig:triangle: a mirror symmetry (a transposition) is named by the role-vertex it fixes.
_MIRROR_CLASS_BY_FIXED_ROLE = {3: "S2", 2: "SE+SE", 1: "DL+DL"}


def class_of_tau(tau: Perm | tuple[int, int, int]) -> str:
    """The class of tau = sigma^{-1} ∘ Sigma (fig:triangle)."""
    tau = as_perm(tau)
    if tau.is_identity:
        return "S1"
    fixed = tau.fixed_points()
    if len(fixed) == 1:  # a mirror symmetry of the triangle of roles
        return _MIRROR_CLASS_BY_FIXED_ROLE[fixed[0]]
    return "SE+DL"  # the two rotations (3-cycles)


@dataclass(frozen=True, init=False)
class Case:
    """One of the 36 cases ``(sigma, Sigma)``.

    Attributes
    ----------
    sigma, Sigma:
        The permutations acting on the old and new variables.
    tau:
        sigma^{-1} ∘ Sigma; it determines the class and the sign.
    sign:
        sgn tau, the sign that (volpot2) must carry for a consistent (orientation preserving) map.
    cls:
        One of ``"S1", "S2", "SE+SE", "DL+DL", "SE+DL"``.
    """

    sigma: Perm
    Sigma: Perm

    def __init__(self, sigma: Any, Sigma: Any):
        object.__setattr__(self, "sigma", as_perm(sigma))
        object.__setattr__(self, "Sigma", as_perm(Sigma))

    # -- derived data -------------------------------------------------------------------------
    @property
    def tau(self) -> Perm:
        return self.sigma.inverse() * self.Sigma

    @property
    def sign(self) -> int:
        return self.tau.sign

    @property
    def cls(self) -> str:
        return class_of_tau(self.tau)

    # Roles: which coordinate (1-based) plays x₊, x∘, x₋ and X₊, X∘, X₋.
    @property
    def x_plus(self) -> int:
        return self.sigma(1)

    @property
    def x_circ(self) -> int:
        return self.sigma(2)

    @property
    def x_minus(self) -> int:
        return self.sigma(3)

    @property
    def X_plus(self) -> int:
        return self.Sigma(1)

    @property
    def X_circ(self) -> int:
        return self.Sigma(2)

    @property
    def X_minus(self) -> int:
        return self.Sigma(3)

    @property
    def roles(self) -> dict[str, int]:
        """``{"x+": i, "x∘": j, "x-": k, "X+": I, "X∘": J, "X-": K}`` (1-based coordinates)."""
        out = {f"x{r}": self.sigma(n) for n, r in enumerate(ROLES, start=1)}
        out.update({f"X{r}": self.Sigma(n) for n, r in enumerate(ROLES, start=1)})
        return out

    # -- the two reductions of Section 3.3 ----------------------------------------------------
    def relabel(self, pi: Any) -> "Case":
        """(pi, pi) · (sigma, Sigma) = (pi ∘ sigma, pi ∘ Sigma)  (prop:permactalg); tau is unchanged."""
        pi = as_perm(pi)
        return Case(pi * self.sigma, pi * self.Sigma)

    def switched(self) -> "Case":
        """(Sigma, sigma): the case of the inverse map and of the adjoint method (prop:switchperm).

        Its tau is tau^{-1}, so its sign and class are unchanged.
        """
        return Case(self.Sigma, self.sigma)

    # -- display ------------------------------------------------------------------------------
    def __str__(self) -> str:
        return f"(σ={self.sigma.one_line()}, Σ={self.Sigma.one_line()})"

    def __repr__(self) -> str:
        return (
            f"Case(sigma={self.sigma.one_line()}, Sigma={self.Sigma.one_line()}; "
            f"tau={self.tau.one_line()}, sign={self.sign:+d}, cls={self.cls!r})"
        )


def cases() -> tuple[Case, ...]:
    """All 36 cases in a stable order: sigma, then Sigma, each in lexicographic one-line order."""
    perms = Perm.all()
    return tuple(Case(s, S) for s in perms for S in perms)

"""SE+SE fast path: explicit inverse shears, hence an explicit adjoint (issue #9).

Ψ*_h = (Ψ_{−h})⁻¹ of :class:`SESEFast` is the inverse shears in reverse order; it must be the same
map as the generic adjoint (the GeneratingMap engine's inverse map, prop:volpotinv) for all six
SE+SE cases — relabelled ones included — and volume preserving (det of the jacfwd Jacobian).
"""

import jax.numpy as jnp
import numpy as np
import pytest

from vpforms import cases, scheme
from vpforms.problems import get

SESE_CASES = [c for c in cases() if c.cls == "SE+SE"]
# ABC: every shear explicit; Lotka–Volterra: every shear a scalar Newton (both branches covered)
FIELDS = {"abc": True, "lotka_volterra": False}


def _points(problem, n=8, seed=3):
    lo, hi = np.asarray(problem.field.box, float).T
    return jnp.asarray(np.random.default_rng(seed).uniform(lo, hi, size=(n, 3)) * 0.5 + 0.25 * (lo + hi))


@pytest.fixture(scope="module", params=FIELDS)
def problem(request):
    return get(request.param)


def test_six_cases():
    assert len(SESE_CASES) == 6


@pytest.mark.parametrize("case", SESE_CASES, ids=str)
def test_fast_adjoint_is_generic_adjoint(problem, case):
    h = 0.07
    x = _points(problem)
    fast, generic = scheme(problem.field, case, fast=True), scheme(problem.field, case)
    rep = getattr(fast, "base", fast)
    assert rep.explicit_inverse == (FIELDS[problem.name],) * 2
    fa, ga = fast.adjoint(), generic.adjoint()
    Xf, sf = fa.step_with_status(x, h)
    Xg, sg = ga.step_with_status(x, h)
    assert int(jnp.max(sf)) == 0 and int(jnp.max(sg)) == 0
    assert float(jnp.max(jnp.abs(Xf - Xg))) <= 1e-13
    # Ψ*_{−h} = Ψ_h⁻¹: the fast adjoint at −h undoes the fast step (one compile fewer than inverse_step)
    assert float(jnp.max(jnp.abs(fa.step(fast.step(x, h), -h) - x))) <= 1e-13
    # volume preserving to rounding: det D Ψ*_h = 1
    assert float(jnp.max(jnp.abs(fa.det(x, h) - 1.0))) <= 1e-12

"""Methods as data (issue #10): spec → JSON → method is bit-identical; unshippable input is refused."""

import json

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import vpforms as V
from vpforms import problems as P

X = np.random.default_rng(7).uniform(-0.8, 0.8, (16, 3))


def _roundtrip(m):
    spec = json.loads(json.dumps(m.spec()))  # the spec is JSON
    assert spec["version"] == V.__version__
    return V.method_from_spec(spec)


def _same_step(m, x=X, h=0.05):
    m2 = _roundtrip(m)
    a, b = np.asarray(m.step(x, h)), np.asarray(m2.step(x, h))
    assert np.all(np.isfinite(a))
    assert np.array_equal(a, b)  # bit for bit
    return m2


@pytest.fixture(scope="module")
def lin():
    return P.get("linear").field


def test_all_36_cases_roundtrip(lin):
    # every case: the rebuilt method is the same construction (its spec and traits); the step is
    # compared bit for bit on a sample of cases here and in the hypothesis test (compiles are slow)
    for i, c in enumerate(V.cases()):
        m = V.scheme(lin, c)
        m2 = _roundtrip(m) if i % 18 else _same_step(m)
        assert (m2.case, m2.name, type(m2)) == (m.case, m.name, type(m))
        assert m2.spec() == m.spec()


@pytest.mark.parametrize("cls", V.CLASSES)
def test_every_class(cls, lin):
    _same_step(V.scheme(lin, cls))


def test_compositions_adjoint_rk4(lin):
    f = P.get("abc").field
    _same_step(V.compose(V.scheme(lin, "SE+SE"), 4, "triple_jump"))
    tj = V.compose(V.scheme(f, "SE+DL", theta=0.5), 4, "triple_jump")
    assert V.method_from_spec(json.dumps(tj.spec())).spec() == tj.spec()
    m6 = V.method_from_spec(V.compose(V.scheme(lin, "S2"), 6, "yoshida").spec())
    psi = m6.without_recovery().stages[0].method.name  # S_h = Ψ*_{h/2}∘Ψ_{h/2} composed by Yoshida's coefficients
    assert (m6.order, m6.name) == (6, f"yoshida6[{psi}*∘{psi}]")
    _same_step(V.scheme(lin, "DL+DL").adjoint())
    _same_step(V.RK4(f), x=X + 1.0)


@pytest.mark.parametrize("name", P.names())
def test_every_problem(name):
    prob = P.get(name)
    x = prob.initial_conditions(8, seed=1)
    _same_step(V.scheme(prob.field, "SE+SE"), x=x, h=0.01)


@settings(max_examples=2, deadline=None)
@given(A=st.floats(0.2, 2.0), B=st.floats(0.2, 2.0), C=st.floats(0.0, 2.0),
       case=st.sampled_from(list(V.cases())))
def test_hypothesis_abc_parameters_and_cases(A, B, C, case):
    f = P.get("abc", A=A, B=B, C=C).field
    try:
        m = V.scheme(f, case)
    except V.RecipeError:
        return  # the recipe does not apply to this (field, case): nothing to ship
    spec = json.loads(json.dumps(m.spec()))
    m2 = V.method_from_spec(spec)
    a, b = m.step_with_status(X + 1.0, 0.02), m2.step_with_status(X + 1.0, 0.02)
    assert np.array_equal(np.asarray(a[0]), np.asarray(b[0]), equal_nan=True)
    assert np.array_equal(np.asarray(a[1]), np.asarray(b[1]))


def test_options_flow_through_generically(lin):
    m = V.scheme(lin, "SE+DL", theta=0.25, printed=False)
    assert m.spec()["options"] == {"theta": 0.25, "printed": False}
    assert V.method_from_spec(json.dumps(m.spec())).spec() == m.spec()


def test_callable_field_cannot_be_shipped():
    f = V.Field.from_callable(lambda x: jnp.stack([x[1], -x[0], 0.0 * x[2]]), name="rot")
    with pytest.raises(V.SpecError, match="JAX callable"):
        f.spec()
    with pytest.raises(V.SpecError, match="JAX callable"):
        V.scheme(f, "SE+SE").spec()


def test_bad_specs_are_named_errors(lin):
    with pytest.raises(V.SpecError):
        V.method_from_spec({"kind": "nope"})
    with pytest.raises(V.SpecError):
        V.method_from_spec("{not json")
    with pytest.raises(V.SpecError, match="not JSON-able"):
        V._spec_record._jsonable({"newton": object()})  # the options of a scheme record
    with pytest.raises(V.SpecError, match="no spec"):
        V.SESE(lin).spec()

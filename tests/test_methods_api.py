"""The method contract (issue #5, item 1; docs/ARCHITECTURE.md "Contract: methods").

step maps (3,) and (N, 3) to the same shape, works under jit with a traced h and under vmap,
returns per-point status codes (and Newton iteration counts), raises named errors only outside
jit; traits are data; docstrings cite the paper's equations.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vpforms
from vpforms import RESULTS, Case, NonFiniteError, compose, scheme
from vpforms._methods import DLDL, S1, S2, SEDL, SESE, QuispelCorrection
from vpforms.problems import get


@pytest.fixture(scope="module")
def abc():
    return get("abc").field


def test_shapes_jit_vmap_status_iterations(abc):
    m = scheme(abc, "SE+SE")
    x = jnp.asarray(np.random.default_rng(0).uniform(0, 6, (5, 3)))
    X = m.step(x, 0.1)
    assert X.shape == (5, 3)
    assert m.step(x[0], 0.1).shape == (3,)
    assert float(jnp.max(jnp.abs(m.step(x[0], 0.1) - X[0]))) == 0.0
    assert m.step(x.reshape(5, 1, 3), 0.1).shape == (5, 1, 3)
    # traced h inside a user's jit, and vmap over step sizes
    f = jax.jit(lambda x, h: m.step(x, h))
    assert float(jnp.max(jnp.abs(f(x, 0.1) - X))) == 0.0
    hs = jnp.array([0.1, 0.05])
    Xh = jax.vmap(lambda h: m.step(x, h))(hs)
    assert float(jnp.max(jnp.abs(Xh[0] - X))) == 0.0
    X2, status, iters = m.step_with_status(x, 0.1, return_iterations=True)
    assert status.shape == (5,) and status.dtype == jnp.int32 and np.all(np.asarray(status) == 0)
    assert iters.shape == (5,) and np.all(np.asarray(iters) >= 1)
    # non-finite input: a status code under jit, a named error at the boundary
    bad = x.at[1, 0].set(jnp.nan)
    _, status = m.step_with_status(bad, 0.1)
    assert int(status[1]) == RESULTS.nonfinite and int(status[0]) == 0
    with pytest.raises(NonFiniteError):
        m(bad, 0.1)
    with pytest.raises(ValueError, match="h must be finite"):
        m(x, float("nan"))
    with pytest.raises(TypeError, match="vpforms.Field"):
        vpforms.scheme(lambda x: x, "SE+SE")  # a plain callable has no potentials


def test_traits_are_data_and_docstrings_cite_the_paper(abc):
    lin = vpforms.Field.linear(get("linear").field.linear_matrix)
    for cls, M, label in (
        ("SE+SE", SESE, "eq:case5"),
        ("SE+DL", SEDL, "eq:case4"),
        ("DL+DL", DLDL, "eq:case3"),
        ("S1", S1, "eq:S1"),
        ("S2", S2, "eq:S2"),
    ):
        assert label in M.__doc__ or label in __import__(M.__module__, fromlist=["x"]).__doc__
        m = scheme(lin, cls, recover=False)  # the bare class recipe
        assert isinstance(m, M) and isinstance(scheme(lin, cls).without_recovery(), M)
        assert (m.cls, m.order, m.symmetric) == (cls, 1, False)
        assert isinstance(m.case, Case) and m.case.cls == cls
        c2 = compose(m, order=4)
        assert (c2.order, c2.symmetric, c2.cls) == (4, True, cls)
    assert "t5vp" in QuispelCorrection.__doc__ and "t5vps2" in QuispelCorrection.__doc__
    assert isinstance(scheme(abc, "S1", recover=False), QuispelCorrection)  # nonlinear field: correction map
    assert scheme(abc, "DL+SE").cls == "SE+DL"


def test_every_step_goes_through_the_engine(abc, monkeypatch):
    # the generic engine is the only solver the recipes call (fast paths excepted)
    calls = []
    orig = vpforms.GeneratingMap.solve

    def spy(self, *a, **k):
        calls.append(self.case)
        return orig(self, *a, **k)

    monkeypatch.setattr(vpforms.GeneratingMap, "solve", spy)
    x = jnp.asarray([0.6, 0.7, 0.8])
    for c in (Case((3, 2, 1), (1, 2, 3)), Case((1, 2, 3), (3, 1, 2)), Case((2, 1, 3), (3, 2, 1))):
        calls.clear()
        # (the DL classes in their engine form: by default they evaluate the same map by stages)
        engine = {"fast": False} if c.cls in ("SE+DL", "DL+DL") else {}
        jax.jit(lambda x: scheme(abc, c, recover=False, **engine)._forward(x, 0.05)[0])(x)
        assert calls and calls[-1] == c  # the map solved is the one of case c itself

"""jit_hoisted: closed-over arrays reach the compiled program as arguments, not as constants."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from vpforms._hoist import jit_hoisted

BIG = 200_000  # 1.6 MB of float64: as a constant it would dominate the program's text


@pytest.mark.parametrize("kind", ["jax", "numpy"])
def test_the_closed_over_array_is_an_argument_and_the_values_are_jits(kind):
    rng = np.random.default_rng(0)
    table = rng.standard_normal(BIG)
    table = jnp.asarray(table) if kind == "jax" else table

    def f(x, scale):
        i = (jnp.abs(x) * 1000).astype(int) % BIG
        return {"y": jnp.asarray(table)[i] * scale, "s": jnp.sum(jnp.asarray(table)[:10]) + x[0]}

    x = jnp.asarray(rng.uniform(-3, 3, 64))
    got, want = jit_hoisted(f)(x, 2.0), jax.jit(f)(x, 2.0)
    np.testing.assert_array_equal(np.asarray(got["y"]), np.asarray(want["y"]))
    np.testing.assert_array_equal(np.asarray(got["s"]), np.asarray(want["s"]))
    g = jit_hoisted(f)
    g(x, 2.0)
    (run, consts, _), = g.programs.values()
    assert any(np.shape(c) == (BIG,) for c in consts)
    text = run.lower(consts, x, 2.0).as_text()
    assert len(text) < 0.05 * BIG * 8, len(text)  # the plain jit's text holds the 1.6 MB table
    assert len(jax.jit(f).lower(x, 2.0).as_text()) > BIG * 8


def test_one_program_per_signature_and_a_closure_over_a_tracer_falls_back():
    calls = []

    def f(x):
        calls.append(x.shape)
        return 2 * x

    g = jit_hoisted(f)
    for n in (3, 3, 4):
        np.testing.assert_array_equal(np.asarray(g(jnp.ones(n))), 2 * np.ones(n))
    assert calls == [(3,), (4,)] and len(g.programs) == 2

    @jax.jit
    def outer(y):  # the inner function closes over y, a tracer of the outer jit
        return jit_hoisted(lambda x: x * y)(jnp.ones(3))

    np.testing.assert_array_equal(np.asarray(outer(5.0)), 5.0 * np.ones(3))
    np.testing.assert_array_equal(np.asarray(outer(7.0)), 7.0 * np.ones(3))

"""Perm: the group S₃ in one-line notation and its right action (MATH.md §2)."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vpforms import FLIP, Perm

ALL = [tuple(p) for p in itertools.permutations((1, 2, 3))]


def matrix(p):
    """Permutation matrix P with (P x) = x·p, built independently from the definition."""
    P = np.zeros((3, 3))
    for i in range(3):
        P[i, p[i] - 1] = 1.0
    return P


def test_six_elements_in_stable_order():
    perms = Perm.all()
    assert [tuple(p) for p in perms] == sorted(ALL)
    assert len(set(perms)) == 6


@pytest.mark.parametrize("p", ALL)
@pytest.mark.parametrize("q", ALL)
def test_composition_is_p_after_q(p, q):
    pq = Perm(p) * Perm(q)
    assert tuple(pq) == tuple(p[q[i] - 1] for i in range(3))
    # as matrices of the right action: x·(p∘q) = (x·p)·q  <=>  P_{p∘q} = P_q P_p
    np.testing.assert_array_equal(matrix(tuple(pq)), matrix(q) @ matrix(p))


@pytest.mark.parametrize("p", ALL)
def test_inverse_and_sign(p):
    P = Perm(p)
    assert (P * P.inverse()).is_identity and (P.inverse() * P).is_identity
    assert P.sign == round(np.linalg.det(matrix(p)))


@pytest.mark.parametrize("p", ALL)
@pytest.mark.parametrize("q", ALL)
def test_right_action_law(p, q):
    x = np.array([10.0, 20.0, 30.0])
    assert np.array_equal(Perm(p).act(x), np.array([x[p[i] - 1] for i in range(3)]))
    # (x·π)·σ = x·(π∘σ)
    assert np.array_equal(Perm(q).act(Perm(p).act(x)), (Perm(p) * Perm(q)).act(x))


@given(st.sampled_from(ALL), st.integers(1, 7))
@settings(max_examples=20, deadline=None)
def test_action_on_batches(p, n):
    x = np.random.default_rng(n).normal(size=(n, 3))
    out = Perm(p).act(x)
    assert out.shape == (n, 3)
    for row_in, row_out in zip(x, out):
        assert np.array_equal(row_out, Perm(p).act(row_in))


def test_action_rejects_bad_shapes():
    with pytest.raises(ValueError, match="shape"):
        Perm((1, 2, 3)).act(np.zeros(4))
    with pytest.raises(ValueError, match="shape"):
        Perm((1, 2, 3)).act(np.zeros((5, 2)))


def test_cycles_and_repr():
    assert Perm((3, 2, 1)).cycles() == ((1, 3),)
    assert Perm((2, 3, 1)).cycles() == ((1, 2, 3),)
    assert Perm((1, 2, 3)).cycles() == ()
    assert "(1 3)" in repr(Perm((3, 2, 1)))
    assert "id" in repr(Perm((1, 2, 3)))
    for p in ALL:  # each cycle maps its elements along the cycle
        P = Perm(p)
        for cyc in P.cycles():
            for a, b in zip(cyc, cyc[1:] + cyc[:1]):
                assert P(a) == b


@pytest.mark.parametrize(
    "bad", [(1, 2), (1, 1, 2), (0, 1, 2), (1, 2, 4), (1.0, 2, 3), (True, 2, 3), "123", None, 3]
)
def test_malformed_permutations_raise_naming_the_input(bad):
    with pytest.raises(ValueError) as err:
        Perm(bad)
    assert repr(bad) in str(err.value)


def test_flip_and_argument_permutation():
    f = lambda a, b, c: a + 10 * b + 100 * c  # noqa: E731
    assert FLIP == (3, 2, 1)
    assert FLIP.act_args(f)(1.0, 2.0, 3.0) == f(3.0, 2.0, 1.0)
    assert FLIP.act_args(FLIP.act_args(f)) is f  # p is an involution
    for p in ALL:
        for q in ALL:
            y = np.array([1.0, 2.0, 3.0])
            g = Perm(q).act_args(Perm(p).act_args(f))  # ((f·p)·q)(y) = f((y·q)·p)
            assert g(*y) == f(*Perm(p).act(Perm(q).act(y)))
            assert g(*y) == (Perm(q) * Perm(p)).act_args(f)(*y)  # = f·(q∘p)

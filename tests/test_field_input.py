"""Field.from_sympy input conveniences (issue #12 item 3): plain coordinate symbols, linear fields
written in any form (constant Jacobian) get the linear treatment (the S1/S2 AZ variant applies)."""

from __future__ import annotations

import numpy as np
import sympy as sp

from vpforms import Field, cases, scheme
from vpforms.fields import SYMBOLS

S1_CASE = next(c for c in cases() if c.cls == "S1")


def test_plain_symbols_are_the_coordinates():
    y = sp.symbols("x1 x2 x3")  # no real=True
    f = Field.from_sympy([sp.sin(y[1]), sp.cos(y[2]), sp.sin(y[0])])
    g = Field.from_sympy([sp.sin(SYMBOLS[1]), sp.cos(SYMBOLS[2]), sp.sin(SYMBOLS[0])])
    x = np.array([0.3, -0.2, 0.7])
    assert np.allclose(np.asarray(f(x)), np.asarray(g(x)), rtol=0, atol=0)
    assert f.exprs == g.exprs


def test_constant_jacobian_is_linear_and_takes_the_az_variant():
    x1, x2, x3 = SYMBOLS
    # a(x) = A x with A traceless, written so that it is not a polynomial
    exprs = [x2 + sp.sin(x1) ** 2 + sp.cos(x1) ** 2 - 1, -x1 + x3, x1 - x2 + sp.log(sp.exp(0 * x3))]
    f = Field.from_sympy(exprs)
    A = np.array([[0.0, 1, 0], [-1, 0, 1], [1, -1, 0]])
    assert f.linear_matrix is not None and np.array_equal(f.linear_matrix, A)
    m = scheme(f, S1_CASE, variant="az")
    x = np.array([0.2, 0.1, -0.3])
    assert abs(float(m.det(x, 0.05)) - 1.0) <= 1e-12
    # the same method as for Field.linear(A)
    ref = scheme(Field.linear(A), S1_CASE, variant="az")
    assert float(np.max(np.abs(np.asarray(m.step(x, 0.05)) - np.asarray(ref.step(x, 0.05))))) <= 1e-14


def test_nonlinear_field_is_not_linear():
    x1, x2, x3 = SYMBOLS
    assert Field.from_sympy([sp.sin(x2), sp.cos(x3), sp.sin(x1)]).linear_matrix is None
    assert Field.from_sympy([x2 + 1, x3, x1]).linear_matrix is None  # affine, a(0) ≠ 0

"""The SymPy symbols shared by the whole symbolic layer (one definition, reused everywhere).

* ``x1, x2, x3`` — the old variables x, ``X1, X2, X3`` — the new variables X = f(x);
* ``h`` — the time step (the paper's Δt);
* ``a11 … a33`` — the entries of a linear field a(x) = A x (eq:linear);
* ``y1, y2, y3, Y1, Y2, Y3`` — the *generic* arguments of eq:volpot, y = x·σ, Y = X·Σ.

All are real SymPy ``Symbol``s; SymPy identifies symbols by name and assumptions, so a user who
writes ``sympy.Symbol("x1", real=True)`` gets the same symbol.
"""

from __future__ import annotations

import sympy as sp

__all__ = ["x", "X", "y", "Y", "h", "A", "a", "COORDS", "x1", "x2", "x3", "X1", "X2", "X3"]

x1, x2, x3 = sp.symbols("x1 x2 x3", real=True)
X1, X2, X3 = sp.symbols("X1 X2 X3", real=True)
#: The old variables (x1, x2, x3) and the new variables (X1, X2, X3).
x: tuple[sp.Symbol, sp.Symbol, sp.Symbol] = (x1, x2, x3)
X: tuple[sp.Symbol, sp.Symbol, sp.Symbol] = (X1, X2, X3)
#: The six coordinates of R⁶ = {(x, X)} on which the graph of the map lives.
COORDS: tuple[sp.Symbol, ...] = x + X
#: Generic arguments of eq:volpot: y = x·σ = (x₊, x∘, x₋), Y = X·Σ = (X₊, X∘, X₋).
y = sp.symbols("y1 y2 y3", real=True)
Y = sp.symbols("Y1 Y2 Y3", real=True)
#: The time step (the paper's Δt).
h = sp.Symbol("h", real=True)
#: The entries of a linear field a = A x: a[i][j] is a_{i+1, j+1}; A is the 3×3 Matrix.
a = tuple(tuple(sp.Symbol(f"a{i}{j}", real=True) for j in (1, 2, 3)) for i in (1, 2, 3))
A = sp.Matrix(a)

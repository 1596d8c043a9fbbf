"""Run-time data of generated kernels: refs to data, their slots in ``fd``, the emitter's scopes.

A field whose potentials are evaluations of data — a spline of A (:mod:`.splines`), filament
coils (:mod:`.coils`) — enters the generated code as SymPy atoms holding a :class:`DataRef`; a
:class:`DataRef` scalar (the base point c of an antiderivative, a grid bound, a period) is a
number the kernel reads at run time. So the C source depends only on the field's structure, and
the data travel in one ``const double *fd`` array (:func:`field_data`): slot j (in the order the
emitter first meets the refs) is ``HS`` doubles at ``fd + HS·j`` — a scalar's value, or the header
its kind's packer writes (offsets, counting from fd, of arrays that follow the headers).

The emitter's state (:class:`_Emission`, active inside :func:`collecting`) holds the refs, a stack
of C scopes with what was already evaluated there (an outer scope's values are visible in inner
ones: a Newton loop reuses what was hoisted before it), and the helper functions the kernel needs.
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np
import sympy as sp

__all__ = ["HS", "PACKERS", "DataRef", "code3", "collecting", "data_atoms", "data_refs", "e_sub",
           "emission", "field_data", "nested", "read_scalars", "scope", "uncode3"]

#: doubles per slot of the data array (a scalar, or a header)
HS = 16


class DataRef(sp.Dummy):
    """A symbol standing for run-time data: a spline or coils (inside their atoms), or a float
    (printed as a read of the data array). A Dummy: two data sets never share a ref, and
    expressions order by its name (structural), not by the data."""

    obj: Any = None

    def __new__(cls, name: str, obj: Any):
        self = super().__new__(cls, name)
        self.obj = obj
        return self


def code3(v: Sequence[int]) -> sp.Integer:
    """Three small integers (derivative orders, degrees: each < 10) as one SymPy integer (an
    argument of an atom, which SymPy differentiates like any other: it must be an Expr)."""
    if not all(0 <= int(a) < 10 for a in v):
        raise ValueError(f"native atoms take orders and degrees 0–9; got {tuple(v)}")
    return sp.Integer(100 * int(v[0]) + 10 * int(v[1]) + int(v[2]))


def uncode3(c: Any) -> list[int]:
    c = int(c)
    return [c // 100, c // 10 % 10, c % 10]


class _Emission:
    """What the emitter of one kernel knows: the data refs (slots in order of first use), the
    knot classes of splines (:mod:`.splines`), a stack of C scopes holding what was already
    emitted, and the helper functions (name → C) the kernel defines before its stages."""

    def __init__(self):
        self.refs: list = []
        self.classes: list = []
        self.scopes: list[dict] = [{}]
        self.count = 0
        self.helpers: dict[Any, tuple[str, str]] = {}

    def slot(self, ref: DataRef) -> int:
        for j, r in enumerate(self.refs):
            if r is ref:
                return j
        self.refs.append(ref)
        return len(self.refs) - 1

    def find(self, key: Any) -> Any:
        for sc in reversed(self.scopes):
            if key in sc:
                return sc[key]
        return None


_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("vp_native_data", default=None)


@contextmanager
def collecting():
    """Collect the data refs the emitter meets (slots in order of first use); yields the list."""
    em = _Emission()
    token = _ACTIVE.set(em)
    try:
        yield em.refs
    finally:
        _ACTIVE.reset(token)


def emission(required: bool = True) -> _Emission | None:
    """The active emitter state; outside kernel generation None, or an error if ``required``."""
    em = _ACTIVE.get()
    if em is None and required:
        raise RuntimeError("run-time field data met outside kernel generation")
    return em


@contextmanager
def scope(function: bool = False):
    """A C block (``function``: a new C function, which sees nothing emitted before): what is
    emitted inside is forgotten at its end. A no-op outside kernel generation."""
    em = _ACTIVE.get()
    if em is None:
        yield
        return
    saved = (em.scopes, em.count)
    em.scopes = [{}] if function else [*em.scopes, {}]
    if function:
        em.count = 0
    try:
        yield
    finally:
        em.scopes = saved[0]
        if function:
            em.count = saved[1]


def data_refs(expr: Any) -> list:
    """The data refs in ``expr`` in a structural order (name, then creation), never a set's: the
    slots are given in the order met, so two fields of the same structure get the same C."""
    return sorted((s for s in sp.sympify(expr).free_symbols if isinstance(s, DataRef)),
                  key=lambda r: (r.name, r.dummy_index))


def data_atoms(e: Any) -> set:
    """The atoms of ``e`` that evaluate run-time data at a point (spline and coil atoms, marked
    ``_vp_at_point``: their point is ``args[3:]``)."""
    return {f for f in sp.sympify(e).atoms(sp.Function) if getattr(type(f), "_vp_at_point", False)}


def nested(atom: Any) -> bool:
    """Whether ``atom`` is evaluated at a point that holds data atoms (a field at x + h a(x)):
    its inner atoms are evaluated first (:func:`.assign._nested_calls`), never hoisted with it."""
    return any(data_atoms(x) for x in atom.args[3:])


def e_sub(e: Any) -> Any:
    """The data scalars in ``e`` as reads of ``fd``."""
    em = emission()
    return sp.sympify(e).xreplace({r: sp.Symbol(f"fd[{HS * em.slot(r)}]") for r in data_refs(e)})


def read_scalars(exprs: list[Any]) -> list[Any]:
    """:func:`e_sub` of each expression."""
    if not any(data_refs(e) for e in exprs):
        return exprs
    return [e_sub(e) for e in exprs]


#: per kind of data object (its type): pack(obj, header (HS,), put) writes the object's header;
#: put(array) appends an array after the headers and returns its offset from fd. Registered by
#: the modules of the kinds (:mod:`.splines`, :mod:`.coils`); anything else is a float scalar.
PACKERS: dict[type, Callable[[Any, np.ndarray, Callable[[Any], int]], None]] = {}


def field_data(refs: Sequence[DataRef]) -> np.ndarray | None:
    """The ``fd`` array of the refs (module docstring), or None when there are none."""
    if not refs:
        return None
    head = np.zeros((len(refs), HS))
    arrays: list[np.ndarray] = []
    pos = len(refs) * HS

    def put(a) -> int:
        nonlocal pos
        a = np.ascontiguousarray(np.asarray(a, dtype=np.float64)).ravel()
        arrays.append(a)
        pos += a.size
        return pos - a.size

    for j, r in enumerate(refs):
        pack = next((p for t, p in PACKERS.items() if isinstance(r.obj, t)), None)
        if pack is not None:
            pack(r.obj, head[j], put)
        else:
            head[j, 0] = float(r.obj)
    return np.concatenate([head.ravel(), *arrays])

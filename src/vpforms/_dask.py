"""What every Dask route of vpforms shares (issues #10, #22, #38): the client, and a method rebuilt
once per worker process from what travels to it.

A method never travels pickled (its jitted functions do not pickle, and the native kernel is
compiled per process). What travels is a *recipe*:

* its JSON spec text (:meth:`method.spec`, :mod:`vpforms._spec`) — every method of a symbolic or
  linear field;
* or, for a method whose field has no spec (a spline of a coil set, a device's grid: its data are
  not JSON), a picklable zero-argument ``builder`` that builds it (e.g.
  ``functools.partial(f, "w7x", grid)`` of a module-level ``f``), with the method's
  description (the method and its field in words): the worker checks that the builder built
  that method.

Each process keeps what it built (:func:`method_of`), keyed by the recipe; the caller's own process
uses the caller's method object (:data:`IN_PROCESS`, already compiled).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import pickle
from collections.abc import Callable
from typing import Any

from ._errors import SpecError
from ._solution import describe
from ._spec import method_from_spec

__all__ = ["IN_PROCESS", "Recipe", "client", "close", "in_process", "method_of", "n_workers", "recipe"]

#: recipe key → the caller's own method (in-process runs)
IN_PROCESS: dict[str, Any] = {}

#: what travels to a worker: (key, spec text or None, builder or None, describe(method))
Recipe = tuple


@functools.lru_cache(maxsize=8)
def _from_spec(spec_text: str) -> Any:
    return method_from_spec(json.loads(spec_text))


_BUILT: dict[str, Any] = {}  # recipe key → the method a builder built in this process


def recipe(method: Any, builder: Callable[[], Any] | None = None) -> Recipe:
    """The recipe of ``method``: its spec text, or ``builder`` (then its pickle's SHA-256 is the key).

    Raises
    ------
    SpecError
        No builder and a method whose field has no spec (the error says to pass a builder).
    TypeError
        A builder that is not callable or does not pickle.
    """
    if builder is None:
        try:
            if not callable(getattr(method, "spec", None)):
                raise SpecError(f"{type(method).__name__} has no spec() (it was not built by vpforms)")
            text = json.dumps(method.spec(), sort_keys=True)
        except SpecError as err:
            raise SpecError(f"{err}; to run it on Dask workers pass builder=, a picklable zero-argument "
                            "callable that builds the method in each worker (e.g. functools.partial of a "
                            "module-level function)") from None
        return (text, text, None, _what(method))
    if not callable(builder):
        raise TypeError(f"builder must be a zero-argument callable that builds the method; got {builder!r:.80}")
    try:
        blob = pickle.dumps(builder)
    except Exception as err:  # noqa: BLE001 — pickle raises many kinds (PicklingError, AttributeError, …)
        raise TypeError(f"builder {builder!r:.80} does not pickle ({type(err).__name__}: {err}); use a "
                        "module-level function or a functools.partial of one") from None
    return ("builder:" + hashlib.sha256(blob).hexdigest(), None, builder, _what(method))


def _what(method: Any) -> str:
    """The method and its field in words (what a builder must reproduce)."""
    field = getattr(method, "field", None)
    return describe(method) + (f" on the field {field.name!r}" if getattr(field, "name", None) else "")


def in_process(method: Any) -> Recipe:
    """The recipe of a run in this process: the caller's method itself (no spec, no builder needed)."""
    IN_PROCESS.clear()
    IN_PROCESS["in process"] = method
    return ("in process", None, None, _what(method))


def method_of(rec: Recipe) -> Any:
    """The method of a recipe, built once per process: the caller's own object in its process, else
    rebuilt from the spec or by the builder (ValueError if the builder built another method)."""
    key, text, builder, what = rec
    m = IN_PROCESS.get(key)
    if m is not None:
        return m
    if text is not None:
        return _from_spec(text)
    m = _BUILT.get(key)
    if m is None:
        m = builder()
        got = _what(m)
        if got != what:
            raise ValueError(f"the builder built {got}, not the method it was given for ({what})")
        _BUILT[key] = m
    return m


def client(client: Any, workers: int | None = None) -> tuple[Any, bool]:
    """(client, owned) for ``client`` = "local" (a ``LocalCluster`` of ``workers`` processes, 1
    thread each; default one per core), an int (that many local workers), "tcp://…" (a scheduler)
    or a ``dask.distributed.Client`` (the caller's: not owned, never closed here)."""
    from dask.distributed import Client, LocalCluster

    if isinstance(client, bool):
        raise TypeError(f"client must be 'local', a worker count, 'tcp://…' or a dask Client; got {client!r}")
    if isinstance(client, int):
        if client < 1:
            raise ValueError(f"a worker count must be ≥ 1; got {client}")
        client, workers = "local", client
    if isinstance(client, str):
        if client == "local":
            cluster = LocalCluster(n_workers=int(workers or os.cpu_count() or 1), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            return Client(cluster), True
        return Client(client), True
    return client, False


def close(cl: Any, owned: bool) -> None:
    """Close a client (and its cluster) that :func:`client` made; leave a caller's client open."""
    if owned:
        cluster = getattr(cl, "cluster", None)
        cl.close()
        if cluster is not None:
            cluster.close()


def n_workers(cl: Any) -> int:
    """The number of worker threads of a client (≥ 1)."""
    try:
        return max(1, int(sum(cl.nthreads().values())))
    except Exception:  # noqa: BLE001 — a client that cannot say (a test double)
        return 1

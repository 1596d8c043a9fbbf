"""Walls in chunks of lines, in this process or as Dask tasks (issue #21 item 4, issue #38 item 4).

:func:`trace_to_wall_chunks` is the one implementation behind
:func:`vpforms.distributed.trace_to_wall` and the Dask route of
:func:`vpforms.fieldlines.connection_length`: the lines are cut into chunks, each chunk is one call
of :func:`~vpforms.fieldlines.trace_to_wall` (a task on a worker, which rebuilds the method from its
recipe once per process: :mod:`vpforms._dask`), for one or several step sizes at once (a connection
length traces every line with h and with −h: both directions' chunks are submitted together, so
that no worker waits for the other direction to start).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import _dask
from ._wall import WallHits, check_wall_run, trace_to_wall, wall_backend

__all__ = ["trace_to_wall_chunks"]


def _wall_chunk(rec: _dask.Recipe, x: np.ndarray, h: float, n_steps: int, wall: Any, t0: float,
                backend: str) -> WallHits:
    """One chunk: the lines ``x`` traced to the wall with step h in this process."""
    return trace_to_wall(_dask.method_of(rec), x, h, n_steps, wall, t0=t0, progress=False, backend=backend)


def trace_to_wall_chunks(method: Any, x0: Any, hs: Sequence[float], n_steps: int, wall: Any, *, t0: float = 0.0,
                         chunk_particles: int | None = 65536, client: Any = None, workers: int | None = None,
                         backend: str = "auto", retries: int = 3, progress: bool | str = "auto",
                         builder: Callable[[], Any] | None = None) -> tuple[list[WallHits], dict]:
    """The lines x0 traced to ``wall`` with each step h of ``hs``, in chunks of ``chunk_particles``
    lines (None: one chunk in this process, about four per worker thread on Dask); ``client`` None (this
    process), "local", a worker count, "tcp://…" or a ``dask.distributed.Client``
    (:func:`vpforms._dask.client`). Returns ([the :class:`WallHits` of all lines for each h], info)
    with info = {"chunks", "workers", "wall_s" (per h in this process; all of them together on
    Dask), "where"}.

    The backend is chosen once, here, and every chunk runs it; a method whose field has no JSON spec
    travels as ``builder`` (:func:`vpforms._dask.recipe`).
    """
    hs = [float(h) for h in hs]
    if not hs:
        raise ValueError("trace_to_wall_chunks needs at least one step size")
    pts = None
    for h in hs:  # every h checked (the start points once: the same for all)
        pts, _, n_steps = check_wall_run(method, x0, h, n_steps, wall, t0)
    backend, reason = wall_backend(method, backend)
    # what the workers rebuild the method from (SpecError: no builder, no spec) before any cluster starts
    rec = _dask.in_process(method) if client is None else _dask.recipe(method, builder)
    N = pts.shape[0]
    show = progress is True or (progress == "auto" and sys.stderr.isatty())
    cl, owned = (None, False) if client is None else _dask.client(client, workers)
    try:
        W = 1 if cl is None else _dask.n_workers(cl)
        if chunk_particles is None:
            C = max(1, N if cl is None else -(-N // (4 * W)))
        else:
            C = int(chunk_particles)
            if C < 1:
                raise ValueError(f"chunk_particles must be ≥ 1, got {chunk_particles}")
        chunks = [pts[lo:lo + C] for lo in range(0, N, C)] or [pts]
        parts: list[list[WallHits]] = [[] for _ in hs]
        info = {"chunks": len(chunks), "workers": W, "wall_s": [], "where": "in process" if cl is None else
                f"Dask, {W} worker thread(s)"}
        if cl is None:
            for i, h in enumerate(hs):
                t = time.perf_counter()
                for k, x in enumerate(chunks):
                    parts[i].append(_wall_chunk(rec, x, h, n_steps, wall, float(t0), backend))
                    if show:
                        print(f"vpforms: wall chunk {k + 1}/{len(chunks)} (h = {h:g}) done", file=sys.stderr)
                info["wall_s"].append(time.perf_counter() - t)
        else:
            t = time.perf_counter()
            futs = [[cl.submit(_wall_chunk, rec, x, h, n_steps, wall, float(t0), backend, pure=False,
                               retries=retries) for x in chunks] for h in hs]
            done = 0
            for i, fs in enumerate(futs):
                for f in fs:
                    parts[i].append(f.result())
                    done += 1
                    if show:
                        print(f"vpforms: wall chunk {done}/{len(chunks) * len(hs)} done", file=sys.stderr)
            info["wall_s"] = [time.perf_counter() - t] * len(hs)
    finally:
        if cl is not None:
            _dask.close(cl, owned)
    out = [dataclasses.replace(WallHits.concatenate(p), backend=backend, backend_reason=reason) for p in parts]
    return out, info

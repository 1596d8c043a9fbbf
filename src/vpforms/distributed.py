"""Chunked, resumable, optionally Dask-distributed particle runs into a Zarr store (issue #10).

``run(method, x0, h, n_steps, store=…)`` splits the N particles into chunks of
``chunk_particles``; each chunk is one task that rebuilds the method from its JSON spec (cached
per worker process: no pickled jitted functions travel), runs :func:`vpforms.integrate` on its
particles segment by segment (``checkpoint_every`` steps per segment, a checkpoint after each),
writes its rows straight into the store and THEN marks itself done.

* ``client=None``: in this process, chunk after chunk; ``"local"``: a
  ``dask.distributed.LocalCluster`` of ``workers`` processes with 1 thread each; ``"tcp://…"``:
  connect to a scheduler; or a ``dask.distributed.Client``.
* resume: a store whose spec, h, n_steps, t0, save_every, chunking and x0 hash match is continued
  (only chunks without a done marker run, each from its checkpoint); any mismatch is a
  :class:`~vpforms.io.StoreMismatchError`, never a mixed store.
* a killed worker: Dask re-runs its task elsewhere (``retries``); a chunk is written whole by one
  task, so a re-run overwrites, never duplicates.

Bitwise reproducibility: a particle's trajectory depends only on its own state (the kernel is
vmapped per particle), so chunking and segmenting reproduce a single ``integrate`` bit for bit
(tested).  Failed particles stay frozen across segments, as in one ``integrate`` call.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import sys
import time
from typing import Any

import numpy as np

from . import io as _io
from ._integrate import saved_steps as _global_steps

__all__ = ["run", "run_chunk"]


_IN_PROCESS: dict[str, Any] = {}  # spec text → the caller's own method (in-process runs)


@functools.lru_cache(maxsize=8)
def _rebuilt(spec_text: str):
    from ._spec import method_from_spec

    return method_from_spec(json.loads(spec_text))


def _method(spec_text: str):
    """The method of a spec, built once per process (compilation cached with it); in the
    caller's process the caller's own method object (already compiled)."""
    m = _IN_PROCESS.get(spec_text)
    return m if m is not None else _rebuilt(spec_text)


def run_chunk(spec_text: str, store: str, c: int, lo: int, x0: np.ndarray, h: float, n_steps: int,
              save_every: int | None, t0: float, segment: int, backend: str | None = None) -> dict:
    """Run chunk ``c`` (particles lo … lo + len(x0)) into ``store``; the unit of work of a task."""
    from ._integrate import integrate

    if _io.is_done(store, c):
        return {"chunk": c, "skipped": True, "wall_s": 0.0}
    t_start = time.perf_counter()
    method = _method(spec_text)
    n = x0.shape[0]
    hi = lo + n
    gsteps = _global_steps(n_steps, save_every)
    ck = _io.ckpt_path(store, c)
    if os.path.exists(ck):
        with np.load(ck) as z:
            x, status, failed, n_done = z["x"], z["status"], z["failed"], int(z["n_done"])
            recovered = z["recovered"]
    else:
        x, status, failed, n_done = x0.copy(), np.zeros(n, np.int32), np.full(n, -1, np.int64), 0
        recovered = np.zeros(n, np.int64)  # steps recovered per particle (issue #12), as Solution.recovered
    first = None if n_done else x0[:, None, :]  # x0 goes out with the first segment (one write)
    kw = {} if backend is None else {"backend": backend}
    while n_done < n_steps:
        m = min(segment, n_steps - n_done)
        sol = integrate(method, x, h, m, save_every=save_every, t0=t0 + h * n_done,
                        chunk_size=n, progress=False, **kw)
        alive = status == 0
        xs = np.array(sol.xs)
        xs[~alive] = x[~alive, None, :]  # a failed particle stays frozen (as in one integrate)
        newly = alive & (sol.status != 0)
        status = np.where(newly, sol.status, status).astype(np.int32)
        failed = np.where(newly, sol.failed_step + n_done, failed).astype(np.int64)
        if sol.recovered is not None:  # a frozen particle takes no step, so it recovers none
            recovered = recovered + np.where(alive, sol.recovered, 0).astype(np.int64)
        idx = np.searchsorted(gsteps, n_done + sol.steps[1:])
        if idx.size and np.array_equal(gsteps[idx], n_done + sol.steps[1:]):
            keep = slice(None)
        else:  # save_every=None: only the very last state is stored
            keep = np.isin(n_done + sol.steps[1:], gsteps)
            idx = np.searchsorted(gsteps, (n_done + sol.steps[1:])[keep])
        x = xs[:, -1]
        n_done += m
        last = n_done >= n_steps
        if idx.size or first is not None:
            out = xs[:, 1:][:, keep]
            t_lo = int(idx[0]) if idx.size else 0
            if first is not None:
                out, t_lo, first = np.concatenate([first, out], axis=1) if idx.size else first, 0, None
            _io.write_chunk(store, lo, hi, x=out, t_lo=t_lo,
                            **({"status": status, "failed": failed, "recovered": recovered} if last else {}))
        elif last:
            _io.write_chunk(store, lo, hi, status=status, failed=failed, recovered=recovered)
        if n_done < n_steps:  # checkpoint: the state at step n_done (atomic replace)
            tmp = ck + f".{os.getpid()}.tmp.npz"
            np.savez(tmp, x=x, status=status, failed=failed, recovered=recovered, n_done=n_done)
            os.replace(tmp, ck)
    if n_steps == 0:
        _io.write_chunk(store, lo, hi, x=x0[:, None, :], status=status, failed=failed, recovered=recovered)
    _io.mark_done(store, c)  # after the data: a half-written chunk is never read as done
    if os.path.exists(ck):
        os.remove(ck)
    return {"chunk": c, "skipped": False, "wall_s": time.perf_counter() - t_start, "particles": n}


def _client(client: Any, workers: int | None):
    """(client, owned) for client = "local" | "tcp://…" | a Client."""
    from dask.distributed import Client, LocalCluster

    if isinstance(client, str):
        if client == "local":
            cluster = LocalCluster(n_workers=int(workers or os.cpu_count() or 1), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            return Client(cluster), True
        return Client(client), True
    return client, False


def run(method: Any, x0: Any, h: float, n_steps: int, *, store: str, save_every: int | None = None,
        t0: float = 0.0, chunk_particles: int = 65536, client: Any = None, workers: int | None = None,
        checkpoint_every: int | None = None, resume: bool = True, progress: bool | str = "auto",
        backend: str | None = None, retries: int = 3):
    """Run the particles x0 (N, 3) with ``method`` into the Zarr ``store``; return the xarray Dataset.

    ``checkpoint_every`` (steps, rounded up to a multiple of ``save_every``; None = no checkpoints)
    is the segment length after which each chunk saves its state.  See the module docstring.
    """
    from ._integrate import _check_run

    pts, _single, h, n_steps = _check_run(method, x0, h, n_steps, t0)
    if save_every is not None and int(save_every) < 1:
        raise ValueError(f"save_every must be ≥ 1, got {save_every}")
    save_every = None if save_every is None else int(save_every)
    C = int(chunk_particles)
    if C < 1:
        raise ValueError(f"chunk_particles must be ≥ 1, got {chunk_particles}")
    seg = n_steps if checkpoint_every is None else int(checkpoint_every)
    if seg < 1 and n_steps:
        raise ValueError(f"checkpoint_every must be ≥ 1, got {checkpoint_every}")
    if save_every is not None:
        seg = -(-max(seg, 1) // save_every) * save_every
    seg = max(seg, 1)
    spec_text = json.dumps(method.spec(), sort_keys=True)  # SpecError: the method cannot be shipped
    N = pts.shape[0]
    steps = _global_steps(n_steps, save_every)
    attrs = {"spec": spec_text, "method": getattr(method, "name", repr(method)), "h": h, "t0": float(t0),
             "n_steps": n_steps, "save_every": -1 if save_every is None else save_every,
             "x0_sha256": hashlib.sha256(np.ascontiguousarray(pts).tobytes()).hexdigest(),
             "n_particles": N, "chunk_particles": C, "single": 0}
    _io.create_store(store, n_particles=N, steps=steps, ts=t0 + h * steps.astype(float), chunk=C,
                     attrs=attrs, resume=resume)
    chunks = [(c, c * C, pts[c * C:(c + 1) * C]) for c in range(-(-N // C))]
    todo = [ch for ch in chunks if not _io.is_done(store, ch[0])]
    show = progress is True or (progress == "auto" and sys.stderr.isatty())
    store = os.fspath(store)
    args = (h, n_steps, save_every, float(t0), seg, backend)
    t_wall = time.perf_counter()
    if client is None:
        _IN_PROCESS.clear()
        _IN_PROCESS[spec_text] = method
        for k, (c, lo, x) in enumerate(todo):
            run_chunk(spec_text, store, c, lo, x, *args)
            if show:
                print(f"vpforms: chunk {k + 1}/{len(todo)} done", file=sys.stderr)
    else:
        from dask.distributed import as_completed

        cl, owned = _client(client, workers)
        try:
            futs = [cl.submit(run_chunk, spec_text, store, c, lo, x, *args, pure=False, retries=retries,
                              key=f"vpforms-chunk-{c}-{attrs['x0_sha256'][:8]}-{time.time_ns()}")
                    for (c, lo, x) in todo]
            for k, f in enumerate(as_completed(futs)):
                f.result()
                if show:
                    print(f"vpforms: chunk {k + 1}/{len(todo)} done", file=sys.stderr)
        finally:
            if owned:
                cluster = getattr(cl, "cluster", None)
                cl.close()
                if cluster is not None:
                    cluster.close()
    missing = [c for c, _, _ in chunks if not _io.is_done(store, c)]
    if missing:  # pragma: no cover — every task either finished or raised above
        raise RuntimeError(f"chunks {missing[:10]} of {store!r} did not complete")
    ds = _io.open_store(store)
    ds.attrs["wall_s"] = time.perf_counter() - t_wall
    return ds

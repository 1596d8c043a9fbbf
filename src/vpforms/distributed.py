"""Chunked, resumable, verified, optionally Dask-distributed particle runs into a Zarr store (issues #10, #22).

``run(method, x0, h, n_steps, store=…)`` splits the N particles into chunks of
``chunk_particles``; each chunk is one task that rebuilds the method from its JSON spec (cached
per worker process: no pickled jitted functions travel, and the native kernel is compiled once per
worker), runs :func:`vpforms.integrate` on its particles segment by segment (``checkpoint_every``
steps per segment, a checkpoint after each), writes its rows straight into the store and THEN
marks itself done with the checksums of what it wrote (read back).

* ``client=None``: in this process, chunk after chunk; ``"local"``: a
  ``dask.distributed.LocalCluster`` of ``workers`` processes with 1 thread each; ``"tcp://…"``:
  connect to a scheduler; or a ``dask.distributed.Client``.
* backend: chosen once by the client (``"auto"``: native where it can run, else JAX), recorded in
  the store and run by every chunk; the native kernel and JAX agree only to rounding, so a store
  is written by one backend.
* resume: a store whose spec, h, n_steps, t0, save_every, chunking, x0 hash and backend match is
  continued; any mismatch is a :class:`~vpforms.io.StoreMismatchError` that prints both values,
  never a mixed store.  Every done marker is verified against the data first
  (:func:`vpforms.io.verify_chunk`): a chunk whose arrays are missing, truncated or corrupt is run
  again (``chunks_report`` says which and why); a chunk an earlier attempt began continues its
  checkpoint, unless the states already written differ from those the checkpoint was taken after.
* a killed worker: Dask re-runs its task elsewhere (``retries``); a chunk is written whole by one
  task, so a re-run overwrites, never duplicates.
* on completion the whole store is verified (:func:`vpforms.io.verify_store`: every chunk against
  its marker, no non-finite particle without a failure status) and the recovered steps by
  alternative are recorded (attr ``recovered_how``).

Bitwise reproducibility: a particle's trajectory depends only on its own state (the kernel is
vmapped per particle), so chunking and segmenting reproduce a single ``integrate`` bit for bit
(tested), and an interrupted, damaged or distributed run leaves a store whose every file equals
an uninterrupted single-process run's.  Failed particles stay frozen across segments, as in one
``integrate`` call.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from typing import Any

import numpy as np

from . import _dask, _integrate
from . import io as _io
from ._integrate import _check_run
from ._solution import saved_steps as _global_steps
from .backends import select_backend
from .fieldlines._wall_chunks import trace_to_wall_chunks

__all__ = ["run", "run_chunk", "trace_to_wall"]


def _method(spec_text: str):
    """The method of a spec, built once per process (compilation cached with it); in the
    caller's process the caller's own method object (already compiled): :func:`vpforms._dask.method_of`."""
    return _dask.method_of((spec_text, spec_text, None, ""))


def _load_checkpoint(store: str, c: int, lo: int, hi: int):
    """(state, None) of chunk c's checkpoint, or (None, why it cannot be continued): none, an
    unreadable file, or saved states in the store that differ from those it was taken after."""
    ck = _io.ckpt_path(store, c)
    if not os.path.exists(ck):
        return None, None
    try:
        with np.load(ck) as z:
            state = {k: z[k] for k in ("x", "status", "failed", "recovered")}
            n_done, t_written, sha = int(z["n_done"]), int(z["t_written"]), str(z["x_sha256"])
            state["how"] = json.loads(str(z["how"]))
        x_sha = _io.states_digest(store, lo, hi, t_written)
    except Exception as err:  # noqa: BLE001 — a truncated or garbled checkpoint or chunk file
        return None, f"checkpoint unreadable ({type(err).__name__})"
    if x_sha != sha:
        return None, "the states the checkpoint continues differ from those it was taken after"
    return {**state, "n_done": n_done, "t_written": t_written}, None


def run_chunk(spec_text: str, store: str, c: int, lo: int, x0: np.ndarray, h: float, n_steps: int,
              save_every: int | None, t0: float, segment: int, backend: str = "auto") -> dict:
    """Run chunk ``c`` (particles lo … lo + len(x0)) into ``store``; the unit of work of a task.

    Continues the chunk's checkpoint when the states already in the store are those it was taken
    after (else starts over, removing what an earlier attempt left); ends with the done marker
    (:func:`vpforms.io.mark_done`: the data's checksums, read back).  Returns what it did:
    ``from_step`` (0 = from the start), ``restarted`` (an earlier attempt had begun this chunk),
    ``discarded`` (why a checkpoint was not continued), ``backend`` (the one that ran).
    """
    if _io.is_done(store, c):  # a retry of a task whose earlier attempt finished (the client verified)
        return {"chunk": c, "skipped": True, "wall_s": 0.0}
    t_start = time.perf_counter()
    method = _method(spec_text)
    n = x0.shape[0]
    hi = lo + n
    gsteps = _global_steps(n_steps, save_every)
    ck, started = _io.ckpt_path(store, c), _io.started_path(store, c)
    restarted = os.path.exists(started)
    if not restarted:
        open(started, "w").close()
    state, discarded = _load_checkpoint(store, c, lo, hi)
    if state is None:
        if os.path.exists(ck):
            os.remove(ck)
        restarted = _io.reset_chunk(store, c) or restarted  # never merge into an earlier attempt's data
        x, status, failed, n_done = x0.copy(), np.zeros(n, np.int32), np.full(n, -1, np.int64), 0
        recovered = np.zeros(n, np.int64)  # steps recovered per particle (issue #12), as Solution.recovered
        how: dict[str, int] = {}  # … and by alternative, as Solution.stats["recovered_how"]
        t_written = 0
    else:
        x, status, failed, n_done = state["x"], state["status"], state["failed"], state["n_done"]
        recovered, how, t_written = state["recovered"], state["how"], state["t_written"]
    from_step, ran = n_done, backend
    first = None if n_done else x0[:, None, :]  # x0 goes out with the first segment (one write)
    while n_done < n_steps:
        m = min(segment, n_steps - n_done)
        sol = _integrate.integrate(method, x, h, m, save_every=save_every, t0=t0 + h * n_done,
                        chunk_size=n, progress=False, backend=backend)
        ran = sol.stats["backend"]
        alive = status == 0
        xs = np.array(sol.xs)
        xs[~alive] = x[~alive, None, :]  # a failed particle stays frozen (as in one integrate)
        newly = alive & (sol.status != 0)
        status = np.where(newly, sol.status, status).astype(np.int32)
        failed = np.where(newly, sol.failed_step + n_done, failed).astype(np.int64)
        if sol.recovered is not None:  # a frozen particle takes no step, so it recovers none
            recovered = recovered + np.where(alive, sol.recovered, 0).astype(np.int64)
        for k, v in sol.stats.get("recovered_how", {}).items():  # a frozen particle fails its step
            how[k] = how.get(k, 0) + int(v)                         # again, unrecovered: exact
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
            t_written = t_lo + out.shape[1]
        elif last:
            _io.write_chunk(store, lo, hi, status=status, failed=failed, recovered=recovered)
        if n_done < n_steps:  # checkpoint: the state at step n_done (atomic replace)
            x_sha = _io.states_digest(store, lo, hi, t_written)
            tmp = ck + f".{os.getpid()}.tmp.npz"
            np.savez(tmp, x=x, status=status, failed=failed, recovered=recovered, n_done=n_done,
                     t_written=t_written, x_sha256=x_sha, how=json.dumps(how, sort_keys=True))
            os.replace(tmp, ck)
    if n_steps == 0:
        _io.write_chunk(store, lo, hi, x=x0[:, None, :], status=status, failed=failed, recovered=recovered)
    # after the data, with their checksums read back: a half-written chunk is never read as done
    _io.mark_done(store, c, {"particles": [lo, hi], "backend": ran, "recovered_how": dict(sorted(how.items())),
                             "arrays": _io.chunk_digest(store, lo, hi)})
    for f in (ck, started):
        if os.path.exists(f):
            os.remove(f)
    return {"chunk": c, "skipped": False, "wall_s": time.perf_counter() - t_start, "particles": n,
            "backend": ran, "from_step": from_step, "restarted": restarted, "discarded": discarded}


def _choose_backend(method: Any, backend: str | None, store: str, resume: bool) -> tuple[str, str]:
    """(backend, why) of a store run: ``backend`` as :func:`vpforms.integrate` chooses it, except
    that ``"auto"`` continues a resumed store with the backend that wrote it (their last bits
    differ: one store, one backend)."""
    backend = "auto" if backend is None else backend
    old = _io.store_attrs(store) if resume else None
    if backend == "auto" and old is not None and old.get("backend") in ("jax", "native"):
        name, _ = select_backend(method, old["backend"])  # NativeUnavailableError: says why
        return name, f"auto: the backend that wrote {os.fspath(store)!r}"
    return select_backend(method, backend)


def _report(kept: int, redone: dict[int, str], results: list[dict]) -> str:
    """What a store run did with its chunks, in one line (the CLI prints it): kept (verified),
    run, redone because they failed verification or because an earlier attempt did not finish,
    and finished by an attempt whose result never came back (a worker killed after its marker)."""
    ran = [r for r in results if not r.get("skipped")]
    restarted = sorted((r for r in ran if r["restarted"] and r["chunk"] not in redone), key=lambda r: r["chunk"])
    fresh = len(ran) - len(restarted) - len(set(redone) & {r["chunk"] for r in ran})
    parts = [f"{kept} kept (verified)"] if kept else []
    if fresh:
        parts.append(f"{fresh} run")
    if redone:
        parts.append(f"{len(redone)} redone: failed verification ({_io.describe_bad(redone)})")
    if restarted:
        where = ", ".join(f"{r['chunk']} from step {r['from_step']}" if r["from_step"] else
                          f"{r['chunk']} from the start" for r in restarted[:5])
        more = f", and {len(restarted) - 5} more" if len(restarted) > 5 else ""
        parts.append(f"{len(restarted)} redone: an earlier attempt did not finish (chunk {where}{more})")
    skipped = sorted(r["chunk"] for r in results if r.get("skipped"))
    if skipped:  # an attempt finished the chunk (its marker is written) but its result was lost,
        # e.g. its worker died after the marker: the retry found it done; verify_store checks it
        parts.append(f"{len(skipped)} finished by an earlier attempt that did not report "
                     f"(chunk {', '.join(map(str, skipped[:5]))}{', …' if len(skipped) > 5 else ''}; "
                     "kept after verification)")
    discarded = [r for r in ran if r.get("discarded")]
    if discarded:
        parts.append(f"{len(discarded)} checkpoint(s) not continued (chunk {discarded[0]['chunk']}: "
                     f"{discarded[0]['discarded']})")
    return "; ".join(parts) or "nothing to run"


def run(method: Any, x0: Any, h: float, n_steps: int, *, store: str, save_every: int | None = None,
        t0: float = 0.0, chunk_particles: int = 65536, client: Any = None, workers: int | None = None,
        checkpoint_every: int | None = None, resume: bool = True, progress: bool | str = "auto",
        backend: str | None = "auto", retries: int = 3):
    """Run the particles x0 (N, 3) with ``method`` into the Zarr ``store``; return the xarray Dataset.

    ``checkpoint_every`` (steps, rounded up to a multiple of ``save_every``; None = no checkpoints)
    is the segment length after which each chunk saves its state.  ``backend`` is
    :func:`vpforms.integrate`'s (``"auto"``: native where it can run — every worker then runs the
    compiled kernel, built once per worker process — else JAX); the choice is made once, here,
    recorded in the store, and every chunk runs it (a resumed store keeps its backend).

    Resume verifies every done marker against the data before trusting it (a chunk whose arrays
    are missing, truncated or changed is run again), and a finished run is verified whole
    (:func:`vpforms.io.verify_store`; :class:`vpforms.io.StoreVerificationError` if it fails).
    The returned Dataset's attrs add ``wall_s``, ``backend_reason``, ``redone`` ({chunk: why it
    failed verification}) and ``chunks_report`` (one line: chunks kept, run, redone and why).
    See the module docstring.
    """
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
    store = os.fspath(store)
    backend, backend_reason = _choose_backend(method, backend, store, resume)
    N = pts.shape[0]
    steps = _global_steps(n_steps, save_every)
    attrs = {"spec": spec_text, "method": getattr(method, "name", repr(method)), "h": h, "t0": float(t0),
             "n_steps": n_steps, "save_every": -1 if save_every is None else save_every,
             "x0_sha256": hashlib.sha256(np.ascontiguousarray(pts).tobytes()).hexdigest(),
             "n_particles": N, "chunk_particles": C, "single": 0, "backend": backend,
             "store_format": _io.STORE_FORMAT}
    resumed = _io.create_store(store, n_particles=N, steps=steps, ts=t0 + h * steps.astype(float), chunk=C,
                               attrs=attrs, resume=resume)
    chunks = [(c, c * C, pts[c * C:(c + 1) * C]) for c in range(-(-N // C))]
    todo, redone, kept = [], {}, 0
    if resumed:  # trust no marker unchecked: a chunk missing, truncated or changed is run again
        _io.remove_partial_files(store)
        for ch in chunks:
            c, lo, x = ch
            if _io.is_done(store, c):
                why = _io.verify_chunk(store, c, lo, lo + x.shape[0])
                if why is None:
                    kept += 1
                    for f in (_io.ckpt_path(store, c), _io.started_path(store, c)):  # a kill after the marker
                        if os.path.exists(f):
                            os.remove(f)
                    continue
                redone[c] = why
                _io.unmark_done(store, c)
            todo.append(ch)
    else:
        todo = chunks
    show = progress is True or (progress == "auto" and sys.stderr.isatty())
    if show and redone:
        print(f"vpforms: {len(redone)} chunk(s) of {store} failed verification and are run again: "
              f"{_io.describe_bad(redone)}", file=sys.stderr)
    args = (h, n_steps, save_every, float(t0), seg, backend)
    results = []
    t_wall = time.perf_counter()
    if client is None:
        _dask.IN_PROCESS.clear()
        _dask.IN_PROCESS[spec_text] = method
        for k, (c, lo, x) in enumerate(todo):
            results.append(run_chunk(spec_text, store, c, lo, x, *args))
            if show:
                print(f"vpforms: chunk {k + 1}/{len(todo)} done", file=sys.stderr)
    else:
        from dask.distributed import as_completed

        cl, owned = _dask.client(client, workers)
        try:
            futs = [cl.submit(run_chunk, spec_text, store, c, lo, x, *args, pure=False, retries=retries,
                              key=f"vpforms-chunk-{c}-{attrs['x0_sha256'][:8]}-{time.time_ns()}")
                    for (c, lo, x) in todo]
            for k, f in enumerate(as_completed(futs)):
                results.append(f.result())
                if show:
                    print(f"vpforms: chunk {k + 1}/{len(todo)} done", file=sys.stderr)
        finally:
            _dask.close(cl, owned)
    wall = time.perf_counter() - t_wall
    check = _io.verify_store(store)  # the final pass: every chunk against its marker, every NaN explained
    if check["bad"]:
        raise _io.StoreVerificationError(f"store {store!r} fails verification after the run: "
                                         f"{_io.describe_bad(check['bad'])}")
    _io.finish_store(store, {"recovered_how": json.dumps(check["recovered_how"], sort_keys=True)})
    ds = _io.open_store(store)
    ds.attrs.update(wall_s=wall, backend_reason=backend_reason, redone=redone,
                    chunks_report=_report(kept, redone, results))
    return ds



def trace_to_wall(method: Any, x0: Any, h: float, n_steps: int, wall: Any, *, t0: float = 0.0,
                  chunk_particles: int = 65536, client: Any = None, workers: int | None = None,
                  backend: str = "auto", retries: int = 3, progress: bool | str = "auto",
                  builder: Any = None):
    """:func:`vpforms.fieldlines.trace_to_wall` over chunks of ``chunk_particles`` lines, each a task
    (``client`` as for :func:`run`: None in this process, ``"local"``, ``"tcp://…"`` or a Client;
    also a worker count: that many local worker processes).

    The backend is chosen once, here (``"auto"``: the native wall kernel where it can run), and every
    chunk runs it; each worker rebuilds the method from its JSON spec (once per process) — or, for a
    method whose field has no spec (a spline of coils, a device's grid), calls ``builder``, a
    picklable zero-argument callable that builds the same method (checked on the worker by its
    description). A line's trace depends only on its own state, so the result equals one
    :func:`~vpforms.fieldlines.trace_to_wall` call of that backend: the same statuses, hits and
    exit steps, and natively the same numbers bit for bit (tested). On JAX the numbers agree to
    rounding: a JAX run re-traces all its lines with the recovering step when one of them needs
    recovery, and a chunk that needs none keeps the bare step, compiled apart (the last bit can
    differ). Returns the :class:`~vpforms.fieldlines.WallHits` of all the lines, in order
    (:func:`vpforms.fieldlines._wall_chunks.trace_to_wall_chunks`).
    """
    (hits,), _ = trace_to_wall_chunks(method, x0, [h], n_steps, wall, t0=t0, chunk_particles=chunk_particles,
                                      client=client, workers=workers, backend=backend, retries=retries,
                                      progress=progress, builder=builder)
    return hits

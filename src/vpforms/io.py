"""xarray / Zarr / netCDF output of particle runs (issue #10).

One layout everywhere (a :class:`Solution`, a netCDF file, a Zarr store written chunk by chunk):
an xarray Dataset with

* ``x(particle, time, coord)`` — saved states (float64), ``time`` = t0 + h·step, ``coord`` = 1..3;
* ``step(time)`` — saved step indices; ``status(particle)`` (``vpforms.RESULTS`` codes) and
  ``failed_step(particle)`` (−1 = never failed); ``recovered(particle)`` (steps that failed bare
  and were recovered, ``Solution.recovered``; always present in a store, whose every chunk runs
  through :func:`vpforms.integrate`);
* attrs: ``spec`` (the method's JSON spec, or "" when it has none), ``method``, ``h``, ``t0``,
  ``n_steps``, ``save_every`` (−1 = only the first and last state), ``version`` (vpforms),
  ``recovered_how`` (JSON: recovered steps by alternative, ``Solution.stats["recovered_how"]``).

A store run (:mod:`vpforms.distributed`) also records ``backend`` (``"native"`` or ``"jax"``: a
store is never written by both, their last bits differ) and ``store_format``.  Its bookkeeping
lives beside the data in ``<store>/.vpforms/``:

* ``done/<chunk>`` — the chunk's done marker, a JSON record written AFTER its data: the particle
  range, the backend that ran, its recovered steps by alternative, and the shape, dtype and
  SHA-256 of each array region it wrote (``x``, ``status``, ``failed_step``, ``recovered``), read
  back from the store.  :func:`verify_chunk` checks the data against it: a marker is trusted only
  when the data it describes are there, whole and unchanged;
* ``ckpt/<chunk>.npz`` — a checkpoint (the chunk's state after a segment, with the SHA-256 of the
  states already written, so that a checkpoint is never continued over damaged data) and
  ``ckpt/<chunk>.started`` (an attempt is under way: a later attempt says it redid the chunk).

Fill values say "never written", never a plausible value: x NaN, status −1, failed_step −2,
recovered −1.  The metadata are consolidated (``xarray.open_zarr(store)`` reads them in one go,
without warnings, and never lists the ``.vpforms`` folder).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import warnings
from typing import Any

import numpy as np

__all__ = [
    "StoreMismatchError",
    "StoreVerificationError",
    "check_metadata",
    "create_store",
    "finish_store",
    "is_done",
    "mark_done",
    "open_store",
    "reset_chunk",
    "solution_to_netcdf",
    "solution_to_xarray",
    "store_attrs",
    "unmark_done",
    "verify_chunk",
    "verify_store",
    "write_chunk",
]

from ._errors import RESULTS, VPFormsError
from ._steps import saved_steps
from ._version import __version__


class StoreMismatchError(VPFormsError, ValueError):
    """A store holds a different run (spec, h, n_steps, t0, save_every, x0, chunking or backend):
    never mixed."""


class StoreVerificationError(VPFormsError, RuntimeError):
    """A store's data do not match its done markers, or a particle is non-finite without a failure
    status (:func:`verify_store`)."""


def _version() -> str:
    return __version__


def _spec_text(method: Any) -> str:
    if method is None or not hasattr(method, "spec"):
        return ""
    try:
        return json.dumps(method.spec(), sort_keys=True)
    except VPFormsError:
        return ""


def solution_to_xarray(sol: Any, method: Any = None):
    """The :class:`vpforms.Solution` as an ``xarray.Dataset`` (layout in the module docstring)."""
    import xarray as xr

    xs = np.asarray(sol.xs)
    single = xs.ndim == 2
    xs = xs[None] if single else xs
    data = {
        "x": (("particle", "time", "coord"), xs),
        "status": (("particle",), np.atleast_1d(np.asarray(sol.status, np.int32))),
        "failed_step": (("particle",), np.atleast_1d(np.asarray(sol.failed_step, np.int64))),
    }
    rec = getattr(sol, "recovered", None)
    if rec is not None:
        data["recovered"] = (("particle",), np.atleast_1d(np.asarray(rec)))
    attrs = {
        "spec": _spec_text(method), "method": str(sol.method), "h": float(sol.h), "t0": float(sol.t0),
        "n_steps": int(sol.n_steps), "save_every": -1 if sol.save_every is None else int(sol.save_every),
        "single": int(single), "version": _version(),
        "recovered_how": json.dumps((getattr(sol, "stats", None) or {}).get("recovered_how", {}), sort_keys=True),
    }
    return xr.Dataset(
        data,
        coords={"time": np.asarray(sol.ts, np.float64), "step": ("time", np.asarray(sol.steps, np.int64)),
                "coord": np.arange(1, 4)},
        attrs=attrs,
    )


def solution_to_netcdf(sol: Any, path: str, method: Any = None) -> None:
    """Write :func:`solution_to_xarray` to a netCDF file (h5netcdf engine, else netCDF4/scipy)."""
    ds = solution_to_xarray(sol, method)
    try:
        ds.to_netcdf(path, engine="h5netcdf")
    except (ImportError, ValueError):
        ds.to_netcdf(path)


# ---------------------------------------------------------------------------------------------
# chunked stores
# ---------------------------------------------------------------------------------------------
#: The layout of a store run; a store of another format is refused on resume (--no-resume rewrites it).
STORE_FORMAT = 2

#: The per-particle arrays a chunk writes, with their dtype and "never written" fill value.
CHUNK_ARRAYS = {"x": ("f8", np.nan), "status": ("i4", -1), "failed_step": ("i8", -2), "recovered": ("i8", -1)}

#: The attributes that identify a run: a store resumes only when all of them agree.
RUN_KEYS = ("spec", "h", "t0", "n_steps", "save_every", "x0_sha256", "n_particles", "chunk_particles",
            "backend", "store_format")


def _meta_dir(store: str, *parts: str) -> str:
    return os.path.join(os.fspath(store), ".vpforms", *parts)


@contextlib.contextmanager
def _quiet():
    """Without zarr's notes about the bookkeeping folder .vpforms (not a Zarr node) and about
    consolidated metadata being a zarr-python extension of format 3."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*not recognized as a component of a Zarr")
        warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata is currently not part")
        yield


def _group(path: str, mode: str):
    """zarr.open_group (consolidated metadata when the store has them), without the notes of _quiet."""
    import zarr

    with _quiet():
        return zarr.open_group(os.fspath(path), mode=mode)


def _consolidate(path: str) -> None:
    import zarr

    with _quiet():
        zarr.consolidate_metadata(os.fspath(path))


def _read_meta(path: str) -> dict:
    """A store's metadata file (a ``zarr.json``) as a JSON object; :class:`StoreVerificationError`
    naming the file when it is not one (binary garbage, truncated or invalid JSON)."""
    try:
        with open(path, "rb") as fh:
            meta = json.loads(fh.read().decode("utf-8"))
    except UnicodeDecodeError as err:
        raise StoreVerificationError(f"store metadata {path!r} is damaged: not text (byte "
                                     f"{err.object[err.start]:#04x} at offset {err.start})") from None
    except json.JSONDecodeError as err:
        raise StoreVerificationError(f"store metadata {path!r} is damaged: not valid JSON ({err.msg} at "
                                     f"line {err.lineno}, column {err.colno})") from None
    if not isinstance(meta, dict):
        raise StoreVerificationError(f"store metadata {path!r} is damaged: a JSON {type(meta).__name__}, "
                                     "not an object")
    return meta


def check_metadata(store: str) -> None:
    """Every metadata file of the store is a JSON object, and each array's ``<name>/zarr.json`` is
    the copy consolidated in the root ``zarr.json`` (Zarr reads that copy, so a damaged array file
    would otherwise pass); :class:`StoreVerificationError` naming the first damaged file."""
    path = os.fspath(store)
    root = _read_meta(os.path.join(path, "zarr.json"))
    consolidated = (root.get("consolidated_metadata") or {}).get("metadata") or {}
    names = sorted(set(consolidated) | {d for d in os.listdir(path) if not d.startswith(".")
                                        and os.path.isfile(os.path.join(path, d, "zarr.json"))})
    for name in names:
        file = os.path.join(path, name, "zarr.json")
        if not os.path.isfile(file):
            raise StoreVerificationError(f"store metadata {file!r} is missing (the root zarr.json lists {name!r})")
        meta = _read_meta(file)
        if consolidated and meta != consolidated.get(name):
            raise StoreVerificationError(f"store metadata {file!r} differs from its copy consolidated in "
                                         f"{os.path.join(path, 'zarr.json')!r}")


def open_store(store: str):
    """The store as a lazy xarray Dataset (consolidated metadata: no listing, no warnings)."""
    import xarray as xr

    path = os.fspath(store)
    consolidated = "consolidated_metadata" in _read_meta(os.path.join(path, "zarr.json"))
    with _quiet():
        return xr.open_zarr(path, consolidated=consolidated)


def store_attrs(store: str) -> dict | None:
    """The run attributes of an existing store (None when there is no store at that path)."""
    meta = os.path.join(os.fspath(store), "zarr.json")
    if not os.path.exists(meta):
        return None
    return _read_meta(meta).get("attributes", {})


def _shown(key: str, value: Any, attrs: dict) -> str:
    """A run attribute as a refusal prints it: short hashes, the method's name for a spec."""
    if value is None:
        return "none"
    if key == "spec":
        return f"{attrs.get('method', '?')} (spec sha256 {hashlib.sha256(str(value).encode()).hexdigest()[:12]})"
    if key == "x0_sha256":
        return f"sha256 {str(value)[:12]}"
    return repr(value) if isinstance(value, str) else f"{value}"


def create_store(store: str, *, n_particles: int, steps: np.ndarray, ts: np.ndarray, chunk: int,
                 attrs: dict, resume: bool) -> bool:
    """Create the store's arrays, or check an existing one against ``attrs``.

    Returns True when an existing store with identical run parameters (:data:`RUN_KEYS`) is being
    resumed; a store of another run is a :class:`StoreMismatchError` that prints both values of
    every attribute that differs.
    """
    path = os.fspath(store)
    old = store_attrs(path) if resume else None
    if old is not None:
        old = {"store_format": 1, **old}  # stores before verified markers had no store_format
        diff = [k for k in RUN_KEYS if old.get(k) != attrs.get(k)]
        if diff:
            shown = "; ".join(f"{k}: store {_shown(k, old.get(k), old)}, this run {_shown(k, attrs.get(k), attrs)}"
                              for k in diff)
            raise StoreMismatchError(
                f"store {path!r} holds a different run ({shown}); refusing to mix runs: "
                "use another --out, or resume=False (--no-resume) to overwrite it"
            )
        return True
    if os.path.exists(path):
        shutil.rmtree(path)
    g = _group(path, "w")
    N, S = int(n_particles), int(steps.size)
    c = max(1, min(int(chunk), N)) if N else 1
    for name, (dtype, fill) in CHUNK_ARRAYS.items():
        shape, chunks, dims = ((N, S, 3), (c, S, 3), ["particle", "time", "coord"]) if name == "x" else \
            ((N,), (c,), ["particle"])
        g.create_array(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill, dimension_names=dims,
                       **({"compressors": None} if name == "x" else {}))
    t = g.create_array("time", shape=(S,), chunks=(S,), dtype="f8", dimension_names=["time"])
    t[:] = ts
    st = g.create_array("step", shape=(S,), chunks=(S,), dtype="i8", dimension_names=["time"])
    st[:] = steps
    co = g.create_array("coord", shape=(3,), chunks=(3,), dtype="i8", dimension_names=["coord"])
    co[:] = np.arange(1, 4)
    g.attrs.update({**attrs, "version": _version()})
    _consolidate(path)
    os.makedirs(_meta_dir(path, "done"), exist_ok=True)
    os.makedirs(_meta_dir(path, "ckpt"), exist_ok=True)
    return False


def write_chunk(store: str, lo: int, hi: int, *, x=None, t_lo: int = 0, status=None, failed=None,
                recovered=None) -> None:
    """Write particles [lo, hi) (x: their saved states from time index ``t_lo``) into the store."""
    g = _group(store, "r+")
    if x is not None:
        g["x"][lo:hi, t_lo:t_lo + x.shape[1]] = x
    if status is not None:
        g["status"][lo:hi] = status
    if failed is not None:
        g["failed_step"][lo:hi] = failed
    if recovered is not None:
        g["recovered"][lo:hi] = recovered


def _chunk_files(g, path: str, chunk: int) -> list[str]:
    """The files that hold store chunk ``chunk`` of each per-particle array (local stores)."""
    out = []
    for name in CHUNK_ARRAYS:
        a = g[name]
        key = a.metadata.encode_chunk_key((chunk,) + (0,) * (a.ndim - 1))
        out.append(os.path.join(path, name, *key.split("/")))
    return out


def reset_chunk(store: str, chunk: int) -> bool:
    """Remove whatever an earlier attempt left of chunk ``chunk`` (its data files, whole or damaged),
    so that a fresh attempt never merges into them; True when there was something to remove."""
    path = os.fspath(store)
    found = False
    for f in _chunk_files(_group(path, "r"), path, chunk):
        if os.path.exists(f):
            os.remove(f)
            found = True
    return found


def remove_partial_files(store: str) -> int:
    """Remove the temporary files (``*.partial``) of zarr writes that a killed process left behind."""
    n = 0
    for name in CHUNK_ARRAYS:
        for root, _dirs, files in os.walk(os.path.join(os.fspath(store), name)):
            for f in files:
                if f.endswith(".partial"):
                    os.remove(os.path.join(root, f))
                    n += 1
    return n


def digest(a: np.ndarray) -> dict:
    """Shape, dtype and SHA-256 of an array's bytes: what a done marker records of each region."""
    a = np.ascontiguousarray(a)
    return {"shape": list(a.shape), "dtype": a.dtype.str, "sha256": hashlib.sha256(a.tobytes()).hexdigest()}


def states_digest(store: str, lo: int, hi: int, t_hi: int) -> str:
    """SHA-256 of the saved states x[lo:hi, :t_hi] in the store (what a checkpoint continues)."""
    return digest(_group(store, "r")["x"][lo:hi, :t_hi])["sha256"]


def chunk_digest(store: str, lo: int, hi: int) -> dict:
    """The :func:`digest` of particles [lo, hi) of every per-particle array, read back from the store."""
    g = _group(store, "r")
    return {name: digest(g[name][lo:hi]) for name in CHUNK_ARRAYS}


def mark_done(store: str, chunk: int, record: dict) -> None:
    """Mark a chunk done (call only after its data is written): ``record`` (its particle range,
    backend, recovered steps and :func:`chunk_digest`) as JSON, by an atomic rename."""
    d = _meta_dir(store, "done")
    tmp = os.path.join(d, f".{chunk}.{os.getpid()}.tmp")
    with open(tmp, "w") as fh:
        json.dump({"store_format": STORE_FORMAT, "chunk": int(chunk), **record}, fh, sort_keys=True)
        fh.write("\n")
    os.replace(tmp, os.path.join(d, str(chunk)))


def unmark_done(store: str, chunk: int) -> None:
    """Withdraw a chunk's done marker (its data failed verification: the chunk is run again)."""
    try:
        os.remove(_meta_dir(store, "done", str(chunk)))
    except FileNotFoundError:
        pass


def is_done(store: str, chunk: int) -> bool:
    """Whether chunk ``chunk`` has a done marker (trusted only after :func:`verify_chunk`)."""
    return os.path.exists(_meta_dir(store, "done", str(chunk)))


def read_marker(store: str, chunk: int) -> dict | None:
    """A chunk's done record, or None when it has none or it is not a readable record."""
    try:
        with open(_meta_dir(store, "done", str(chunk))) as fh:
            rec = json.load(fh)
    except (OSError, ValueError):
        return None
    return rec if isinstance(rec, dict) else None


def ckpt_path(store: str, chunk: int) -> str:
    return _meta_dir(store, "ckpt", f"{chunk}.npz")


def started_path(store: str, chunk: int) -> str:
    return _meta_dir(store, "ckpt", f"{chunk}.started")


def unexplained_failures(x: np.ndarray, status: np.ndarray, failed: np.ndarray, recovered: np.ndarray,
                         lo: int = 0) -> str | None:
    """Why particles lo… do not tell their own story, or None: every status a ``RESULTS`` code (−1
    = never written), ``failed_step`` −1 exactly for the particles that succeeded, no negative
    recovered count, and no non-finite state unless the particle's status says why."""
    def first(mask, what):
        i = int(np.flatnonzero(mask)[0])
        return f"particle {lo + i}: {what(i)} ({int(mask.sum())} particle(s))"

    bad = ~np.isin(status, list(RESULTS.messages))
    if bad.any():
        return first(bad, lambda i: f"status {int(status[i])} is no result code"
                     + (" (never written)" if status[i] == -1 else ""))
    bad = (status == RESULTS.successful) != (failed == -1)
    if bad.any():
        return first(bad, lambda i: f"failed_step {int(failed[i])} with status {RESULTS.short[int(status[i])]!r}")
    bad = recovered < 0
    if bad.any():
        return first(bad, lambda i: f"recovered {int(recovered[i])}" + (" (never written)" if recovered[i] == -1 else ""))
    bad = (status == RESULTS.successful) & ~np.all(np.isfinite(x.reshape(x.shape[0], -1)), axis=1)
    if bad.any():
        return first(bad, lambda i: "a non-finite state with status 'succeeded'")
    return None


def verify_chunk(store: str, chunk: int, lo: int, hi: int) -> str | None:
    """None when chunk ``chunk`` (particles [lo, hi)) is done and its data are exactly what its
    marker recorded and tell their own story (:func:`unexplained_failures`); else why not, in a
    few words (no marker, an older marker without checksums, an array missing, truncated,
    unreadable or changed)."""
    return _check_chunk(_group(store, "r"), store, chunk, lo, hi)[0]


def _check_chunk(g, store: str, chunk: int, lo: int, hi: int) -> tuple[str | None, dict]:
    """(why not, the arrays read) of :func:`verify_chunk`."""
    rec = read_marker(store, chunk)
    if rec is None:
        return ("no done marker" if not is_done(store, chunk) else "an unreadable done marker"), {}
    if rec.get("store_format") != STORE_FORMAT or not isinstance(rec.get("arrays"), dict):
        return "a done marker without checksums", {}
    if rec.get("particles") != [int(lo), int(hi)]:
        return f"a done marker of particles {rec.get('particles')}", {}
    data = {}
    for name, file in zip(CHUNK_ARRAYS, _chunk_files(g, store, chunk)):
        if not os.path.exists(file):
            return f"{name} missing", data
        try:
            data[name] = g[name][lo:hi]
        except Exception as err:  # noqa: BLE001 — a truncated or garbled chunk file, in any codec
            return f"{name} unreadable ({type(err).__name__})", data
        want, got = rec["arrays"].get(name, {}), digest(data[name])
        for field in ("shape", "dtype", "sha256"):
            if want.get(field) != got[field]:
                return f"{name} {'checksum' if field == 'sha256' else field} differs", data
    return unexplained_failures(data["x"], data["status"], data["failed_step"], data["recovered"], lo), data


def verify_store(store: str) -> dict:
    """Check a whole store: every chunk :func:`verify_chunk`, the coordinates (time, step, coord)
    those of the run's attributes.  Returns a report: ``bad`` ({chunk: why}; empty = verified),
    ``chunks``, ``particles``, ``failed`` (particles with a failure status), ``recovered_steps``,
    ``recovered_how`` (summed over the markers), ``backend``. A damaged metadata file (a root or
    array ``zarr.json`` that is not JSON, or an array's that differs from its consolidated copy)
    raises :class:`StoreVerificationError` naming it."""
    path = os.fspath(store)
    attrs = store_attrs(path)
    if attrs is None:
        raise StoreVerificationError(f"no store at {path!r} (no zarr.json)")
    if attrs.get("store_format") != STORE_FORMAT:
        raise StoreVerificationError(f"store {path!r} has format {attrs.get('store_format', 1)}, not "
                                     f"{STORE_FORMAT}: it has no checksums to verify (rewrite it with --no-resume)")
    check_metadata(path)  # a damaged zarr.json is named, never read past
    g = _group(path, "r")
    N, C = int(attrs["n_particles"]), int(attrs["chunk_particles"])
    bad: dict[int, str] = {}
    save_every = None if attrs["save_every"] == -1 else int(attrs["save_every"])
    steps = saved_steps(int(attrs["n_steps"]), save_every)
    coords = {"step": steps, "time": attrs["t0"] + attrs["h"] * steps.astype(float), "coord": np.arange(1, 4)}
    for name, want in coords.items():
        try:
            ok = np.array_equal(g[name][:], want)
        except Exception:  # noqa: BLE001
            ok = False
        if not ok:
            bad[-1] = f"the coordinate {name} differs from the run's"
    how: dict[str, int] = {}
    failed = recovered = 0
    for c in range(-(-N // C)):
        lo, hi = c * C, min((c + 1) * C, N)
        why, data = _check_chunk(g, path, c, lo, hi)
        if why is not None:
            bad[c] = why
            continue
        for k, v in read_marker(path, c).get("recovered_how", {}).items():
            how[k] = how.get(k, 0) + int(v)
        failed += int(np.count_nonzero(data["status"]))
        recovered += int(np.sum(data["recovered"]))
    return {"store": path, "bad": bad, "chunks": -(-N // C), "particles": N, "failed": failed,
            "recovered_steps": recovered, "recovered_how": dict(sorted(how.items())),
            "backend": attrs.get("backend")}


def describe_bad(bad: dict[int, str], limit: int = 3) -> str:
    """``{chunk: why}`` as one short line: "chunk 3: x checksum differs; chunk 7: …; and 4 more"."""
    items = [("coordinates" if c < 0 else f"chunk {c}") + f": {why}" for c, why in sorted(bad.items())]
    return "; ".join(items[:limit]) + (f"; and {len(items) - limit} more" if len(items) > limit else "")


def finish_store(store: str, attrs: dict) -> None:
    """Record the finished run's ``attrs`` (e.g. ``recovered_how``) and consolidate the metadata."""
    g = _group(store, "r+")
    g.attrs.update(attrs)
    _consolidate(store)

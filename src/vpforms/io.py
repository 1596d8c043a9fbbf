"""xarray / Zarr / netCDF output of particle runs (issue #10).

One layout everywhere (a :class:`Solution`, a netCDF file, a Zarr store written chunk by chunk):
an xarray Dataset with

* ``x(particle, time, coord)`` — saved states (float64), ``time`` = t0 + h·step, ``coord`` = 1..3;
* ``step(time)`` — saved step indices; ``status(particle)`` (``vpforms.RESULTS`` codes) and
  ``failed_step(particle)`` (−1 = never failed); ``recovered(particle)`` (steps that failed bare
  and were recovered, ``Solution.recovered``; always present in a store, whose every chunk runs
  through :func:`vpforms.integrate`);
* attrs: ``spec`` (the method's JSON spec, or "" when it has none), ``method``, ``h``, ``t0``,
  ``n_steps``, ``save_every`` (−1 = only the first and last state), ``version`` (vpforms).

A store run (:mod:`vpforms.distributed`) keeps its bookkeeping beside the data in
``<store>/.vpforms/``: ``done/<chunk>`` markers (written AFTER the chunk's data, so a half-written
chunk is never read as done) and ``ckpt/<chunk>.npz`` checkpoints.
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

__all__ = ["solution_to_xarray", "solution_to_netcdf", "create_store", "open_store",
           "write_chunk", "mark_done", "is_done", "StoreMismatchError"]

from ._errors import VPFormsError


class StoreMismatchError(VPFormsError, ValueError):
    """A store holds a different run (spec, h, n_steps, t0, save_every or x0): never mixed."""


def _version() -> str:
    from . import __version__

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
def _meta_dir(store: str, *parts: str) -> str:
    return os.path.join(os.fspath(store), ".vpforms", *parts)


def open_store(store: str):
    """The store as a lazy xarray Dataset (the bookkeeping folder .vpforms is not a Zarr node)."""
    import warnings

    import xarray as xr

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*not recognized as a component of a Zarr")
        return xr.open_zarr(os.fspath(store), consolidated=False)


def create_store(store: str, *, n_particles: int, steps: np.ndarray, ts: np.ndarray, chunk: int,
                 attrs: dict, resume: bool) -> bool:
    """Create the store's arrays, or check an existing one against ``attrs``.

    Returns True when an existing store with identical run parameters is being resumed.
    """
    import zarr

    path = os.fspath(store)
    if os.path.exists(os.path.join(path, "zarr.json")) and resume:
        old = json.load(open(os.path.join(path, "zarr.json")))["attributes"]
        keys = ("spec", "h", "t0", "n_steps", "save_every", "x0_sha256", "n_particles", "chunk_particles")
        diff = [k for k in keys if old.get(k) != attrs.get(k)]
        if diff:
            raise StoreMismatchError(
                f"store {path!r} holds a different run ({', '.join(diff)} differ); refusing to mix runs: "
                "use another --out, or resume=False (--no-resume) to overwrite it"
            )
        return True
    if os.path.exists(path):
        import shutil

        shutil.rmtree(path)
    g = zarr.open_group(path, mode="w", zarr_format=3)
    N, S = int(n_particles), int(steps.size)
    c = max(1, min(int(chunk), N)) if N else 1
    g.create_array("x", shape=(N, S, 3), chunks=(c, S, 3), dtype="f8", fill_value=np.nan, compressors=None,
                   dimension_names=["particle", "time", "coord"])
    g.create_array("status", shape=(N,), chunks=(c,), dtype="i4", fill_value=-1,
                   dimension_names=["particle"])
    g.create_array("failed_step", shape=(N,), chunks=(c,), dtype="i8", fill_value=-1,
                   dimension_names=["particle"])
    g.create_array("recovered", shape=(N,), chunks=(c,), dtype="i8", fill_value=0,
                   dimension_names=["particle"])
    t = g.create_array("time", shape=(S,), chunks=(S,), dtype="f8", dimension_names=["time"])
    t[:] = ts
    st = g.create_array("step", shape=(S,), chunks=(S,), dtype="i8", dimension_names=["time"])
    st[:] = steps
    co = g.create_array("coord", shape=(3,), chunks=(3,), dtype="i8", dimension_names=["coord"])
    co[:] = np.arange(1, 4)
    g.attrs.update({**attrs, "version": _version()})
    os.makedirs(_meta_dir(path, "done"), exist_ok=True)
    os.makedirs(_meta_dir(path, "ckpt"), exist_ok=True)
    return False


def _group(path: str, mode: str):
    """zarr.open_group without the warning about the bookkeeping folder .vpforms."""
    import warnings

    import zarr

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*not recognized as a component of a Zarr")
        return zarr.open_group(path, mode=mode)


def write_chunk(store: str, lo: int, hi: int, *, x=None, t_lo: int = 0, status=None, failed=None,
                recovered=None) -> None:
    """Write particles [lo, hi) (x: their saved states from time index ``t_lo``) into the store."""
    g = _group(os.fspath(store), "r+")
    if x is not None:
        g["x"][lo:hi, t_lo:t_lo + x.shape[1]] = x
    if status is not None:
        g["status"][lo:hi] = status
    if failed is not None:
        g["failed_step"][lo:hi] = failed
    if recovered is not None:
        g["recovered"][lo:hi] = recovered


def mark_done(store: str, chunk: int) -> None:
    """Mark a chunk done (call only after its data is written): an atomic rename of a small file."""
    d = _meta_dir(store, "done")
    tmp = os.path.join(d, f".{chunk}.{os.getpid()}.tmp")
    with open(tmp, "w") as fh:
        fh.write("done\n")
    os.replace(tmp, os.path.join(d, str(chunk)))


def is_done(store: str, chunk: int) -> bool:
    return os.path.exists(_meta_dir(store, "done", str(chunk)))


def ckpt_path(store: str, chunk: int) -> str:
    return _meta_dir(store, "ckpt", f"{chunk}.npz")

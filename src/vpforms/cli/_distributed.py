"""``vpforms run --out run.zarr``: the store-backed, resumable, verified, optionally distributed run
(issues #10, #22); ``vpforms verify run.zarr``: check a store against its done markers."""

from __future__ import annotations

import json
import os

import numpy as np

from .._spec import SpecError
from ..backends import NativeUnavailableError
from ..distributed import run
from ..io import StoreMismatchError, StoreVerificationError, describe_bad, verify_store
from ._common import CLIError, _positive_int, _summary_table


def add_args(p) -> None:
    """The options of a store run (used only when --out ends in .zarr)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS|local",
                   help="Dask scheduler (tcp://host:port) or 'local' (a LocalCluster); default: in process")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="worker processes of --scheduler local (default: CPU count)")
    p.add_argument("--resume", action="store_true", default=True,
                   help="continue a matching .zarr store (default): its chunks are verified against "
                        "their checksums first, and any missing, truncated or corrupt one is run again")
    p.add_argument("--no-resume", dest="resume", action="store_false", help="overwrite the .zarr store")
    p.add_argument("--chunk-particles", type=_positive_int, default=65536,
                   help="particles per task of a .zarr run (default 65536)")
    p.add_argument("--checkpoint-every", type=_positive_int, default=None,
                   help="steps between per-chunk checkpoints of a .zarr run (default: none)")


def _how(counts: dict) -> str:
    return ", ".join(f"{v} {k}" for k, v in counts.items())


def cmd_run_store(args, prob, method, x0, console) -> int:
    try:
        ds = run(method, x0, args.h, args.steps, store=args.out, save_every=args.save_every,
                 chunk_particles=args.chunk_particles, client=args.scheduler, workers=args.workers,
                 checkpoint_every=args.checkpoint_every, resume=args.resume, progress="auto",
                 backend=args.backend)
    except (StoreMismatchError, SpecError, NativeUnavailableError) as err:
        raise CLIError(str(err)) from None
    status = ds.status.values
    how = json.loads(ds.attrs.get("recovered_how", "{}"))
    rows = {
        "problem": prob.name, "method": ds.attrs["method"],
        "backend": f"{ds.attrs['backend']} ({ds.attrs['backend_reason']})",
        "particles": int(status.size),
        "h": args.h, "steps": args.steps, "t final": float(ds.time.values[-1]),
        "saved states per particle": int(ds.sizes["time"]),
        "failed particles": int(np.count_nonzero(status)),
        "recovered steps": f"{int(ds.recovered.values.sum())}" + (f" ({_how(how)})" if how else ""),
        "chunks": ds.attrs["chunks_report"],
        "verified": "every chunk against its checksums; no non-finite particle without a failure status",
        "scheduler": args.scheduler or "in process",
        "wall time (s)": round(float(ds.attrs["wall_s"]), 3),
    }
    console.print(_summary_table("vpforms run", rows))
    console.print(f"written: {args.out}", soft_wrap=True)
    return 0


def _cmd_verify(args, console) -> int:
    if not os.path.isdir(args.store):
        raise CLIError(f"no store at {args.store!r}")
    check = verify_store(args.store)  # StoreVerificationError (no store, an old format): exit 1
    if check["bad"]:
        raise StoreVerificationError(f"store {args.store!r} fails verification ({len(check['bad'])} of "
                                     f"{check['chunks']} chunk(s)): {describe_bad(check['bad'])}; "
                                     "`vpforms run` with the same arguments runs them again")
    console.print(_summary_table("vpforms verify", {
        "store": args.store, "backend": check["backend"], "particles": check["particles"],
        "chunks verified": f"{check['chunks']} (data equal to the checksums of their done markers)",
        "failed particles": check["failed"],
        "recovered steps": f"{check['recovered_steps']}" + (f" ({_how(check['recovered_how'])})"
                                                           if check["recovered_how"] else ""),
        "non-finite particles": "none without a failure status",
    }))
    return 0


def register(sub) -> None:
    """Add ``verify``."""
    p = sub.add_parser("verify", help="verify a .zarr store of `vpforms run`",
                       description="Check every chunk of a .zarr store written by `vpforms run` against the "
                                   "checksums of its done marker, and that no particle is non-finite unless "
                                   "its status says why. Exit 0 when verified; 1 (one line naming the chunks "
                                   "and arrays) when not: re-running the same `vpforms run` redoes them.")
    p.add_argument("store", help="the .zarr store")
    p.set_defaults(func=_cmd_verify)

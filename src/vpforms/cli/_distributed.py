"""``vpforms run --out run.zarr``: the store-backed, resumable, optionally distributed run (issue #10)."""

from __future__ import annotations

from ._common import CLIError, _positive_int, _summary_table


def add_args(p) -> None:
    """The options of a store run (used only when --out ends in .zarr)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS|local",
                   help="Dask scheduler (tcp://host:port) or 'local' (a LocalCluster); default: in process")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="worker processes of --scheduler local (default: CPU count)")
    p.add_argument("--resume", action="store_true", default=True,
                   help="continue a matching .zarr store (default)")
    p.add_argument("--no-resume", dest="resume", action="store_false", help="overwrite the .zarr store")
    p.add_argument("--chunk-particles", type=_positive_int, default=65536,
                   help="particles per task of a .zarr run (default 65536)")
    p.add_argument("--checkpoint-every", type=_positive_int, default=None,
                   help="steps between per-chunk checkpoints of a .zarr run (default: none)")


def cmd_run_store(args, prob, method, x0, console) -> int:
    import numpy as np

    from ..distributed import run
    from ..io import StoreMismatchError
    from .._spec import SpecError

    try:
        ds = run(method, x0, args.h, args.steps, store=args.out, save_every=args.save_every,
                 chunk_particles=args.chunk_particles, client=args.scheduler, workers=args.workers,
                 checkpoint_every=args.checkpoint_every, resume=args.resume, progress="auto")
    except (StoreMismatchError, SpecError) as err:
        raise CLIError(str(err)) from None
    status = ds.status.values
    rows = {
        "problem": prob.name, "method": ds.attrs["method"], "particles": int(status.size),
        "h": args.h, "steps": args.steps, "t final": float(ds.time.values[-1]),
        "saved states per particle": int(ds.sizes["time"]),
        "failed particles": int(np.count_nonzero(status)),
        "scheduler": args.scheduler or "in process",
        "wall time (s)": round(float(ds.attrs["wall_s"]), 3),
    }
    console.print(_summary_table("vpforms run", rows))
    console.print(f"written: {args.out}", soft_wrap=True)
    return 0

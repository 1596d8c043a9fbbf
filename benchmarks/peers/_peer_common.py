"""What the peer scripts share (numpy + scipy only: it runs in every tool's own virtual environment).

The driver ``benchmarks/peers/bench_peers.py`` writes ``problem.json`` (the coils file, the starting
points, the transits) into a work folder; each ``run_<tool>.py`` reads it, traces, and writes
``<tool>.json`` there: per run the section points (R, Z) at φ = 2πk/nfp, k = 1, 2, …, per line,
and the wall times. The driver compares them."""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np


def load_problem(argv=None) -> tuple[dict, str]:
    """(problem, work folder) from ``python run_<tool>.py WORKDIR``."""
    argv = sys.argv[1:] if argv is None else argv
    work = argv[0]
    with open(os.path.join(work, "problem.json")) as fh:
        return json.load(fh), work


def accuracy_transits(P: dict, tool: str) -> int:
    """The transits of ``tool``'s accuracy run: ``accuracy_transits``, unless the driver asked this
    tool for fewer (``accuracy_transits_by_tool``: a peer too slow for the full size)."""
    return int(P.get("accuracy_transits_by_tool", {}).get(tool, P["accuracy_transits"]))


def write_result(work: str, tool: str, result: dict) -> None:
    def conv(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.floating, np.integer)):
            return o.item()
        raise TypeError(type(o))

    result["loadavg_end"] = os.getloadavg()
    with open(os.path.join(work, f"{tool}.json"), "w") as fh:
        json.dump(result, fh, default=conv)


def read_makegrid(path: str) -> list[tuple[np.ndarray, float, int, str]]:
    """The coils of a MAKEGRID ``coils.*`` file: (points without the closing repeat, current, group, name)."""
    coils, cur, current = [], [], 0.0
    with open(path) as fh:
        for line in fh:
            s = line.split()
            if not s or s[0] in ("periods", "begin", "mirror", "end"):
                continue
            x = [float(v) for v in s[:4]]
            if len(s) == 4:
                cur.append(x[:3])
                current = x[3]
            else:  # closing point of a coil: x y z 0 group name
                coils.append((np.array(cur), current, int(s[4]), s[5] if len(s) > 5 else ""))
                cur = []
    return coils


def dop853_section(B_xyz, R0, Z0, nfp: int, n_sections: int, rtol: float = 1e-12, atol: float = 1e-13):
    """Reference section points: DOP853 in φ of dR/dφ = R B_R/B_φ, dZ/dφ = R B_Z/B_φ for all lines
    at once, with ``B_xyz`` a vectorised (n, 3) → (n, 3) Cartesian field; returns (R, Z) of shape
    (n_sections, n_lines) at φ = 2πk/nfp, k = 1 … n_sections."""
    from scipy.integrate import solve_ivp

    R0, Z0 = np.asarray(R0, float), np.asarray(Z0, float)

    def rhs(phi, s):
        R, Z = s[: len(R0)], s[len(R0):]
        c, sn = np.cos(phi), np.sin(phi)
        b = np.asarray(B_xyz(np.stack([R * c, R * sn, Z], -1)))
        BR, Bp = b[:, 0] * c + b[:, 1] * sn, -b[:, 0] * sn + b[:, 1] * c
        return np.concatenate([R * BR / Bp, R * b[:, 2] / Bp])

    phis = 2 * np.pi / nfp * np.arange(1, n_sections + 1)
    sol = solve_ivp(rhs, (0, phis[-1]), np.concatenate([R0, Z0]), method="DOP853", rtol=rtol, atol=atol,
                    t_eval=phis)
    if not sol.success:
        raise RuntimeError(f"reference failed: {sol.message}")
    return sol.y[: len(R0)].T, sol.y[len(R0):].T


def timed(fn):
    """(seconds, result) of one call."""
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out

"""Field lines traced natively until they leave a wall or a domain (``vp_wall``, :mod:`.codegen.walls`).

:func:`run_wall` advances points as :func:`.runner.run_points` does (the same steps, the same lazy
JAX recovery of failed steps) and stops each line at the first step whose new point is outside the
boundary (a polygon per φ: :mod:`vpforms.domains`), as :func:`vpforms.fieldlines.trace_to_wall`'s
JAX scan does: the line keeps x_n, its
status becomes ``left_domain``, and the step index n and the outside point X are kept for the exit
to be located afterwards. The connection length ∫|B| |dt| and the toroidal angle are accumulated
per line. A step recovered through JAX is given the same treatment here, by the caller's ``inside``
and ``speed``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .runner import CALLS, kernel_for, run_with_events

__all__ = ["WallRun", "WallTrace", "run_wall"]


def _cylindrical(x: np.ndarray, toroidal: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, φ, Z) of points (M, 3), as the kernel's ``vp_cyl``."""
    if toroidal:
        return np.sqrt(2.0 * x[:, 0]), x[:, 1], x[:, 2]
    return np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0]), x[:, 2]


class WallRun:
    """The per-line accumulators of one native wall trace, kept between kernel calls; ``advance`` and
    ``recovered`` are what :func:`vpforms.backends._advance.advance_with_recovery` calls on its ``events``."""

    def __init__(self, N: int, boundary: Any, tolm: float, toroidal: bool,
                 inside: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
                 speed: Callable[[np.ndarray], np.ndarray], h: float):
        self.h = float(h)
        self.pp, self.Rv, self.Zv = (np.ascontiguousarray(a, dtype=np.float64)
                                     for a in (boundary.phis, boundary.R, boundary.Z))
        self.period, self.vspeed = float(boundary.period), float(boundary.vertex_speed)
        self.tolm, self.toroidal = float(tolm), bool(toroidal)
        self.inside, self.speed = inside, speed
        self.s, self.phi, self.L, self.dphi, self.mg = (np.zeros(N) for _ in range(5))
        self.step = np.full(N, -1, np.int64)
        self.Xo = np.zeros((N, 3))
        self._init = True

    def advance(self, kernel, x, status, n, n_target, h) -> None:
        """One ``vp_wall`` call to n_target (the first call sets |B| and φ at the starting points)."""
        f = kernel._ffi

        def d(a):
            return f.cast("double *", a.ctypes.data)

        kernel.lib.lib.vp_wall(
            x.shape[0], d(x), f.cast("int32_t *", status.ctypes.data), f.cast("int64_t *", n.ctypes.data),
            int(n_target), float(h), int(self.toroidal), self.pp.size, d(self.pp), self.period, self.vspeed,
            self.Rv.shape[1], d(self.Rv), d(self.Zv), self.tolm,
            int(self._init), d(self.s), d(self.phi), d(self.L), d(self.dphi), d(self.mg),
            f.cast("int64_t *", self.step.ctypes.data), d(self.Xo), kernel._fd())
        self._init = False

    def stopped(self, idx: np.ndarray) -> np.ndarray:
        """Which of the lines ``idx`` the kernel stopped at the wall (not failures: never recovered)."""
        return self.step[idx] >= 0

    def recovered(self, idx: np.ndarray, n: np.ndarray, x: np.ndarray, X: np.ndarray) -> np.ndarray:
        """Steps n → n+1 of lines ``idx`` taken through JAX (from x to X): the lines they take out of
        the wall stop there (returned mask: the caller keeps them at x with status ``left_domain``);
        the others accumulate as the kernel does."""
        R, ph, Z = _cylindrical(X, self.toroidal)
        out = ~np.asarray(self.inside(R, ph, Z), bool)
        o, k = idx[out], idx[~out]
        self.step[o], self.Xo[o] = n[out], X[out]
        if k.size:
            sX = np.asarray(self.speed(X[~out]))
            d = ph[~out] - self.phi[k]
            if not self.toroidal:
                d = d - 2 * np.pi * np.floor((d + np.pi) / (2 * np.pi))
            self.L[k] += 0.5 * abs(self.h) * (self.s[k] + sX)
            self.dphi[k] += d
            self.phi[k], self.s[k] = ph[~out], sX
            self.mg[k] = 0.0  # the next step tests fully
        return out


@dataclass(frozen=True)
class WallTrace:
    """What :func:`run_wall` returns, per line: status, the exit step n (−1: none), the point x
    reached (x_n for a line that left), the outside point X = Ψ_h(x_n) of the exit step, |B| at x,
    ∫|B| |dt| and the toroidal angle accumulated to x, and the JAX-recovered steps (count, by kind)."""

    status: np.ndarray
    step: np.ndarray
    x: np.ndarray
    X_out: np.ndarray
    s: np.ndarray
    L: np.ndarray
    dphi: np.ndarray
    recovered: np.ndarray
    how: dict


def run_wall(method: Any, pts: np.ndarray, h: float, n_steps: int, boundary: Any,
             tolm: float, toroidal: bool, inside: Callable, speed: Callable,
             progress_cb: Callable[[int], Any] | None = None, calls: int = CALLS) -> WallTrace:
    """Advance points (N, 3) natively for at most n_steps steps of h, stopping each line where it
    leaves the ``boundary`` (a :class:`vpforms.domains.ToroidalDomain`: polygons on planes, linear in
    φ between them); ``tolm`` the margin under which the kernel tests a point fully;
    ``inside(R, φ, Z)`` and ``speed(X)`` the test and |B| for steps
    recovered through JAX. At most ``calls`` kernel calls (the progress bar's granularity)."""
    kernel = kernel_for(method, "auto", "wall")
    N = pts.shape[0]
    run = WallRun(N, boundary, tolm, toroidal, inside, speed, h)
    x, status, _, recovered, how = run_with_events(kernel, method, pts, h, n_steps, run, progress_cb, calls)
    if N and run._init:  # n_steps = 0: no call was made; |B| at the starting points still counts
        run.s[:] = np.asarray(speed(x))
    return WallTrace(status=status, step=run.step, x=x, X_out=run.Xo, s=run.s, L=run.L, dphi=run.dphi,
                     recovered=recovered, how=how)

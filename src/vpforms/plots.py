"""Figures with matplotlib (object API, Agg canvas: no display or pyplot state needed).

* :func:`poincare_figure` — a Poincaré section (thousands of small dots, coloured by orbit,
  angles in units of π when the section is periodic).
* :func:`order_figure` — error against step size on log–log axes with the fitted orders and
  reference slopes h¹, h², h⁴.
* :func:`drift_figure` — volume drift |log det D(Ψ_h^n)| (and invariant drift) against time on a
  log scale, one line per method (max and median over particles).

Each returns the :class:`matplotlib.figure.Figure` and writes a PNG when ``path`` is given.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["poincare_figure", "order_figure", "drift_figure", "fieldline_figure", "iota_figure", "save"]

_SUB = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")


def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save(fig, path: str | None) -> None:
    """Write ``fig`` as PNG to ``path`` (nothing when path is None)."""
    if path is not None:
        fig.savefig(path, dpi=fig.dpi)


def _pi_ticks(ax, which: str, period: float) -> None:
    """Ticks at multiples of period/4 labelled in units of π (for 2π-periodic angles)."""
    n = 4
    ticks = np.linspace(0.0, period, n + 1)
    if abs(period - 2 * math.pi) < 1e-12:
        labels = ["0", "π/2", "π", "3π/2", "2π"]
    else:
        labels = [f"{t:g}" for t in ticks]
    getattr(ax, f"set_{which}ticks")(ticks, labels)


def poincare_figure(section: Any, title: str | None = None, path: str | None = None, max_points: int = 200_000):
    """Scatter of a :class:`vpforms.diagnostics.PoincareSection`, coloured by orbit.

    Periodic sections are shown modulo the period on [0, P)², with π-labelled ticks and square
    aspect; the marker size shrinks with the number of points so that thousands stay readable.
    """
    fig = _figure(6.4, 6.4)
    ax = fig.add_subplot()
    uv = section.coordinates()
    pid = np.asarray(section.particle)
    if uv.shape[0] > max_points:
        keep = np.random.default_rng(0).choice(uv.shape[0], max_points, replace=False)
        uv, pid = uv[keep], pid[keep]
    M = uv.shape[0]
    # dot area (pt²) shrinks with the number of points: ~4 for 10³ points, ~1 for 10⁴, ≥ 0.3
    size = float(np.clip(4000.0 / max(M, 1), 0.3, 6.0))
    # a dark qualitative palette cycled over orbits: neighbouring orbits get different colours
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    colors = cmap(pid % 10) if M else None
    ax.scatter(uv[:, 0], uv[:, 1], s=size, c=colors, marker="o", linewidths=0, rasterized=True)
    a, b = section.plane_axes
    names = [f"x{i + 1}".translate(_SUB) for i in (a, b)]
    normal = f"x{section.axis + 1}".translate(_SUB)
    if section.period is not None:
        P = section.period
        unit = "rad, mod 2π" if abs(P - 2 * math.pi) < 1e-12 else f"mod {P:g}"
        ax.set_xlim(0.0, P)
        ax.set_ylim(0.0, P)
        _pi_ticks(ax, "x", P)
        _pi_ticks(ax, "y", P)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{names[0]} ({unit})")
        ax.set_ylabel(f"{names[1]} ({unit})")
        plane = f"{normal} = {section.value:g} (mod {'2π' if abs(P - 2 * math.pi) < 1e-12 else f'{P:g}'})"
    else:
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        plane = f"{normal} = {section.value:g}"
    way = {1: f"{normal} increasing", -1: f"{normal} decreasing", 0: "both directions"}[section.direction]
    n_orbits = int(np.count_nonzero(np.asarray(section.counts) > 0))
    n_total = int(np.asarray(section.counts).size)
    ax.set_title(
        (title + "\n" if title else "")
        + f"Poincaré section {plane}, {way}\n{M} crossings; {n_orbits} of {n_total} orbits crossed",
        fontsize=10,
    )
    ax.grid(True, lw=0.3, alpha=0.4)
    save(fig, path)
    return fig


def order_figure(
    fits: Mapping[str, Any],
    title: str | None = None,
    path: str | None = None,
    reference_orders: Sequence[int] = (1, 2, 4),
    error_label: str = "max error at T",
):
    """Log–log error against h for several methods (``name → OrderFit``), with reference slopes.

    Points used by the plateau-aware fit are filled, the others hollow; the legend gives the
    observed order.  Reference lines h^p are dashed grey, anchored at the largest h.
    """
    fig = _figure(6.4, 4.8)
    ax = fig.add_subplot()
    markers = "osD^v<>ph"
    all_h, all_e = [], []
    for i, (name, fit) in enumerate(fits.items()):
        hs, er, used = np.asarray(fit.hs), np.asarray(fit.errors), np.asarray(fit.used)
        good = np.isfinite(er) & (er > 0)
        (line,) = ax.loglog(hs[good], er[good], "-", lw=1.2, alpha=0.7)
        c = line.get_color()
        m = markers[i % len(markers)]
        ms = max(9.0 - 1.3 * i, 4.0)  # shrinking markers: coinciding curves stay visible
        z = 3 + i
        if str(name).strip().lower().startswith("rk"):  # a cross on top: RK4 coincides with order 4
            m, ms, z = "x", 9.0, 50
        ax.loglog(hs[good & used], er[good & used], m, color=c, ms=ms, zorder=z,
                  label=f"{name}: observed order {fit.order:.2f}")
        ax.loglog(hs[good & ~used], er[good & ~used], m, color=c, ms=ms, mfc="none", zorder=z)
        all_h.append(hs[good])
        all_e.append(er[good])
    if all_h:
        hcat, ecat = np.concatenate(all_h), np.concatenate(all_e)
        h0, h1 = hcat.min(), hcat.max()
        e_top = np.max(ecat)
        hh = np.array([h0, h1])
        for p in reference_orders:
            ref = e_top * 2.0 * (hh / h1) ** p
            ax.loglog(hh, ref, "--", color="0.55", lw=0.9)
            ax.annotate(f"h^{p}".replace("^1", "¹").replace("^2", "²").replace("^4", "⁴").replace("^6", "⁶"),
                        (h0, ref[0]), fontsize=9, color="0.35", ha="right", va="center",
                        xytext=(-3, 0), textcoords="offset points")
        ax.set_ylim(max(np.min(ecat) / 10, 1e-17), e_top * 30)
    ax.axhspan(1e-17, 1e-13, color="0.92", zorder=0)
    ax.set_xlabel("step size h")
    ax.set_ylabel(error_label)
    ax.set_title(title or "Convergence: error against step size", fontsize=10)
    ax.grid(True, which="both", lw=0.3, alpha=0.4)
    ax.legend(fontsize=8, loc="lower right")
    save(fig, path)
    return fig


def drift_figure(
    panels: Mapping[str, Mapping[str, tuple[Any, Any]]],
    title: str | None = None,
    path: str | None = None,
    floor: float = 1e-17,
):
    """Drift against time on a log scale, one panel per quantity.

    ``panels`` maps a panel title (e.g. "volume: |log det DΨⁿ|") to ``label → (ts, values)`` where
    values has shape (S,) or (N, S) (absolute drifts; the max and median over particles are drawn).
    Exact zeros are drawn at ``floor``; the band below 1e-13 marks rounding level.
    """
    n = max(len(panels), 1)
    fig = _figure(6.4, 3.4 * n)
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for ax, (ptitle, series) in zip(axes, panels.items()):
        for label, (ts, vals) in series.items():
            v = np.abs(np.asarray(vals, dtype=np.float64))
            v2 = v.reshape(-1, v.shape[-1])
            ts = np.asarray(ts)
            vmax = np.maximum(np.max(v2, axis=0), floor)
            (line,) = ax.semilogy(ts, vmax, lw=1.4, label=f"{label} (max over {v2.shape[0]})")
            if v2.shape[0] > 1:
                ax.semilogy(ts, np.maximum(np.median(v2, axis=0), floor), lw=1.0, ls="--",
                            color=line.get_color(), label=f"{label} (median)")
        ax.axhspan(floor, 1e-13, color="0.92", zorder=0)
        ax.text(0.01, 0.03, "rounding level", transform=ax.transAxes, fontsize=8, color="0.4")
        ax.set_ylim(bottom=floor)
        ax.set_title(ptitle, fontsize=10)
        ax.set_xlabel("time t")
        ax.set_ylabel("absolute drift")
        ax.grid(True, which="both", lw=0.3, alpha=0.4)
        ax.legend(fontsize=8, loc="best", framealpha=0.85)
    if title:
        fig.suptitle(title, fontsize=11)
    save(fig, path)
    return fig


def fieldline_figure(section: Any, axis: Any = None, fixed_points: Sequence[Any] = (), wall: Any = None,
                     title: str | None = None, path: str | None = None):
    """A toroidal Poincaré section in (R, Z) (:class:`~vpforms.fieldlines.ToroidalSection`), coloured
    by line, with the magnetic axis (×), island O-points (○) and X-points (✕), and the wall."""
    fig = _figure(6.0, 6.4)
    ax = fig.add_subplot(1, 1, 1)
    n = int(section.line.max()) + 1 if len(section) else 1
    size = float(np.clip(2e4 / max(len(section), 1), 0.6, 6.0))  # few points: bigger dots
    ax.scatter(section.R, section.Z, c=section.line, s=size, cmap="viridis", vmin=0, vmax=max(n - 1, 1),
               linewidths=0, rasterized=True)
    if wall is not None:
        ax.plot(wall.R, wall.Z, "k-", lw=1.0, label="wall")
    if axis is not None:
        ax.plot([axis.R], [axis.Z], "r+", ms=12, mew=2, label=f"axis (ι = {axis.iota:.6g})")
    for kind, marker in (("O", "o"), ("X", "x")):
        pts = [p for p in fixed_points if p.kind == kind]
        if pts:
            orbit = np.concatenate([p.orbit for p in pts])
            ax.plot(orbit[:, 0], orbit[:, 1], marker, color="C3", ms=7, mfc="none", mew=1.6,
                    label=f"{kind}-points (m = {pts[0].m})")
    ax.set_xlabel("R")
    ax.set_ylabel("Z")
    ax.set_aspect("equal", adjustable="datalim")
    if axis is not None or fixed_points or wall is not None:
        ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title or f"section φ = {section.phi0:.4g}", fontsize=10)
    save(fig, path)
    return fig


def iota_figure(iota: Any, title: str | None = None, path: str | None = None):
    """ι and q = 1/ι against the starting radius R (:class:`~vpforms.fieldlines.Iota`), with the
    Birkhoff error estimate as error bars."""
    fig = _figure(7.0, 4.2)
    a1 = fig.add_subplot(1, 2, 1)
    a2 = fig.add_subplot(1, 2, 2)
    ok = np.isfinite(iota.iota)
    a1.errorbar(iota.R0[ok], iota.iota[ok], yerr=iota.error[ok], fmt=".-", ms=4, lw=0.8)
    a1.set_xlabel("R (start, Z = axis)")
    a1.set_ylabel("ι")
    a2.plot(iota.R0[ok], iota.q[ok], ".-", ms=4, lw=0.8, color="C1")
    a2.set_xlabel("R (start, Z = axis)")
    a2.set_ylabel("q = 1/ι")
    fig.suptitle(title or "rotational transform (weighted Birkhoff average)", fontsize=10)
    save(fig, path)
    return fig

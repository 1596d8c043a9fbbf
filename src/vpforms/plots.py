"""Figures with matplotlib (object API, Agg canvas: no display or pyplot state needed).

* :func:`poincare_figure` — a Poincaré section (thousands of small dots, coloured by orbit,
  angles in units of π when the section is periodic).
* :func:`order_figure` — error against step size on log–log axes with the fitted orders and
  reference slopes h¹, h², h⁴.
* :func:`drift_figure` — volume drift |log det D(Ψ_h^n)| (and invariant drift) against time on a
  log scale, one line per method (max and median over particles).
* :func:`fieldline_figure` — a toroidal section in (R, Z) with units, the magnetic axis, island
  O- and X-points, the wall, a legend and a colour bar (issue #41 item 6).
* :func:`iota_figure` — the ι and q = 1/ι profiles against the starting radius, with the axis's ι.
* :func:`connection_length_figure` — a connection-length map: L_c of lines started on a section,
  on a log colour scale, the lines that did not reach the wall apart, the wall (issue #38 item 4).

Titles are wrapped to the figure's width, so that none runs off its edge.
Each returns the :class:`matplotlib.figure.Figure` and writes a PNG when ``path`` is given.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ._errors import RESULTS

__all__ = ["poincare_figure", "order_figure", "drift_figure", "fieldline_figure", "iota_figure",
           "connection_length_figure", "save"]

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


def _wrapped(fig, text: str, fontsize: float, share: float = 0.96) -> str:
    """``text`` broken (textwrap, at spaces) into lines that fit ``share`` of the figure's width:
    a character of a sans-serif font at ``fontsize`` pt is ≤ 0.6·fontsize pt wide on average
    (DejaVu Sans: 0.55 for digits and lower case), so a line holds width/(0.6·fontsize) of them.
    Existing line breaks are kept; "h = 0.05" is never split at its "=" (no-break spaces)."""
    width_pt = fig.get_figwidth() * 72.0 * share
    chars = max(int(width_pt / (0.6 * fontsize)), 12)
    text = str(text).replace(" = ", "\u00a0=\u00a0")
    return "\n".join(textwrap.fill(part, chars, break_on_hyphens=False) for part in text.split("\n"))


def _unit(label: str, units: str) -> str:
    """"R (m)", or "R" when the units are unknown ("")."""
    return f"{label} ({units})" if units else label


def _angle_text(phi0: float, nfp: int) -> str:
    """φ = 0, φ = 0.628 rad; with "(mod 2π/nfp)" for nfp > 1."""
    base = "φ = 0" if phi0 == 0 else f"φ = {phi0:.4g} rad"
    return base + (f" (mod 2π/{nfp})" if nfp > 1 else "")


def fieldline_figure(section: Any, axis: Any = None, fixed_points: Sequence[Any] = (), wall: Any = None,
                     title: str | None = None, path: str | None = None, *, units: str = "m",
                     color_by: Any = None, color_label: str | None = None):
    """A toroidal Poincaré section in (R, Z) (:class:`~vpforms.fieldlines.ToroidalSection`): the
    crossings coloured by line (a colour bar gives the line's index, or ``color_by``: one value per
    line, e.g. its starting R or connection length, named by ``color_label``), the magnetic axis
    (+), island O-points (○) and X-points (✕), and the wall; a legend names each.

    ``units``: of R and Z, "m" for coil and grid fields (the default), "" when unknown (the labels
    are then plain "R", "Z"). The title is wrapped to the figure's width (:func:`_wrapped`), so
    that it never runs off the edge; the legend sits below the axes, off the points."""
    import matplotlib
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import BoundaryNorm, Normalize
    from matplotlib.lines import Line2D

    fig = _figure(6.4, 7.4)
    ax = fig.add_subplot(1, 1, 1)
    n_pts = len(section)
    n_lines = int(np.asarray(section.status).size) or (int(section.line.max()) + 1 if n_pts else 1)
    size = float(np.clip(2e4 / max(n_pts, 1), 0.6, 8.0))  # few points: bigger dots
    line = np.asarray(section.line, dtype=np.int64)
    if color_by is not None:
        vals = np.asarray(color_by, dtype=np.float64).reshape(-1)
        if vals.size <= (int(line.max()) if n_pts else -1):
            raise ValueError(f"color_by has {vals.size} values; the section has lines 0 … {int(line.max())}")
        c = vals[line]
        finite = vals[np.isfinite(vals)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if hi <= lo:
            lo, hi = lo - 0.5, hi + 0.5
        cmap, norm = matplotlib.colormaps["viridis"], Normalize(lo, hi)
        clabel = color_label or "line value"
    else:  # one colour per line, the bar's ticks at the line indices
        c = line
        cmap = matplotlib.colormaps["viridis"].resampled(max(n_lines, 2))
        norm = BoundaryNorm(np.arange(-0.5, max(n_lines, 2) + 0.5), cmap.N)
        clabel = color_label or "field line (index)"
    ax.scatter(section.R, section.Z, c=c, s=size, cmap=cmap, norm=norm, linewidths=0, rasterized=True)
    handles = [Line2D([], [], ls="none", marker="o", ms=4, color=cmap(0.6),
                      label=f"section points ({n_pts} crossings of {n_lines} lines)")]
    if wall is not None:
        (w,) = ax.plot(wall.R, wall.Z, "k-", lw=1.2, label="wall")
        handles.append(w)
    if axis is not None:
        iota_text = f", ι = {axis.iota:.5g}" if np.isfinite(getattr(axis, "iota", np.nan)) else ""
        (a,) = ax.plot([axis.R], [axis.Z], "+", color="C3", ms=13, mew=2.2, zorder=5,
                       label=f"magnetic axis{iota_text}")
        handles.append(a)
    for kind, marker, colour, what in (("O", "o", "C1", "O-points (elliptic)"), ("X", "x", "C3", "X-points (hyperbolic)")):
        pts = [p for p in fixed_points if p.kind == kind]
        if pts:
            orbit = np.concatenate([np.asarray(p.orbit, float).reshape(-1, 2) for p in pts])
            ms = sorted({int(p.m) for p in pts})
            (h,) = ax.plot(orbit[:, 0], orbit[:, 1], marker, color=colour, ms=8, mfc="none", mew=1.8, zorder=6,
                           label=f"{what}, m = {', '.join(map(str, ms))}")
            handles.append(h)
    ax.set_xlabel(_unit("R", units), fontsize=11)
    ax.set_ylabel(_unit("Z", units), fontsize=11)
    ax.tick_params(labelsize=10)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3, alpha=0.4)
    ax.set_title(f"Poincaré section {_angle_text(float(section.phi0), int(section.nfp))}", fontsize=11)
    sm = ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(sm, ax=ax, shrink=0.85, pad=0.02)
    cb.set_label(_wrapped(fig, clabel, 10, share=0.5), fontsize=10)
    if color_by is None:
        step = max(1, int(math.ceil(n_lines / 10)))
        cb.set_ticks(np.arange(0, n_lines, step))
    cb.ax.tick_params(labelsize=9)
    fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=9, frameon=False)
    if title:
        fig.suptitle(_wrapped(fig, title, 11), fontsize=11)
    save(fig, path)
    return fig


def iota_figure(iota: Any, title: str | None = None, path: str | None = None, *, units: str = "m",
                axis: Any = None):
    """The rotational transform ι and the safety factor q = 1/ι against the starting radius R of
    each line (:class:`~vpforms.fieldlines.Iota`), with the weighted Birkhoff average's error
    estimate |ι_N − ι_{N/2}| as error bars, and, given ``axis`` (a
    :class:`~vpforms.fieldlines.FixedPoint`), the axis's ι from the tangent map at R_axis.

    Labels at ≥ 10 pt, spelled out ("rotational transform ι", "safety factor q = 1/ι"), the
    abscissa in ``units`` ("m"; "" when unknown); lines whose ι is not finite (a failed line) are
    left out and counted in a note; the title is wrapped to the figure's width."""
    from matplotlib.lines import Line2D

    fig = _figure(8.0, 4.8)
    a1 = fig.add_subplot(1, 2, 1)
    a2 = fig.add_subplot(1, 2, 2)
    vals = np.asarray(iota.iota, float)
    R0 = np.asarray(iota.R0, float)
    err = np.asarray(iota.error, float)
    ok = np.isfinite(vals)
    yerr = np.where(np.isfinite(err[ok]), err[ok], 0.0)
    a1.errorbar(R0[ok], vals[ok], yerr=yerr, fmt="o-", ms=4, lw=1.0, capsize=2, color="C0")
    q = np.asarray(iota.q, float)
    okq = ok & np.isfinite(q)
    a2.plot(R0[okq], q[okq], "o-", ms=4, lw=1.0, color="C1")
    handles = [Line2D([], [], marker="o", color="C0", ms=4, lw=1.0,
                      label="field lines: weighted Birkhoff average (bars: |ι(N) − ι(N/2)|)")]
    if axis is not None and np.isfinite(getattr(axis, "iota", np.nan)):
        a1.plot([axis.R], [axis.iota], "*", color="C3", ms=12, zorder=5)
        if axis.iota != 0:
            a2.plot([axis.R], [1.0 / axis.iota], "*", color="C3", ms=12, zorder=5)
        handles.append(Line2D([], [], ls="none", marker="*", color="C3", ms=10,
                              label=f"magnetic axis (tangent map), ι = {axis.iota:.5g}"))
    xlabel = _unit("starting R on Z = Z_axis", units)
    for a, ylabel in ((a1, "rotational transform ι"), (a2, "safety factor q = 1/ι")):
        a.set_xlabel(xlabel, fontsize=11)
        a.set_ylabel(ylabel, fontsize=11)
        a.tick_params(labelsize=10)
        a.grid(True, lw=0.3, alpha=0.4)
    if not ok.all():  # a line that left the domain (a grid's edge, a wall) did not fail: said apart
        left = int(np.count_nonzero(~ok & (np.asarray(iota.status) == RESULTS.left_domain)))
        failed = int(np.count_nonzero(~ok)) - left
        said = (f"{failed} of {vals.size} lines failed" + (f", {left} left the domain" if left else "") if failed
                else f"{left} of {vals.size} lines left the domain")
        a1.text(0.02, 0.02, f"{said} (no ι): not shown", transform=a1.transAxes, fontsize=9, color="0.3")
    fig.legend(handles=handles, loc="outside lower center", ncol=1, fontsize=9, frameon=False)
    fig.suptitle(_wrapped(fig, title or "rotational transform ι and safety factor q", 11), fontsize=11)
    save(fig, path)
    return fig


def connection_length_figure(lengths: Any, grid: Any = None, wall: Any = None, section: Any = None,
                             title: str | None = None, path: str | None = None, *, units: str = "m"):
    """A connection-length map on a section: each starting point coloured by its L_c = L_fwd + L_bwd
    (:class:`~vpforms.fieldlines.ConnectionLengths`) on a logarithmic colour scale with a colour bar;
    the lines that did not reach the wall within the steps given (their length is only a lower bound)
    in light grey, the failed ones (or those stopped by the field's own domain) in red; the wall, and
    optionally a Poincaré ``section`` (:class:`~vpforms.fieldlines.ToroidalSection`) as small black
    dots for the islands and surfaces.

    ``grid`` (a :class:`~vpforms.fieldlines.StartGrid` of the starting points): drawn as cells of the
    grid; without it, as dots. ``units``: of R, Z and L_c ("m"; "" when unknown)."""
    import matplotlib
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    L = np.asarray(lengths.L, float)
    reached = np.asarray(lengths.reached, bool)
    open_ = np.asarray(lengths.unreached, bool)
    bad = ~reached & ~open_
    if wall is not None:
        r0, r1, z0, z1 = wall.bounds
    else:
        R0 = np.sqrt(2 * lengths.x0[:, 0]) if lengths.toroidal else np.hypot(lengths.x0[:, 0], lengths.x0[:, 1])
        r0, r1, z0, z1 = R0.min(), R0.max(), lengths.x0[:, 2].min(), lengths.x0[:, 2].max()
    aspect = float(np.clip((r1 - r0) / max(z1 - z0, 1e-300), 0.3, 3.0))
    fig = _figure(float(np.clip(5.2 * aspect + 2.6, 6.0, 11.0)), 7.8)  # the section's width at equal scales
    ax = fig.add_subplot(1, 1, 1)
    cmap = matplotlib.colormaps["viridis"]
    ok = L[reached]
    lo, hi = (float(ok.min()), float(ok.max())) if ok.size else (1.0, 10.0)
    if hi <= lo:
        lo, hi = lo / 2, hi * 2
    norm = LogNorm(lo, hi)
    grey, red = ListedColormap(["0.82"]), ListedColormap(["C3"])
    if grid is not None:
        def cells(values, **kw):
            ax.pcolormesh(grid.R, grid.Z, np.ma.masked_invalid(grid.image(values)), shading="nearest",
                          rasterized=True, **kw)

        cells(np.where(reached, L, np.nan), cmap=cmap, norm=norm)
        cells(np.where(open_, 1.0, np.nan), cmap=grey, vmin=0, vmax=2)
        cells(np.where(bad, 1.0, np.nan), cmap=red, vmin=0, vmax=2)
    else:
        R0 = np.sqrt(2 * lengths.x0[:, 0]) if lengths.toroidal else np.hypot(lengths.x0[:, 0], lengths.x0[:, 1])
        Z0 = lengths.x0[:, 2]
        size = float(np.clip(3e4 / max(L.size, 1), 1.0, 30.0))
        ax.scatter(R0[reached], Z0[reached], c=L[reached], cmap=cmap, norm=norm, s=size, linewidths=0)
        ax.scatter(R0[open_], Z0[open_], color="0.82", s=size, linewidths=0)
        ax.scatter(R0[bad], Z0[bad], color="C3", s=size, linewidths=0)
    n = L.size
    unit = f" {units}" if units else ""
    handles = [Patch(color=cmap(0.6), label=f"reached the wall ({int(reached.sum())} of {n} lines): L_c in colour")]
    if open_.any():
        lb = float(np.min(np.asarray(lengths.traced)[open_]))
        handles.append(Patch(color="0.82", label=f"not reached within the steps ({int(open_.sum())}): "
                                                 f"L_c > {lb:.3g}{unit}, a lower bound"))
    if bad.any():
        handles.append(Patch(color="C3", label=f"failed or left the field's domain ({int(bad.sum())})"))
    if section is not None and len(section):
        ax.scatter(section.R, section.Z, s=0.4, color="k", linewidths=0, alpha=0.8, rasterized=True)
        handles.append(Line2D([], [], ls="none", marker=".", ms=3, color="k",
                              label=f"Poincaré section ({len(section)} crossings)"))
    if wall is not None:
        (w,) = ax.plot(wall.R, wall.Z, "k-", lw=1.4, label="wall")
        handles.append(w)
    ax.set_xlabel(_unit("R", units), fontsize=11)
    ax.set_ylabel(_unit("Z", units), fontsize=11)
    ax.tick_params(labelsize=10)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, lw=0.3, alpha=0.4)
    cb = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.85, pad=0.02)
    cb.set_label(_unit("connection length L_c = L_fwd + L_bwd", units), fontsize=10)
    cb.ax.tick_params(labelsize=9)
    fig.legend(handles=handles, loc="outside lower center", ncol=1, fontsize=9, frameon=False)
    if title:
        fig.suptitle(_wrapped(fig, title, 11), fontsize=11)
    save(fig, path)
    return fig

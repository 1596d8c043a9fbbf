"""Where a field-line study may start (issue #41): inside the field's domain, at R > 0, off the axis.

A study from an impossible start used to give a wrong answer rather than an error: a line started
outside a field's box was traced until it failed (ι = NaN, status 2, after the whole trace); a
radius R ≤ 0 became u = R²/2 > 0, i.e. the line at |R|; a line on the magnetic axis, whose poloidal
angle θ = atan2(Z − Z_a, R − R_a) is undefined, read ι = 0 with error 0. These checks refuse such
starts up front, in one line naming the line, its (R, Z) and the box:

* **R > 0** — R is the distance from the major axis; R ≤ 0 (or not a number) has no line;
* **in the domain** — the field's own ``domain_check`` where it has one (a gridded field: its
  grid), and the field's ``box`` on every non-periodic coordinate (φ is an angle: never checked);
  outside it a closed-form field has not been checked and a grid field does not exist;
* **off the axis** (ι only) — a start within :data:`ON_AXIS_FRACTION` of the (R, Z) size of the box
  from the axis curve at its φ. The axis's ι is that of the tangent map,
  :func:`~vpforms.fieldlines.magnetic_axis`\\ ``(…).iota``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ._geometry import is_toroidal

__all__ = ["ON_AXIS_FRACTION", "StartPointError", "check_radii", "check_starts", "check_off_axis", "rz_box"]

#: a start closer to the axis than this fraction of the (R, Z) size of the field's box is on the axis
ON_AXIS_FRACTION = 1e-6


class StartPointError(ValueError):
    """A study asked to start where no answer is right (module docstring): one line naming where."""


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def check_radii(R: Any, what: str, indexed: bool = True) -> np.ndarray:
    """R as a 1-D float array, every entry a positive finite number (ValueError naming the first
    that is not: ``what`` says which, e.g. "line" or "the axis guess", followed by its index when
    ``indexed``)."""
    R = np.asarray(R, float).reshape(-1)
    bad = np.flatnonzero(~(np.isfinite(R) & (R > 0)))
    if bad.size:
        i = int(bad[0])
        who = f"{what} {i}" if indexed else what
        raise StartPointError(f"{who}: R must be a positive number (the distance from the major axis); got "
                         f"R = {_fmt(R[i])}")
    return R


def rz_box(field: Any) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The (R, Z) ranges of the field's box: R from u = R²/2 in (u, φ, Z); in Cartesian (x₁, x₂, x₃)
    R ∈ [0, max |corner|] of the (x₁, x₂) square. None when the field has no box."""
    box = getattr(field, "box", None)
    if box is None:
        return None
    b = np.asarray(box, float)
    if is_toroidal(field):
        return (math.sqrt(2 * max(b[0, 0], 0.0)), math.sqrt(2 * max(b[0, 1], 0.0))), (b[2, 0], b[2, 1])
    return (0.0, float(np.max(np.hypot(np.abs(b[0]).max(), np.abs(b[1]).max())))), (b[2, 0], b[2, 1])


def _names(field: Any) -> tuple[str, str, str]:
    return ("u", "φ", "Z") if is_toroidal(field) else ("x1", "x2", "x3")


def _box_text(field: Any) -> str:
    b = np.asarray(field.box, float)
    if is_toroidal(field):
        (r0, r1), (z0, z1) = rz_box(field)
        return f"R ∈ [{_fmt(r0)}, {_fmt(r1)}], Z ∈ [{_fmt(z0)}, {_fmt(z1)}]"
    return ", ".join(f"{n} ∈ [{_fmt(lo)}, {_fmt(hi)}]" for n, (lo, hi) in zip(_names(field), b))


def _checked_axes(field: Any) -> list[int]:
    """The coordinates the box bounds: not φ of (u, φ, Z), not a periodic one."""
    periods = tuple(getattr(field, "periods", None) or (None,) * 3)
    return [a for a in range(3) if periods[a] is None and not (is_toroidal(field) and a == 1)]


def check_starts(field: Any, pts: np.ndarray, what: str = "line", verb: str = "starts",
                 indexed: bool = True) -> None:
    """ValueError unless every point (N, 3) of the field's coordinates has R > 0 and lies in the
    field's domain and box (module docstring); the message names ``what`` and (``indexed``) the
    point's index."""
    pts = np.asarray(pts, float).reshape(-1, 3)
    tor = is_toroidal(field)
    R = np.sqrt(np.maximum(2 * pts[:, 0], 0.0)) if tor else np.hypot(pts[:, 0], pts[:, 1])
    Z = pts[:, 2]
    def who(i: int) -> str:
        return f"{what} {i}" if indexed else what

    nonpos = np.flatnonzero((pts[:, 0] <= 0) if tor else (R == 0))
    if nonpos.size:
        i = int(nonpos[0])
        raise StartPointError(f"{who(i)} {verb} at R = 0 (u = {_fmt(pts[i, 0])})" if tor else
                         f"{who(i)} {verb} on the major axis R = 0, where φ is undefined")
    check = getattr(field, "domain_check", None)
    if check is not None:
        try:
            check(pts)
        except ValueError as exc:
            raise StartPointError(f"{what}: {exc}") from None
    if getattr(field, "box", None) is None:
        return
    b = np.asarray(field.box, float)
    out = np.zeros(len(pts), bool)
    for a in _checked_axes(field):
        out |= (pts[:, a] < b[a, 0]) | (pts[:, a] > b[a, 1])
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise StartPointError(f"{who(i)} {verb} at R = {_fmt(R[i])}, Z = {_fmt(Z[i])}, outside the field's box "
                         f"{_box_text(field)}: the field is not known there")


def check_off_axis(field: Any, R: np.ndarray, Z: np.ndarray, Ra: np.ndarray, Za: np.ndarray) -> None:
    """ValueError naming the first line whose start (R, Z) is within :data:`ON_AXIS_FRACTION` of the
    box's (R, Z) size from the axis point (R_a, Z_a) at its φ: its poloidal angle is undefined."""
    box = rz_box(field)
    size = max(box[0][1] - box[0][0], box[1][1] - box[1][0]) if box else max(float(np.max(np.abs(Ra))), 1.0)
    d = np.hypot(np.asarray(R) - Ra, np.asarray(Z) - Za)
    on = np.flatnonzero(d <= ON_AXIS_FRACTION * size)
    if on.size:
        i = int(on[0])
        raise StartPointError(
            f"line {i} starts on the magnetic axis ((R, Z) = ({_fmt(R[i])}, {_fmt(Z[i])}), {d[i]:.2g} from "
            f"it): the poloidal angle about the axis is undefined there, so its ι would read 0; the axis's "
            "own ι is magnetic_axis(...).iota (from the tangent map)")

"""The W7-X section reference of the simsopt side-by-side benchmark (issue #38 item 5): load it, compare to it.

numpy only — imported by ``benchmarks/peers/run_simsopt_w7x.py`` (simsopt's venv) and usable from the
vpforms side; run as a script it prints a summary of the file:

    python benchmarks/peers/w7x_reference.py [benchmarks/peers/data/w7x_reference.npz]

 The file ``benchmarks/peers/data/w7x_reference.npz`` is written by
``run_simsopt_w7x.py reference``: simsopt ``compute_fieldlines`` on the direct ``BiotSavart`` of W7-X
(``get_data("w7x")``, 70 coils × 96 quadrature points, tol ``tol``), ``transits`` toroidal transits.

Crossing ordering convention
----------------------------
* **Lines.** ``line = i`` (0 … 19) starts at (R, φ, Z) = (``start_R[i]``, 0, 0), ``start_R[i] = R_axis +
  offsets[i]``, ``offsets = linspace(0.0125, 0.25, 20)``, R_axis the corrected axis of
  ``src/vpforms/coils/data/w7x.json`` at φ = 0 (5.948618791… m).
* **Direction.** Each line is traced along +B (dx/dt = B). W7-X's B points towards −φ on the
  start plane, so ``direction = −1``: the line's accumulated toroidal angle decreases,
  φ_acc(t) = 0 → −∞.
* **Planes.** The 10 planes φ = kπ/5, k = 0 … 9 (W7-X has nfp = 5): the **bean** planes φ ≡ 0
  (mod 2π/5) and the **triangle** planes φ ≡ π/5 (mod 2π/5) of every field period.
* **Crossing index** ``crossing = j`` (1, 2, … , 10·transits): the j-th plane the line meets after
  its start, i.e. the point where φ_acc = direction · j · π/5. So
  - j even ⇔ a bean plane (j = 10·n: the plane φ = 0 itself, after n full transits), j odd ⇔ a
    triangle plane;
  - transit number = j / 10 (j = 10 ends transit 1; the first 50 transits are j = 1 … 500);
  - field period p = ⌈j / 2⌉; ``phi_plane`` stores the plane's angle in [0, 2π) (φ_acc mod 2π).
  The start itself (j = 0) is not stored.
* **Rows.** ``line``, ``crossing``, ``R``, ``Z``, ``t`` (simsopt's time: arclength / |B|, dx/dt = B),
  ``phi_plane`` are flat arrays, sorted by line, then by crossing; every line has all j = 1 … 10·transits.
* **Tracing the other way.** A tracer that follows −B (or uses φ as the time, increasing) from the same
  start meets φ = +jπ/5; by stellarator symmetry (R, φ, Z) → (R, −φ, −Z), its j-th crossing is the
  reference's j-th crossing with Z negated: compare (R, −Z).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PLANES = ("all", "bean", "triangle")


def load_reference(path) -> dict:
    """The reference file as a dict of numpy arrays (scalars as 0-d arrays; ``info`` a JSON string),
    checked for the ordering of the module docstring."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no W7-X reference at {path} (run benchmarks/peers/run_simsopt_w7x.py reference)")
    with np.load(path, allow_pickle=False) as f:
        ref = {k: f[k] for k in f.files}
    need = ("line", "crossing", "R", "Z", "start_R", "start_Z", "transits", "direction")
    missing = [k for k in need if k not in ref]
    if missing:
        raise ValueError(f"{path} is not a W7-X reference file: missing {missing}")
    key = ref["line"].astype(np.int64) * (1 << 32) + ref["crossing"].astype(np.int64)
    if np.any(np.diff(key) <= 0):
        raise ValueError(f"{path}: rows are not sorted by (line, crossing) without repeats")
    ref["_key"] = key
    ref["info"] = str(ref["info"]) if "info" in ref else ""
    return ref


def section_error(reference: dict, R, Z, line_index, crossing_index, plane: str = "all") -> tuple[float, float]:
    """(max, median) over the given crossings of the in-plane distance |(R, Z) − (R_ref, Z_ref)| (m).

    R, Z, line_index, crossing_index: arrays of one shape, one entry per crossing of the caller's
    tracer, indexed as the module docstring says (line 0 … 19, crossing j ≥ 1). ``plane``: "all",
    "bean" (only j even) or "triangle" (only j odd). A crossing the reference does not hold is an
    error (ValueError), as is a non-finite R or Z — a missed or NaN crossing is never silently dropped.
    """
    if plane not in PLANES:
        raise ValueError(f"plane must be one of {PLANES}, got {plane!r}")
    R, Z = np.asarray(R, dtype=float).ravel(), np.asarray(Z, dtype=float).ravel()
    li = np.asarray(line_index).ravel().astype(np.int64)
    j = np.asarray(crossing_index).ravel().astype(np.int64)
    if not (R.shape == Z.shape == li.shape == j.shape):
        raise ValueError(f"R, Z, line_index, crossing_index differ in size: {R.size}, {Z.size}, {li.size}, {j.size}")
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(Z))):
        raise ValueError("R or Z holds a non-finite value")
    if plane != "all":
        keep = (j % 2 == 0) if plane == "bean" else (j % 2 == 1)
        R, Z, li, j = R[keep], Z[keep], li[keep], j[keep]
    if R.size == 0:
        raise ValueError(f"no crossings to compare (plane {plane!r})")
    key = li * (1 << 32) + j
    pos = np.searchsorted(reference["_key"], key)
    pos_c = np.minimum(pos, reference["_key"].size - 1)
    bad = reference["_key"][pos_c] != key
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValueError(f"the reference holds no crossing j = {j[k]} of line {li[k]} "
                         f"(it has lines 0 … {int(reference['line'].max())}, j = 1 … {int(reference['crossing'].max())})")
    d = np.hypot(R - reference["R"][pos_c], Z - reference["Z"][pos_c])
    return float(d.max()), float(np.median(d))


def main(argv=None) -> None:
    """Print the file's settings and, per line, its start, crossings and how far simsopt's own points
    (as ``compute_fieldlines`` returned them) lie from the refined ones."""
    import json
    import sys

    args = sys.argv[1:] if argv is None else argv
    path = Path(args[0]) if args else Path(__file__).resolve().parent / "data" / "w7x_reference.npz"
    ref = load_reference(path)
    info = json.loads(ref["info"]) if ref["info"] else {}
    print(f"{path}: tol {float(ref['tol']):g}, {int(ref['transits'])} transits, direction {int(ref['direction'])}, "
          f"simsopt {info.get('simsopt', '?')}, {info.get('seconds', float('nan')):.0f} s")
    for i, R0 in enumerate(ref["start_R"]):
        sel = ref["line"] == i
        off = np.hypot(ref["R"][sel] - ref["R_simsopt"][sel], ref["Z"][sel] - ref["Z_simsopt"][sel]).max() \
            if "R_simsopt" in ref else float("nan")
        print(f"line {i:2d}: R0 = {R0:.6f} m, crossings {int(ref['crossing'][sel].min())} … "
              f"{int(ref['crossing'][sel].max())}, simsopt's points off the refined ones by ≤ {off:.1e} m")


if __name__ == "__main__":
    main()

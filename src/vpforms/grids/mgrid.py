"""STELLOPT MAKEGRID ``mgrid_*.nc`` files: reader and writer (netCDF through ``scipy.io``).

Layout followed — the one ``MAKEGRID/Sources/write_mgrid.f`` (``write_mgrid_nc``) writes and
``LIBSTELL/Sources/Modules/mgrid_mod.f`` (``read_mgrid_nc``, used by VMEC) reads, in the
PrincetonUniversity/STELLOPT sources:

* dimensions ``stringsize`` (30), ``external_coil_groups`` (nextcur), ``dim_00001`` (1),
  ``external_coils`` (nextcur), ``rad`` (ir), ``zee`` (jz), ``phi`` (kp);
* scalars ``ir``, ``jz``, ``kp``, ``nfp``, ``nextcur`` (int), ``rmin``, ``zmin``, ``rmax``, ``zmax``
  (double); ``coil_group`` (char, (external_coil_groups, stringsize); for nextcur = 1 MAKEGRID
  writes a 1-D char(dim_00030) — both are read); ``mgrid_mode`` (char(dim_00001): 'S' or 'R');
  ``raw_coil_cur`` (double(external_coils));
* per coil group g = 1 … nextcur (3 digits): ``br_001``, ``bp_001``, ``bz_001`` — the physical
  cylindrical components B_R, B_φ, B_Z, double(phi, zee, rad) (R fastest); optionally
  ``ar_001``, ``ap_001``, ``az_001``, the vector potential (newer MAKEGRID; same layout).

Grid: R_i = rmin + i (rmax − rmin)/(ir − 1), Z_j = zmin + j (zmax − zmin)/(jz − 1) (both ends
included), φ_k = 2π k/(nfp kp), k = 0 … kp − 1: one field period, endpoint excluded.

Scaling (MAKEGRID ``compute_bfield``; VMEC sums bvac = Σ_g extcur_g · b_g in either mode):
mode 'S' (scaled) stores b_g for unit current — the group's field divided by its raw current
I_g = ``raw_coil_cur[g]`` (the coil current of largest magnitude in the coils file), so the
physical field at currents I_g' is Σ I_g' b_g; mode 'R' (raw) stores the field at the raw currents,
so it is Σ (I_g'/I_g) b_g (VMEC's extcur is then the ratio). :meth:`MGrid.total` does this.

NetCDF3 (classic / 64-bit offset) is read and written by ``scipy.io.netcdf_file`` (no extra
dependency); a NetCDF4/HDF5 file is read when ``h5netcdf`` or ``netCDF4`` is importable. Whatever
is wrong with a file — not netCDF, truncated, missing variables, wrong shapes, NaN/inf values, a
grid with rmin ≤ 0 — raises one :class:`GridFileError` naming the file and the problem.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.io import netcdf_file

__all__ = ["GridFileError", "MGrid", "read_mgrid", "write_mgrid"]

_STRINGSIZE = 30
_MODES = ("S", "R", "N")  # N: no mode information (old files, as LIBSTELL reads them)
_COMPONENTS_B = ("br", "bp", "bz")
_COMPONENTS_A = ("ar", "ap", "az")


class GridFileError(ValueError):
    """A grid file that cannot be used: the message names the file and what is wrong."""


@dataclass(eq=False)
class MGrid:
    """The contents of an mgrid file (module docstring).

    Attributes
    ----------
    rmin, rmax, zmin, zmax:
        The (R, Z) box; R_i and Z_j span it with ``ir`` and ``jz`` points, both ends included.
    nfp:
        Number of field periods; φ_k = 2π k/(nfp kp), one period, endpoint excluded.
    B:
        Shape (nextcur, 3, kp, jz, ir): per coil group (B_R, B_φ, B_Z) in netCDF order (φ, Z, R).
    A:
        The vector potential (A_R, A_φ, A_Z) of each group, same shape, or None.
    names:
        The coil-group names (≤ 30 characters each).
    currents:
        ``raw_coil_cur``: per group the raw current I_g, or None if the file has none.
    mode:
        'S' (scaled: fields per unit current), 'R' (raw: fields at the raw currents) or 'N' (no
        mode information).
    """

    rmin: float
    rmax: float
    zmin: float
    zmax: float
    nfp: int
    B: np.ndarray
    A: np.ndarray | None = None
    names: list[str] = field(default_factory=list)
    currents: np.ndarray | None = None
    mode: str = "S"

    def __post_init__(self):
        self.B = np.asarray(self.B, dtype=float)
        if self.B.ndim == 4:  # one group given as (3, kp, jz, ir)
            self.B = self.B[None]
        if self.B.ndim != 5 or self.B.shape[1] != 3:
            raise ValueError(f"B must have shape (nextcur, 3, kp, jz, ir); got {self.B.shape}")
        ng = self.B.shape[0]
        if self.A is not None:
            self.A = np.asarray(self.A, dtype=float)
            if self.A.ndim == 4:
                self.A = self.A[None]
            if self.A.shape != self.B.shape:
                raise ValueError(f"A must have B's shape {self.B.shape}; got {self.A.shape}")
        if not self.names:
            self.names = [f"group_{g + 1:03d}" for g in range(ng)]
        self.names = [str(n) for n in self.names]
        if len(self.names) != ng:
            raise ValueError(f"{len(self.names)} names for {ng} coil groups")
        for n in self.names:
            if len(n) > _STRINGSIZE or not n.isascii():
                raise ValueError(f"a coil-group name must be ≤ {_STRINGSIZE} ASCII characters: "
                                 f"{n!r}")
        if self.currents is not None:
            self.currents = np.asarray(self.currents, dtype=float).reshape(-1)
            if self.currents.shape != (ng,):
                raise ValueError(f"currents must have one entry per group ({ng}); got "
                                 f"{self.currents.shape}")
        if self.mode not in _MODES:
            raise ValueError(f"mode must be one of {_MODES}; got {self.mode!r}")
        if isinstance(self.nfp, bool) or int(self.nfp) != self.nfp or int(self.nfp) < 1:
            raise ValueError(f"nfp must be a positive integer; got {self.nfp!r}")
        self.nfp = int(self.nfp)
        for name in ("rmin", "rmax", "zmin", "zmax"):
            setattr(self, name, float(getattr(self, name)))
        _check_grid(self, "MGrid")

    # -- the grid ---------------------------------------------------------------------------
    @property
    def nextcur(self) -> int:
        return int(self.B.shape[0])

    @property
    def kp(self) -> int:
        return int(self.B.shape[2])

    @property
    def jz(self) -> int:
        return int(self.B.shape[3])

    @property
    def ir(self) -> int:
        return int(self.B.shape[4])

    @property
    def R(self) -> np.ndarray:
        """R_i = rmin + i (rmax − rmin)/(ir − 1), i = 0 … ir − 1."""
        return np.linspace(self.rmin, self.rmax, self.ir)

    @property
    def Z(self) -> np.ndarray:
        """Z_j = zmin + j (zmax − zmin)/(jz − 1), j = 0 … jz − 1."""
        return np.linspace(self.zmin, self.zmax, self.jz)

    @property
    def phi(self) -> np.ndarray:
        """φ_k = 2π k/(nfp kp), k = 0 … kp − 1 (one field period, endpoint excluded)."""
        return 2 * np.pi * np.arange(self.kp) / (self.nfp * self.kp)

    @property
    def period(self) -> float:
        """The field period 2π/nfp."""
        return 2 * np.pi / self.nfp

    # -- the summed field -------------------------------------------------------------------
    def weights(self, currents: Sequence[float] | None = None,
                extcur: Sequence[float] | None = None) -> np.ndarray:
        """The factor w_g of each group in Σ_g w_g b_g (:meth:`total`)."""
        if extcur is not None:
            if currents is not None:
                raise ValueError("give currents or extcur, not both")
            w = np.asarray(extcur, dtype=float).reshape(-1)
        else:
            raw = self.currents if self.currents is not None else np.ones(self.nextcur)
            cur = raw if currents is None else np.asarray(currents, dtype=float).reshape(-1)
            if cur.shape != (self.nextcur,):
                raise ValueError(f"currents must have one entry per group ({self.nextcur})")
            if self.mode == "R":
                if np.any(raw == 0):
                    raise ValueError("mode 'R' with a zero raw current: use extcur instead")
                w = cur / raw  # the raw fields scaled to the requested currents
            else:  # 'S' (and 'N'): the stored fields are per unit current
                w = cur
        if w.shape != (self.nextcur,) or not np.all(np.isfinite(w)):
            raise ValueError(f"need {self.nextcur} finite weights; got {w!r}")
        return w

    def total(self, currents: Sequence[float] | None = None, *,
              extcur: Sequence[float] | None = None, potential: bool = False) -> np.ndarray:
        """The field of all groups, (3, kp, jz, ir) = (B_R, B_φ, B_Z), summed as VMEC does.

        ``currents`` are the physical group currents I_g' (default: the raw currents of the
        file, i.e. the coils file as MAKEGRID saw it): mode 'S' (and 'N') gives Σ I_g' b_g, mode
        'R' gives Σ (I_g'/I_g) b_g. ``extcur`` instead gives VMEC's multipliers directly:
        Σ extcur_g b_g in either mode. ``potential=True`` sums A the same way (A is linear in the
        currents too)."""
        w = self.weights(currents, extcur)
        src = self.B
        if potential:
            if self.A is None:
                raise ValueError("this mgrid has no vector potential (ar_/ap_/az_)")
            src = self.A
        return np.tensordot(w, src, axes=(0, 0))

    # -- construction from functions --------------------------------------------------------
    @classmethod
    def from_functions(cls, B: Callable[..., Any] | Sequence[Callable[..., Any]], *,
                       rmin: float, rmax: float, zmin: float, zmax: float, ir: int, jz: int,
                       kp: int, nfp: int = 1,
                       A: Callable[..., Any] | Sequence[Callable[..., Any]] | None = None,
                       names: Sequence[str] = (), currents: Sequence[float] | None = None,
                       mode: str = "S") -> MGrid:
        """Sample B(R, φ, Z) → (B_R, B_φ, B_Z) (numpy-vectorised; one function per group) and
        optionally A the same way on the mgrid of the given size."""
        Bs = [B] if callable(B) else list(B)
        As = None if A is None else ([A] if callable(A) else list(A))
        R = np.linspace(rmin, rmax, ir)
        Z = np.linspace(zmin, zmax, jz)
        phi = 2 * np.pi * np.arange(kp) / (nfp * kp)
        P, ZZ, RR = np.meshgrid(phi, Z, R, indexing="ij")  # (kp, jz, ir)

        def sample(f):
            out = np.stack([np.broadcast_to(np.asarray(c, float), RR.shape) for c in f(RR, P, ZZ)])
            if out.shape != (3, kp, jz, ir):
                raise ValueError(f"a field function must return 3 arrays of shape {RR.shape}")
            return out

        return cls(rmin=rmin, rmax=rmax, zmin=zmin, zmax=zmax, nfp=nfp,
                   B=np.stack([sample(f) for f in Bs]),
                   A=None if As is None else np.stack([sample(f) for f in As]),
                   names=list(names), currents=currents, mode=mode)


def _check_grid(g: MGrid, where: str) -> None:
    """The checks shared by the constructor and the reader (ValueError naming ``where``)."""
    if not all(np.isfinite(v) for v in (g.rmin, g.rmax, g.zmin, g.zmax)):
        raise ValueError(f"{where}: the grid bounds must be finite")
    if not g.rmin > 0:
        raise ValueError(f"{where}: rmin = {g.rmin!r} must be > 0 (R = 0 is the axis of the "
                         "cylindrical coordinates)")
    if not g.rmax > g.rmin:
        raise ValueError(f"{where}: rmax = {g.rmax!r} must be > rmin = {g.rmin!r}")
    if not g.zmax > g.zmin:
        raise ValueError(f"{where}: zmax = {g.zmax!r} must be > zmin = {g.zmin!r}")
    if g.ir < 2 or g.jz < 2 or g.kp < 1:
        raise ValueError(f"{where}: need ir ≥ 2, jz ≥ 2, kp ≥ 1; got ir={g.ir}, jz={g.jz}, "
                         f"kp={g.kp}")
    for what, arr in (("B", g.B), ("A", g.A), ("raw_coil_cur", g.currents)):
        if arr is not None and not np.all(np.isfinite(arr)):
            bad = np.argwhere(~np.isfinite(np.asarray(arr)))[0]
            raise ValueError(f"{where}: {what} has a non-finite value ({np.asarray(arr)[tuple(bad)]})"
                             f" at index {tuple(int(i) for i in bad)}")


# ------------------------------------------------------------------------------------ writing
def write_mgrid(mgrid: MGrid, path: str | os.PathLike) -> None:
    """Write ``mgrid`` in the MAKEGRID layout (module docstring) as NetCDF3 64-bit offset.

    Reading it back with :func:`read_mgrid` gives bit-for-bit identical arrays."""
    ng = mgrid.nextcur
    with netcdf_file(os.fspath(path), "w", version=2) as f:
        f.createDimension("stringsize", _STRINGSIZE)
        f.createDimension("external_coil_groups", ng)
        f.createDimension("dim_00001", 1)
        f.createDimension("external_coils", ng)
        f.createDimension("rad", mgrid.ir)
        f.createDimension("zee", mgrid.jz)
        f.createDimension("phi", mgrid.kp)
        if ng == 1:
            f.createDimension(f"dim_{_STRINGSIZE:05d}", _STRINGSIZE)
        for name, val in (("ir", mgrid.ir), ("jz", mgrid.jz), ("kp", mgrid.kp),
                          ("nfp", mgrid.nfp), ("nextcur", ng)):
            f.createVariable(name, "i", ()).data[()] = np.int32(val)
        for name in ("rmin", "zmin", "rmax", "zmax"):
            f.createVariable(name, "d", ()).data[()] = np.float64(getattr(mgrid, name))
        names = np.array([list(n.ljust(_STRINGSIZE)) for n in mgrid.names], dtype="S1")
        if ng == 1:  # MAKEGRID writes a single name as a 1-D character array
            f.createVariable("coil_group", "c", (f"dim_{_STRINGSIZE:05d}",))[:] = names[0]
        else:
            f.createVariable("coil_group", "c", ("external_coil_groups", "stringsize"))[:] = names
        f.createVariable("mgrid_mode", "c", ("dim_00001",))[:] = np.array([mgrid.mode], "S1")
        if mgrid.currents is not None:
            f.createVariable("raw_coil_cur", "d", ("external_coils",))[:] = mgrid.currents
        dims = ("phi", "zee", "rad")
        for g in range(ng):
            for c, name in enumerate(_COMPONENTS_B):
                f.createVariable(f"{name}_{g + 1:03d}", "d", dims)[:] = mgrid.B[g, c]
            if mgrid.A is not None:
                for c, name in enumerate(_COMPONENTS_A):
                    f.createVariable(f"{name}_{g + 1:03d}", "d", dims)[:] = mgrid.A[g, c]


# ------------------------------------------------------------------------------------ reading
def read_mgrid(path: str | os.PathLike) -> MGrid:
    """Read an mgrid file (NetCDF3 through scipy; NetCDF4 if h5netcdf or netCDF4 is importable).

    Raises :class:`GridFileError` (naming the file) for anything that is not a usable mgrid."""
    p = os.fspath(path)
    data = _load(p)

    def fail(msg: str) -> GridFileError:
        return GridFileError(f"mgrid file {p!r}: {msg}")

    def scalar(name: str, kind: type) -> Any:
        if name not in data:
            raise fail(f"missing variable {name!r}")
        v = np.asarray(data[name][1])
        if v.size != 1:
            raise fail(f"variable {name!r} must be a scalar; has shape {v.shape}")
        v = v.reshape(()).item()
        if kind is int:
            if not float(v).is_integer():
                raise fail(f"variable {name!r} must be an integer; got {v!r}")
            return int(v)
        if not np.isfinite(v):
            raise fail(f"variable {name!r} is not finite ({v!r})")
        return float(v)

    ir, jz, kp = scalar("ir", int), scalar("jz", int), scalar("kp", int)
    nfp, ng = scalar("nfp", int), scalar("nextcur", int)
    if ng < 1:
        raise fail(f"nextcur = {ng} (no coil groups)")
    if nfp < 1:
        raise fail(f"nfp = {nfp} must be ≥ 1")
    rmin, zmin = scalar("rmin", float), scalar("zmin", float)
    rmax, zmax = scalar("rmax", float), scalar("zmax", float)

    def field3(prefix: Sequence[str], g: int) -> np.ndarray | None:
        arrs = []
        for name in (f"{c}_{g + 1:03d}" for c in prefix):
            if name not in data:
                if arrs:  # some components of this group but not all
                    raise fail(f"missing variable {name!r}")
                return None
            a = np.asarray(data[name][1])
            if a.shape != (kp, jz, ir):
                raise fail(f"variable {name!r} has shape {a.shape}; the grid (kp, jz, ir) is "
                           f"{(kp, jz, ir)}")
            arrs.append(np.asarray(a, dtype=np.float64))
        return np.stack(arrs)

    B = []
    for g in range(ng):
        b = field3(_COMPONENTS_B, g)
        if b is None:
            raise fail(f"missing variable {_COMPONENTS_B[0]}_{g + 1:03d} (nextcur = {ng})")
        B.append(b)
    As = [field3(_COMPONENTS_A, g) for g in range(ng)]
    if any(a is None for a in As) and not all(a is None for a in As):
        raise fail("the vector potential (ar_/ap_/az_) is given for some coil groups only")
    A = None if As[0] is None else np.stack(As)

    names = [f"group_{g + 1:03d}" for g in range(ng)]
    if "coil_group" in data:
        names = _names(data["coil_group"][1], ng, fail)
    mode = "N"
    if "mgrid_mode" in data:
        mode = _chars(data["mgrid_mode"][1]).strip() or "N"
        if mode not in _MODES:
            raise fail(f"mgrid_mode = {mode!r}; expected 'S' or 'R'")
    currents = None
    if "raw_coil_cur" in data:
        currents = np.asarray(data["raw_coil_cur"][1], dtype=np.float64).reshape(-1)
        if currents.shape != (ng,):
            raise fail(f"raw_coil_cur has {currents.size} entries for nextcur = {ng}")
    try:
        return MGrid(rmin=rmin, rmax=rmax, zmin=zmin, zmax=zmax, nfp=nfp, B=np.stack(B), A=A,
                     names=names, currents=currents, mode=mode)
    except ValueError as err:
        raise fail(str(err).removeprefix("MGrid: ")) from None


def _chars(a: Any) -> str:
    a = np.asarray(a)
    if a.dtype.kind in "SU":
        parts = [x.decode("latin-1") if isinstance(x, bytes) else str(x) for x in a.ravel()]
        return "".join(parts)
    return "".join(chr(int(x)) for x in a.ravel())


def _names(a: Any, ng: int, fail: Callable[[str], Exception]) -> list[str]:
    a = np.asarray(a)
    if a.ndim <= 1:
        rows = [a]
    elif a.ndim == 2:
        rows = list(a)
    else:
        raise fail(f"coil_group has shape {a.shape}")
    if len(rows) != ng:
        raise fail(f"coil_group has {len(rows)} names for nextcur = {ng}")
    return [_chars(r).replace("\x00", " ").strip() for r in rows]


def _load(path: str) -> dict[str, tuple[tuple[str, ...], np.ndarray]]:
    """Every variable of a netCDF file: name → (dimensions, data copied into memory)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as err:
        raise GridFileError(f"mgrid file {path!r}: cannot be opened ({err.strerror})") from None
    if head[:3] == b"CDF" and head[3:4] in (b"\x01", b"\x02"):
        try:
            with netcdf_file(path, "r", mmap=False) as f:
                return {name: (tuple(v.dimensions), np.array(v.data, copy=True))
                        for name, v in f.variables.items()}
        except Exception as err:  # noqa: BLE001 - scipy raises many kinds on corrupt files
            raise GridFileError(
                f"mgrid file {path!r}: not a readable netCDF file (truncated or corrupt: "
                f"{type(err).__name__}: {err})") from None
    if head == b"\x89HDF\r\n\x1a\n":
        return _load_hdf5(path)
    if head[:3] == b"CDF":
        raise GridFileError(
            f"mgrid file {path!r}: netCDF format version {head[3]} (CDF-5) is not supported by "
            "scipy.io; convert it (nccopy -k classic or -k 64-bit-offset)")
    raise GridFileError(
        f"mgrid file {path!r}: not a netCDF file (it starts with {head!r}, not b'CDF' or the "
        "HDF5 signature)")


def _load_hdf5(path: str) -> dict[str, tuple[tuple[str, ...], np.ndarray]]:
    """A NetCDF4 (HDF5) file through h5netcdf or netCDF4, when one of them is installed."""
    try:
        try:
            import h5netcdf.legacyapi as nc4
        except ImportError:
            import netCDF4 as nc4  # type: ignore[no-redef]
    except ImportError:
        raise GridFileError(
            f"mgrid file {path!r}: a NetCDF4 (HDF5) file; reading it needs h5netcdf or netCDF4 "
            "(pip install h5netcdf), or convert it to NetCDF3 (nccopy -k classic)") from None
    try:
        with nc4.Dataset(path, "r") as f:
            out = {}
            for name, v in f.variables.items():
                if hasattr(v, "set_auto_mask"):
                    v.set_auto_mask(False)
                out[name] = (tuple(v.dimensions), np.array(v[...], copy=True))
            return out
    except Exception as err:  # noqa: BLE001
        raise GridFileError(f"mgrid file {path!r}: not a readable NetCDF4 file "
                            f"({type(err).__name__}: {err})") from None

"""The sampled volume and file I/O: ``Volume``, ``load``.

A ``Volume`` is a numpy array indexed ``[z, y, x]`` (x fastest, as MetaImage/NRRD/NIfTI store voxels) with the
grid geometry: ``spacing`` (x, y, z) in world units per voxel (mm for medical data) and ``origin`` (x, y, z), the
world position of voxel (0, 0, 0). World position of voxel (x, y, z) = origin + spacing * (x, y, z).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Optional, Sequence, Tuple

import numpy as np

from . import _volrig
from ._volrig import VolrigError

Vec3 = Tuple[float, float, float]

#: File name endings each reader handles (longest first matters for ".nii.gz").
FORMATS = {
    ".nii.gz": "nifti", ".nii": "nifti", ".hdr": "nifti",
    ".nrrd": "nrrd", ".nhdr": "nrrd",
    ".mha": "metaimage", ".mhd": "metaimage",
    ".vdb": "vdb",
    ".raw": "raw", ".bin": "raw", ".img": "raw",
}


def _vec3(v, what: str) -> Vec3:
    t = tuple(float(x) for x in (v if np.ndim(v) else (v, v, v)))
    if len(t) != 3 or not all(np.isfinite(t)):
        raise VolrigError(f"{what} must be three finite numbers (x, y, z), got {v!r}")
    return t  # type: ignore[return-value]


def format_of(path: str) -> str:
    """The reader/writer name for ``path`` from its ending (see ``FORMATS``); raises ValueError when unknown."""
    low = os.fspath(path).lower()
    for ending in sorted(FORMATS, key=len, reverse=True):
        if low.endswith(ending):
            return FORMATS[ending]
    raise VolrigError(f"{path}: unknown volume format (known endings: {', '.join(sorted(FORMATS))})")


@dataclass
class Volume:
    """Samples on a regular grid.

    array:   numpy array ``[z, y, x]``.
    spacing: voxel size (x, y, z) in world units (mm for medical scans).
    origin:  world position (x, y, z) of voxel (0, 0, 0).
    path:    the file it was read from, if any.
    """

    array: np.ndarray
    spacing: Vec3 = (1.0, 1.0, 1.0)
    origin: Vec3 = (0.0, 0.0, 0.0)
    path: Optional[str] = field(default=None, compare=False)

    def __post_init__(self):
        self.array = np.asarray(self.array)
        if self.array.ndim != 3:
            raise VolrigError(f"a Volume needs a 3-D array [z, y, x], got shape {self.array.shape}")
        self.spacing = _vec3(self.spacing, "spacing")
        if min(self.spacing) <= 0:
            raise VolrigError(f"spacing must be positive, got {self.spacing}")
        self.origin = _vec3(self.origin, "origin")

    @property
    def dims(self) -> Tuple[int, int, int]:
        """Grid size (x, y, z) in voxels."""
        z, y, x = self.array.shape
        return (x, y, z)

    @property
    def shape(self) -> Tuple[int, int, int]:
        """Array shape (z, y, x)."""
        return self.array.shape  # type: ignore[return-value]

    def world(self, ijk) -> np.ndarray:
        """World positions (N, 3) xyz of voxel indices ``ijk`` (N, 3) given as [z, y, x]."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return ijk[..., ::-1] * np.asarray(self.spacing) + np.asarray(self.origin)

    def like(self, array: np.ndarray) -> "Volume":
        """A Volume with this one's geometry holding ``array`` (same shape)."""
        if array.shape != self.array.shape:
            raise VolrigError(f"shape {array.shape} does not match the volume's {self.array.shape}")
        return Volume(array, self.spacing, self.origin)

    def on_grid(self, origin, dims) -> "Volume":
        """The samples placed on another grid of the same spacing: ``origin`` (x, y, z) and ``dims`` (x, y, z)
        voxels, zero where this volume has no sample. The origins must differ by whole voxels (e.g. a VDB file
        read back, which holds only the bounding box of its non-zero voxels, returned to the grid it was
        written from)."""
        origin = np.asarray(_vec3(origin, "origin"))
        dims = tuple(int(d) for d in dims)
        if len(dims) != 3 or min(dims) < 0:
            raise VolrigError(f"dims must be three sizes (x, y, z), got {dims}")
        shift = (np.asarray(self.origin) - origin) / np.asarray(self.spacing)
        step = np.round(shift)
        if np.abs(shift - step).max() > 1e-3:
            raise VolrigError(f"origin {tuple(origin)} is not a whole number of voxels from {self.origin}")
        out = np.zeros(dims[::-1], dtype=self.array.dtype)
        dst, src = [], []
        for axis, off in enumerate(step.astype(np.int64)[::-1]):  # z, y, x
            n_src, n_dst = self.array.shape[axis], out.shape[axis]
            lo, hi = max(0, off), min(n_dst, off + n_src)
            if hi <= lo:
                return Volume(out, self.spacing, tuple(origin))
            dst.append(slice(lo, hi))
            src.append(slice(lo - off, hi - off))
        out[tuple(dst)] = self.array[tuple(src)]
        return Volume(out, self.spacing, tuple(origin))

    def save(self, path: str, *, compress: bool = True, half: bool = False, grid: str = "density") -> None:
        """Write the volume to ``path``: ``.nrrd`` (gzip when ``compress``), ``.mha`` (zlib when ``compress``)
        or ``.vdb`` (one float grid named ``grid``; half floats when ``half``). Written to a temporary file and
        renamed, so a failed write never leaves a partial file."""
        path = os.fspath(path)
        fmt = format_of(path)
        arr = np.ascontiguousarray(self.array)
        if arr.dtype == np.bool_:
            arr = arr.view(np.uint8)
        if fmt == "nrrd":
            _volrig.write_nrrd(path, arr, self.spacing, self.origin, compress)
        elif fmt == "metaimage":
            if path.lower().endswith(".mhd"):
                raise VolrigError(f"{path}: write MetaImage as a single .mha file")
            _volrig.write_metaimage(path, arr, self.spacing, self.origin, compress)
        elif fmt == "vdb":
            _volrig.write_vdb(path, [(grid, arr)], self.spacing, self.origin, half)
        else:
            raise VolrigError(f"{path}: cannot write {fmt} files (write .nrrd, .mha or .vdb)")

    def __repr__(self) -> str:
        x, y, z = self.dims
        return (f"Volume({x} x {y} x {z} {self.array.dtype}, spacing={self.spacing}, origin={self.origin}"
                + (f", path={self.path!r})" if self.path else ")"))


def load(path: str, *, dims: Optional[Sequence[int]] = None, dtype=None, spacing=(1.0, 1.0, 1.0),
         origin=(0.0, 0.0, 0.0), byte_order: str = "little", offset: int = 0, grid: str = "",
         max_bytes: Optional[int] = None) -> Volume:
    """Read a volume file.

    The format comes from the name: NRRD (``.nrrd``, ``.nhdr``), MetaImage (``.mha``, ``.mhd``), NIfTI-1
    (``.nii``, ``.nii.gz``, ``.hdr``), OpenVDB (``.vdb``) or raw voxels (``.raw``, ``.bin``, ``.img``).

    Raw files need the hints: ``dims`` (x, y, z) in voxels, ``dtype`` (numpy name or type), ``spacing`` and
    ``origin`` (x, y, z, world units), ``byte_order`` ("little" or "big"), ``offset`` (bytes to skip).
    VDB files: ``grid`` names the grid to read (default "density", else the first scalar grid).
    ``max_bytes`` caps the decoded size (default 16 GiB or $VOLRIG_MAX_BYTES).

    Errors: FileNotFoundError when the file is missing; ``volrig.FileFormatError`` (a ValueError) naming the
    file and the problem for anything malformed, before any large allocation.
    """
    path = os.fspath(path)
    fmt = format_of(path) if dims is None else "raw"
    limit = -1 if max_bytes is None else int(max_bytes)
    if fmt == "raw":
        if dims is None or dtype is None:
            raise VolrigError(f"{path}: raw files need dims=(x, y, z) and dtype=...")
        if byte_order not in ("little", "big"):
            raise VolrigError(f"byte_order must be 'little' or 'big', got {byte_order!r}")
        arr, sp, org = _volrig.read_raw(path, tuple(int(d) for d in dims), np.dtype(dtype).name,
                                        _vec3(spacing, "spacing"), _vec3(origin, "origin"),
                                        byte_order == "big", int(offset), limit)
    elif fmt == "vdb":
        arr, sp, org = _volrig.read_vdb(path, grid, limit)
    else:
        arr, sp, org = _volrig.read_volume(path, limit)
    return Volume(arr, sp, org, path=path)


def write_vdb(path: str, grids, spacing=None, origin=None, half: bool = True) -> None:
    """Write several named grids on one geometry to an OpenVDB file.

    grids:   mapping name -> Volume or array [z, y, x] (all the same shape), e.g. {"density": v, "bone": labels}.
             Floating and uint8/bool arrays become float grids, other integer arrays (e.g. int16/int32
             labels) int32 grids; only non-zero voxels are active.
    spacing, origin: (x, y, z) world geometry; taken from the first Volume when omitted.
    half:    store float grids as 16-bit half floats (smaller files, ~3 significant digits).
    The file is written to a temporary name and renamed.
    """
    items = list(grids.items()) if hasattr(grids, "items") else list(grids)
    if not items:
        raise VolrigError(f"{path}: no grids to write")
    first = next((g for _, g in items if isinstance(g, Volume)), None)
    spacing = _vec3(spacing if spacing is not None else (first.spacing if first else 1.0), "spacing")
    origin = _vec3(origin if origin is not None else (first.origin if first else 0.0), "origin")
    arrays = []
    for name, g in items:
        a = np.ascontiguousarray(g.array if isinstance(g, Volume) else np.asarray(g))
        if a.dtype == np.bool_:
            a = a.view(np.uint8)
        arrays.append((str(name), a))
    _volrig.write_vdb(os.fspath(path), arrays, spacing, origin, bool(half))

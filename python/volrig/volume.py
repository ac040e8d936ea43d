"""The sampled volume and file I/O: ``Volume``, ``load``.

A ``Volume`` is a numpy array indexed ``[z, y, x]`` (x fastest, as MetaImage/NRRD/NIfTI store voxels) with the
grid geometry: ``spacing`` (x, y, z) in world units per voxel (mm for medical data), ``origin`` (x, y, z), the
world position of voxel (0, 0, 0), and ``direction`` (3, 3), whose columns are the patient (LPS) directions of
the voxel axes x, y, z (identity by default).

Two frames (docs/DESIGN.md, "Orientation"): the pipeline (skeleton, rig, frames) works in the *grid frame*, where
voxel (x, y, z) sits at origin + spacing * (x, y, z); the patient (LPS) position is
origin + direction @ (spacing * (x, y, z)). ``grid_to_world()`` is the 4x4 matrix from the first to the second,
applied once where results are placed (the add-on's Volume object), so every result agrees with the volume.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import Optional, Sequence, Tuple

import numpy as np

from . import _volrig
from ._volrig import FileFormatError, VolrigError

Vec3 = Tuple[float, float, float]

#: File name endings each reader handles (longest first matters for ".nii.gz").
FORMATS = {
    ".nii.gz": "nifti", ".nii": "nifti", ".hdr": "nifti",
    ".nrrd": "nrrd", ".nhdr": "nrrd",
    ".mha": "metaimage", ".mhd": "metaimage",
    ".vdb": "vdb",
    ".vti": "vti",
    ".tif": "tiff", ".tiff": "tiff",
    ".dcm": "dicom", "dicomdir": "dicom",
    ".raw": "raw", ".bin": "raw", ".img": "raw",
}


def _vec3(v, what: str) -> Vec3:
    t = tuple(float(x) for x in (v if np.ndim(v) else (v, v, v)))
    if len(t) != 3 or not all(np.isfinite(t)):
        raise VolrigError(f"{what} must be three finite numbers (x, y, z), got {v!r}")
    return t  # type: ignore[return-value]


def _direction(d) -> np.ndarray:
    """A (3, 3) float64 direction matrix with orthonormal columns (None: identity)."""
    if d is None:
        return np.eye(3)
    m = np.array(d, dtype=np.float64).reshape(3, 3) if np.size(d) == 9 else None
    if m is None or not np.all(np.isfinite(m)) or not np.allclose(m.T @ m, np.eye(3), atol=1e-3):
        raise VolrigError(f"direction must be a 3x3 matrix with orthonormal columns, got {d!r}")
    return m


def _native_path(path) -> Tuple[str, bytes]:
    """(the name for messages and format detection, the bytes the native core opens): any name the filesystem
    allows, UTF-8 or not (os.fsdecode/os.fsencode); a NUL, which the OS would cut the name at, is refused."""
    text = os.fsdecode(os.fspath(path))
    if "\0" in text:
        raise VolrigError(f"{text.split(chr(0))[0]}...: a file name must not contain a NUL character")
    return text, os.fsencode(text)


def _refuse_special(path) -> None:
    """FileFormatError for a path that exists but is neither a regular file nor a folder (as the native readers)."""
    import stat
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else
                "a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode) else
                "not a regular file")
        raise FileFormatError(f"{os.fsdecode(path)}: {kind}, not a regular file or folder")


def format_of(path: str) -> str:
    """The reader/writer name for ``path`` from its ending (see ``FORMATS``), "folder" for a folder (of DICOM or
    TIFF files), "dicom" for a file with the DICOM preamble; raises VolrigError when unknown."""
    path = os.fspath(path)
    if os.path.isdir(path):
        return "folder"
    low = path.lower()
    for ending in sorted(FORMATS, key=len, reverse=True):
        if low.endswith(ending):
            return FORMATS[ending]
    _refuse_special(path)  # open() would block on a FIFO
    try:
        with open(path, "rb") as f:
            if f.read(132)[128:] == b"DICM":
                return "dicom"
    except OSError:
        pass
    raise VolrigError(f"{path}: unknown volume format (known endings: {', '.join(sorted(FORMATS))}; "
                      "folders of DICOM or TIFF files)")


@dataclass
class Volume:
    """Samples on a regular grid.

    array:   numpy array ``[z, y, x]``.
    spacing: voxel size (x, y, z) in world units (mm for medical scans).
    origin:  world position (x, y, z) of voxel (0, 0, 0).
    path:    the file it was read from, if any.
    direction: (3, 3) matrix whose columns are the LPS directions of the voxel axes (None: identity).
    """

    array: np.ndarray
    spacing: Vec3 = (1.0, 1.0, 1.0)
    origin: Vec3 = (0.0, 0.0, 0.0)
    path: Optional[str] = field(default=None, compare=False)
    direction: Optional[np.ndarray] = field(default=None, compare=False)

    def __post_init__(self):
        self.array = np.asarray(self.array)
        if self.array.ndim != 3:
            raise VolrigError(f"a Volume needs a 3-D array [z, y, x], got shape {self.array.shape}")
        self.spacing = _vec3(self.spacing, "spacing")
        if min(self.spacing) <= 0:
            raise VolrigError(f"spacing must be positive, got {self.spacing}")
        self.origin = _vec3(self.origin, "origin")
        self.direction = _direction(self.direction)

    @property
    def axis_aligned(self) -> bool:
        """True when the direction is the identity (the grid frame is the patient frame)."""
        return bool(np.array_equal(self.direction, np.eye(3)))

    def index_to_world(self) -> np.ndarray:
        """4x4 matrix taking voxel indices (x, y, z, 1) to patient (LPS) positions:
        origin + direction @ (spacing * index)."""
        m = np.eye(4)
        m[:3, :3] = self.direction * np.asarray(self.spacing)  # scales the columns
        m[:3, 3] = self.origin
        return m

    def index_to_grid(self) -> np.ndarray:
        """4x4 matrix taking voxel indices (x, y, z, 1) to the grid frame: origin + spacing * index."""
        m = np.diag([*self.spacing, 1.0])
        m[:3, 3] = self.origin
        return m

    def grid_to_world(self) -> np.ndarray:
        """4x4 matrix taking grid-frame positions (where skeletons, rigs and frames live) to patient (LPS)
        positions; the identity for an axis-aligned volume. It turns about the origin."""
        return self.index_to_world() @ np.linalg.inv(self.index_to_grid())

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
        """Grid-frame positions (N, 3) xyz of voxel indices ``ijk`` (N, 3) given as [z, y, x] (the patient
        positions when the volume is axis-aligned; else see ``patient``)."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return ijk[..., ::-1] * np.asarray(self.spacing) + np.asarray(self.origin)

    def patient(self, ijk) -> np.ndarray:
        """Patient (LPS) positions (N, 3) xyz of voxel indices ``ijk`` (N, 3) given as [z, y, x]."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return (ijk[..., ::-1] * np.asarray(self.spacing)) @ self.direction.T + np.asarray(self.origin)

    def like(self, array: np.ndarray) -> "Volume":
        """A Volume with this one's geometry (direction too) holding ``array`` (same shape)."""
        if array.shape != self.array.shape:
            raise VolrigError(f"shape {array.shape} does not match the volume's {self.array.shape}")
        return Volume(array, self.spacing, self.origin, direction=self.direction)

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
        or ``.vdb`` (one float grid named ``grid``; half floats when ``half``; VDB keeps the grid frame, not the
        direction). NRRD and MetaImage keep the direction. Written to a temporary file and
        renamed, so a failed write never leaves a partial file."""
        path, raw = _native_path(path)
        fmt = format_of(path)
        arr = np.ascontiguousarray(self.array)
        if arr.dtype == np.bool_:
            arr = arr.view(np.uint8)
        d = tuple(float(x) for x in self.direction.ravel())
        if fmt == "nrrd":
            _volrig.write_nrrd(raw, arr, self.spacing, self.origin, compress, d)
        elif fmt == "metaimage":
            if path.lower().endswith(".mhd"):
                raise VolrigError(f"{path}: write MetaImage as a single .mha file")
            _volrig.write_metaimage(raw, arr, self.spacing, self.origin, compress, d)
        elif fmt == "vdb":
            _volrig.write_vdb(raw, [(grid, arr)], self.spacing, self.origin, half)
        else:
            raise VolrigError(f"{path}: cannot write {fmt} files (write .nrrd, .mha or .vdb)")

    def __repr__(self) -> str:
        x, y, z = self.dims
        turned = "" if self.axis_aligned else f", direction={self.direction.round(4).tolist()}"
        return (f"Volume({x} x {y} x {z} {self.array.dtype}, spacing={self.spacing}, origin={self.origin}"
                + turned + (f", path={self.path!r})" if self.path else ")"))


def _source_array(source: Volume) -> np.ndarray:
    """The array the core reads from a source volume: C-contiguous, bool as uint8 (deform's and rigid_layer's)."""
    if not isinstance(source, Volume):
        raise TypeError(f"source must be a volrig.Volume, got {type(source).__name__}")
    a = source.array
    if a.dtype == np.bool_:
        a = a.view(np.uint8)
    return np.ascontiguousarray(a)


def load(path: str, *, dims: Optional[Sequence[int]] = None, dtype=None, spacing=None,
         origin=(0.0, 0.0, 0.0), byte_order: str = "little", offset: int = 0, grid: str = "",
         max_bytes: Optional[int] = None, series: str = "", crop=None) -> Volume:
    """Read a volume file or folder.

    The format comes from the name: NRRD (``.nrrd``, ``.nhdr``), MetaImage (``.mha``, ``.mhd``), NIfTI-1
    (``.nii``, ``.nii.gz``, ``.hdr``), OpenVDB (``.vdb``), TIFF stacks (``.tif``, ``.tiff``: every page a slice),
    DICOM (``.dcm``, a ``DICOMDIR``, any file with the DICOM preamble) or raw voxels (``.raw``, ``.bin``,
    ``.img``); a folder is read as one DICOM series, or as a TIFF stack (files in natural order) when it holds
    only TIFF files. NRRD, MetaImage, NIfTI and DICOM keep the orientation (``Volume.direction``, LPS).

    Raw files need the hints: ``dims`` (x, y, z) in voxels, ``dtype`` (numpy name or type), ``spacing`` and
    ``origin`` (x, y, z, world units), ``byte_order`` ("little" or "big"), ``offset`` (bytes to skip).
    VDB files: ``grid`` names the grid to read (default "density", else the first scalar grid); ``crop``
    ((x0, y0, z0), (x1, y1, z1)), the grid's index coordinates, inclusive, reads only that box of it (met with the
    active voxels' bounding box, which ``vdb_grids`` gives): for a sparse grid too large to read densely.
    DICOM: ``series`` picks a SeriesInstanceUID (default: the series with most slices; ``dicom_series`` lists
    them). Slice spacing that jitters is averaged with a ``UserWarning`` saying so.
    TIFF: ``spacing`` (x, y, z), a component 0 or None taken from the file (x, y from its resolution, z = x).
    ``max_bytes`` caps the decoded size (default 16 GiB or $VOLRIG_MAX_BYTES).

    Errors: FileNotFoundError when the file is missing; ``volrig.FileFormatError`` (a ValueError) naming the
    file and the problem for anything malformed, before any large allocation.
    """
    path, raw = _native_path(path)
    fmt = format_of(path) if dims is None else "raw"
    limit = -1 if max_bytes is None else int(max_bytes)
    if crop is not None and fmt != "vdb":
        raise VolrigError(f"{path}: crop= applies to VDB files only")
    if fmt == "raw":
        if dims is None or dtype is None:
            raise VolrigError(f"{path}: raw files need dims=(x, y, z) and dtype=...")
        if byte_order not in ("little", "big"):
            raise VolrigError(f"byte_order must be 'little' or 'big', got {byte_order!r}")
        arr, sp, org = _volrig.read_raw(raw, tuple(int(d) for d in dims), np.dtype(dtype).name,
                                        _vec3(1.0 if spacing is None else spacing, "spacing"),
                                        _vec3(origin, "origin"),
                                        byte_order == "big", int(offset), limit)
    elif fmt == "vdb":
        arr, sp, org = _volrig.read_vdb(raw, grid, limit, _index_box(crop))
    else:
        given = (0.0, 0.0, 0.0) if spacing is None else tuple(
            0.0 if x is None else float(x) for x in (spacing if np.ndim(spacing) else (spacing,) * 3))
        arr, sp, org, d, said = _volrig.read_volume(raw, limit, str(series), given)
        for w in said:
            warnings.warn(w, stacklevel=2)
        return Volume(arr, sp, org, path=path, direction=np.asarray(d).reshape(3, 3))
    return Volume(arr, sp, org, path=path)


def vdb_grids(path: str) -> list:
    """The grids of an OpenVDB file, without reading their voxels: dicts with ``name``, ``type``, ``bbox_min`` and
    ``bbox_max`` (the active voxels' bounding box, index coordinates x, y, z, inclusive: what ``load``'s ``crop``
    takes) and ``active_voxels``."""
    return _volrig.vdb_grids(_native_path(path)[1])


def _index_box(crop):
    """``crop`` as ((x0, y0, z0), (x1, y1, z1)) whole numbers, or None."""
    if crop is None:
        return None
    try:
        box = np.asarray(crop, dtype=np.float64)
    except (TypeError, ValueError):
        box = None
    if box is None or box.shape != (2, 3) or not np.all(np.isfinite(box)) or np.any(box != np.round(box)):
        raise VolrigError(f"crop must be ((x0, y0, z0), (x1, y1, z1)) in whole index coordinates, got {crop!r}")
    return tuple(tuple(int(v) for v in row) for row in box)


def dicom_series(path: str) -> list:
    """The DICOM image series under a folder, DICOMDIR or file, the largest first: dicts with ``uid``,
    ``description``, ``modality``, ``dims`` (columns, rows, slices) and ``files``. What the folder walk skipped
    (dangling links, FIFOs, sockets, link loops, unreadable folders) is told as warnings, as ``load`` tells it."""
    series, said = _volrig.dicom_series(_native_path(path)[1])
    for w in said:
        warnings.warn(w, stacklevel=2)
    return series


def write_vdb(path: str, grids, spacing=None, origin=None, half: bool = True, labels=(), metadata=None) -> None:
    """Write several named grids on one geometry to an OpenVDB file.

    grids:   mapping name -> Volume or array [z, y, x], e.g. {"density": v, "bone": labels}. Floating (float16
             too) and uint8/bool arrays become float grids, other integer arrays (e.g. int16/int32 labels) int32 grids;
             only non-zero voxels are active. A Volume lies at its own origin (a grid cropped to its voxels), a
             whole number of voxels from the others (one voxel lattice); an array at ``origin``.
    spacing, origin: (x, y, z) world geometry; taken from the first Volume when omitted.
    half:    store float grids as 16-bit half floats (smaller files, ~3 significant digits).
    labels:  names of integer grids that are labels: int32 grids whatever their dtype, uint8 too (a bake's frame
             holds its bone labels as bytes).
    metadata: {name: str} written as the file's metadata (``vdb_metadata`` reads it back), e.g. a bake's tissue
             classes (``volrig.tissues.METADATA``).
    The file is written to a temporary name and renamed.
    """
    _volrig.write_vdb(*_vdb_arguments(path, grids, spacing, origin, half, labels, metadata))


def build_vdb(path: str, grids, spacing=None, origin=None, half: bool = True, labels=(), metadata=None):
    """``write_vdb`` in two steps: the grids built now (checked as ``write_vdb`` checks them; ``path`` names the
    file in errors), written by ``.write(path)`` later, say on another thread once the arrays are gone (a bake's
    frame goes back to its Deformer as soon as its grids are built). The grids are freed once written."""
    return _volrig.build_vdb(*_vdb_arguments(path, grids, spacing, origin, half, labels, metadata))


def _vdb_arguments(path, grids, spacing, origin, half, labels, metadata=None):
    items = list(grids.items()) if hasattr(grids, "items") else list(grids)
    if not items:
        raise VolrigError(f"{path}: no grids to write")
    first = next((g for _, g in items if isinstance(g, Volume)), None)
    spacing = _vec3(spacing if spacing is not None else (first.spacing if first else 1.0), "spacing")
    origin = _vec3(origin if origin is not None else (first.origin if first else 0.0), "origin")
    arrays, origins = [], []
    for name, g in items:
        a = np.ascontiguousarray(g.array if isinstance(g, Volume) else np.asarray(g))
        if a.dtype == np.bool_:
            a = a.view(np.uint8)
        arrays.append((str(name), a))
        origins.append(_vec3(g.origin, "origin") if isinstance(g, Volume) else origin)
    meta = [(str(k), str(v)) for k, v in (metadata or {}).items()]
    return _native_path(path)[1], arrays, spacing, origin, bool(half), origins, [str(n) for n in labels], meta


#: The OpenVDB file versions whose header ``vdb_metadata`` reads (OpenVDB 3 on: per-grid compression).
_VDB_VERSIONS = (222, 1000)


def vdb_metadata(path: str) -> dict:
    """The OpenVDB file's string metadata ({name: str}; entries of other types left out), from its header only
    (what ``write_vdb(..., metadata=)`` wrote). Raises ``FileFormatError`` on a file that is not OpenVDB."""
    import struct
    with open(_native_path(path)[1], "rb") as f:
        head = f.read(8 + 12 + 1 + 36)
        if len(head) < 57 or struct.unpack_from("<q", head)[0] != 0x56444220:
            raise FileFormatError(f"{path}: not an OpenVDB file")
        version = struct.unpack_from("<I", head, 8)[0]
        if not _VDB_VERSIONS[0] <= version < _VDB_VERSIONS[1]:
            raise FileFormatError(f"{path}: OpenVDB file version {version}: metadata not read")

        def chunk(limit=1 << 24) -> bytes:
            raw = f.read(4)
            n = struct.unpack("<I", raw)[0] if len(raw) == 4 else -1
            data = f.read(n) if 0 <= n <= limit else b""
            if n < 0 or n > limit or len(data) != n:
                raise FileFormatError(f"{path}: truncated or corrupt OpenVDB file metadata")
            return data

        raw = f.read(4)
        count = struct.unpack("<i", raw)[0] if len(raw) == 4 else -1
        if not 0 <= count < 1 << 16:
            raise FileFormatError(f"{path}: corrupt OpenVDB file metadata ({count} entries)")
        out = {}
        for _ in range(count):
            name, kind, value = chunk(), chunk(), chunk()
            if kind == b"string":
                out[name.decode("utf-8", "replace")] = value.decode("utf-8", "replace")
        return out

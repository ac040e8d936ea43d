"""The scan behind each volrig Volume object: its cache folder on disk and, in memory for this Blender session,
its samples, mask and skeleton.

The cache folder sits beside the .blend (``<blend name>_volrig/<object>/``; a temporary folder while the file is
unsaved) and holds ``source.vdb`` (the imported samples as float32, the grid the object shows before baking), the
``.vrig`` rig files and the baked ``frames/``. The user's source file is only ever read.

The skeleton is computed once per segmentation and metric and kept here, keyed by the cache folder (one per
import, so another file's object of the same name never sees this one's data), so
the thinness slider re-thresholds it instantly. Entries are checked against the settings they were made with, so
undo and redo never show a stale one; after reopening a .blend they are rebuilt from the cache folder on demand.
"""
import json
import os
import tempfile

import bpy
import numpy as np

import volrig
from volrig import pipeline

_memory = {}  # cache folder -> {"source": Volume, "mask": (settings, Volume), "skeleton": (settings, Skeleton)}


def _entry(volume_obj) -> dict:
    return _memory.setdefault(bpy.path.abspath(volume_obj.volrig.cache_dir), {})


@bpy.app.handlers.persistent
def forget_all(*_args) -> None:
    """Drops every scan held in memory (on loading a .blend: its objects rebuild theirs from their caches)."""
    _memory.clear()


def cache_root() -> str:
    """The folder new caches go to: beside the saved .blend (as a Blender-relative path), else a temp folder."""
    if bpy.data.filepath:
        stem = os.path.splitext(os.path.basename(bpy.data.filepath))[0]
        return "//" + stem + "_volrig"
    return os.path.join(tempfile.gettempdir(), f"volrig_{os.getpid()}")


def cache_dir(volume_obj) -> str:
    """Absolute path of the object's cache folder (created if missing)."""
    path = bpy.path.abspath(volume_obj.volrig.cache_dir)
    if not volume_obj.volrig.cache_dir:
        raise volrig.VolrigError(f"{volume_obj.name} has no volrig cache folder (import it with volrig)")
    os.makedirs(path, exist_ok=True)
    return path


def source_path(volume_obj) -> str:
    return os.path.join(cache_dir(volume_obj), "source.vdb")


def rig_path(volume_obj) -> str:
    """Absolute path of the object's current .vrig file; VolrigError when it has not been rigged."""
    s = volume_obj.volrig
    if not s.rig_file:
        raise volrig.VolrigError(f"{volume_obj.name} has no rig yet: press Rig first")
    return os.path.join(cache_dir(volume_obj), s.rig_file)


def remember_source(volume_obj, volume: volrig.Volume) -> None:
    entry = _entry(volume_obj)
    entry.clear()
    entry["source"] = volume


def write_source(folder: str, volume: volrig.Volume, source_file: str = "") -> str:
    """Write ``volume`` (float32 samples) into a cache folder: source.vdb and source.json, the exact grid (Blender's
    float properties are single precision, the rig file's geometry is not); returns the VDB's path."""
    from volrig.files import atomic_output
    vdb = os.path.join(folder, "source.vdb")
    volrig.write_vdb(vdb, {"density": volume}, half=False)
    with atomic_output(os.path.join(folder, "source.json")) as tmp:
        with open(tmp, "w") as f:
            json.dump({"dims": list(volume.dims), "spacing": list(volume.spacing), "origin": list(volume.origin),
                       "source": source_file}, f, indent=1)
    return vdb


def source(volume_obj) -> volrig.Volume:
    """The samples (float32) on the grid they were imported with, from memory or the cache's source.vdb."""
    entry = _entry(volume_obj)
    v = entry.get("source")
    if v is None:
        path = source_path(volume_obj)
        try:
            with open(os.path.join(os.path.dirname(path), "source.json")) as f:
                grid = json.load(f)
        except (OSError, ValueError) as e:
            raise FileNotFoundError(f"{os.path.dirname(path)}: the cached source of {volume_obj.name} is missing or "
                                    f"damaged ({e}); import {volume_obj.volrig.source or 'the volume'} again") from None
        v = volrig.load(path).on_grid(grid["origin"], grid["dims"])
        v = volrig.Volume(v.array, tuple(grid["spacing"]), tuple(grid["origin"]))
        entry.clear()
        entry["source"] = v
    return v


def _segmentation(s) -> pipeline.Segmentation:
    if s.segment_by == "LABELS":
        return pipeline.Segmentation.of_labels(s.labels, largest=bool(s.largest))
    return pipeline.Segmentation(lo=float(s.low), hi=float(s.high), largest=bool(s.largest))


def segmentation_key(volume_obj) -> pipeline.Segmentation:
    """The object's segmentation settings (hashable; VolrigError when they are invalid)."""
    return _segmentation(volume_obj.volrig)


def mask(volume_obj) -> volrig.Volume:
    """The segmentation mask for the object's current settings (computed once per setting)."""
    key = _segmentation(volume_obj.volrig)
    entry = _entry(volume_obj)
    cached = entry.get("mask")
    if cached is None or cached[0] != key:
        entry["mask"] = cached = (key, key.mask(source(volume_obj), name=volume_obj.name))
        entry.pop("skeleton", None)
    return cached[1]


def skeleton(volume_obj, progress=None, compute: bool = True):
    """The skeleton (scores sorted once) for the current segmentation and metric; None when not computed yet and
    ``compute`` is False."""
    s = volume_obj.volrig
    entry = _entry(volume_obj)
    try:
        key = (_segmentation(s), s.metric)
    except volrig.VolrigError:
        return None
    cached = entry.get("skeleton")
    if cached is not None and cached[0] == key:
        return cached[1]
    if not compute:
        return None
    sk = pipeline.skeleton_of(mask(volume_obj), s.metric, progress=progress)
    entry["skeleton"] = (key, sk)
    return sk


def thinness(volume_obj) -> float:
    """The skeleton's thinness TP for the slider's value (in voxels)."""
    s = volume_obj.volrig
    return pipeline.thinness_from_voxels(s.thinness, s.metric, s.spacing)


def update_mask_count(volume_obj) -> None:
    """The live object-voxel count shown under the segmentation settings (thresholds only: the largest-part filter
    applies when skeletonizing). -1 when the settings are invalid or the source is unavailable."""
    s = volume_obj.volrig
    try:
        s.mask_count = _segmentation(s).count(source(volume_obj).array)
    except (volrig.VolrigError, OSError):
        s.mask_count = -1


def rigid(volume_obj):
    """The tissue that must not bend (``volrig.rigid_tissue`` of the source), by the object's *Rigid tissue*
    setting: the tissue table's bone class (Automatic, when the object has a table), the given labels or value
    range, or None. VolrigError when the labels or range hold no voxel of the source."""
    s = volume_obj.volrig
    source_ = source(volume_obj)
    if s.rigid_by == "NONE" or (s.rigid_by == "AUTO" and not s.tissue_table):
        return None
    if s.rigid_by == "AUTO":
        table = volrig.read_tissue_table(bpy.path.abspath(s.tissue_table))
        bone = [t for t in volrig.tissue_classes(table, present=np.unique(source_.array)) if t.name == "bone"]
        if not bone:
            return None
        out, what = volrig.rigid_tissue(source_, labels=bone[0].codes), f"the table's bone codes {bone[0].codes}"
    elif s.rigid_by == "LABELS":
        labels = volrig.pipeline.parse_labels(s.rigid_labels)
        out, what = volrig.rigid_tissue(source_, labels=labels), f"labels {s.rigid_labels!r}"
    else:
        out = volrig.rigid_tissue(source_, value_range=(s.rigid_low, s.rigid_high))
        what = f"values {s.rigid_low:g} to {s.rigid_high:g}"
    if not out.array.any():
        raise volrig.VolrigError(f"rigid tissue: no voxel of {volume_obj.name} has {what}")
    return out

"""The one pipeline from a volume file to baked frames, shared by the command line, the Blender add-on and the demo.

    load_source -> import_defaults (label map? value window, density) -> Segmentation.mask -> skeletonize
    -> skeleton_points -> rig_skeleton (skeleton-tree, autorig, bind) -> save_rig
    -> pose matrices per frame (mocap_poses, or Blender's armature) -> FolderBake.bake (Deformer -> <stem>_NNNN.vdb)

Every step here has exactly one implementation: ``python -m volrig rig / bake-mocap``, the add-on's operators and
``volrig.demo`` call these functions and add only their own input and output (argument parsing, progress bars,
Blender objects). User mistakes raise ``volrig.VolrigError`` (a ``ValueError``) or ``OSError`` with a message to
show as it is; anything else is a bug.
"""
from __future__ import annotations

import concurrent.futures
import hashlib
import json
import os
import re
import time
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

from ._volrig import VolrigError
from .bones import separated
from .deform import DEFORM_REVISION, Deformer
from .files import atomic_output
from .mesh import MESH_EXTENSIONS, ProgressFn, voxelize
from .parts import part_grids, substitute_grid
from .tissues import GRID as TISSUE_GRID
from .tissues import classes_metadata, tissue_grid
from .rig import Binding, Rig, autorig_fit, bind, rest_pose
from .rigfile import RiggedSkeleton, load_rig
from .segment import check_range, segment
from .skeleton import Skeleton, SkeletonPoints, skeletonize
from .skin import MESH_VOXELS, SKIN_BLEND, MeshRig, _points, _span, mesh_voxel_size, skin_weights
from .tree import _mask_for, skeleton_tree
from .volume import Volume, format_of, load, write_vdb

#: progress(step, fraction) -> False cancels; step is one of STEPS.
StepProgress = Optional[Callable[[str, float], Optional[bool]]]
#: The steps reporting progress, in order.
STEPS = ("skeletonize", "skeleton-tree", "autorig", "bind")


def _step(progress: StepProgress, name: str):
    """A volrig progress callback reporting ``name``'s fraction to a StepProgress (None when there is none)."""
    if progress is None:
        return None
    return lambda f: progress(name, f)


# ---- import -----------------------------------------------------------------------------------------------------

def load_source(path: str, *, dims: Optional[Sequence[int]] = None, dtype=None, spacing=(1.0, 1.0, 1.0),
                big_endian: bool = False, offset: int = 0, grid: str = "", series: str = "",
                tiff_spacing=None, crop=None) -> Volume:
    """``volrig.load`` with the hints the command line and the import dialog take: with ``dims`` the file is read
    as raw voxels of ``dtype``; a raw file (.raw .bin .img) without them is refused. ``series``: the DICOM
    series; ``tiff_spacing``: TIFF spacing (x, y, z), 0 = from the file; ``crop``: a VDB's index box (``load``)."""
    if dims is None:
        if format_of(path) == "raw":
            raise VolrigError(f"{os.path.basename(path)}: a raw file needs its size in voxels (x, y, z) and its "
                              "element type")
        return load(path, grid=grid, series=series, spacing=tiff_spacing, crop=crop)
    if not dtype:
        raise VolrigError(f"{os.path.basename(path)}: a raw file needs its element type besides its size")
    return load(path, dims=tuple(int(d) for d in dims), dtype=dtype, spacing=spacing,
                byte_order="big" if big_endian else "little", offset=offset)


def float_samples(volume: Volume) -> Volume:
    """The samples as float32 with NaN and infinities set to 0 (what a VDB grid for Blender holds)."""
    samples = volume.array.astype(np.float32, copy=False)
    finite = np.isfinite(samples)
    if not finite.all():
        samples = np.where(finite, samples, np.float32(0))
    return volume.like(samples)  # the geometry, orientation included


def looks_like_labels(array: np.ndarray) -> bool:
    """A label map: a few small non-negative integers numbered from about 1 up (not a scan's intensity levels).
    Judged on every 32nd slice along z."""
    if not array.size:
        return False
    some = np.unique(array[:: max(1, array.shape[0] // 32)])
    some = some[np.isfinite(some)] if some.dtype.kind == "f" else some
    return bool(0 < len(some) <= 64 and some.min() >= 0 and np.array_equal(some, np.round(some))
                and 3 < some.max() <= 2 * len(some) + 8)


@dataclass(frozen=True)
class ImportDefaults:
    """The settings an imported volume starts with."""
    value_min: float
    value_max: float
    low: float           #: segmentation range: the 5th percentile of the non-zero samples ...
    high: float          #: ... up to the maximum
    label_map: bool      #: segment by labels, sample nearest, colour per label
    labels: str          #: "1-N" for label maps, else ""
    sampling: str        #: "nearest" for label maps, else "trilinear"
    density_scale: float  #: render density per scene unit: 40 / the largest extent in scene units


def import_defaults(volume: Volume, unit_scale: float = 1.0) -> ImportDefaults:
    """Import heuristics: the value window, whether the volume is a label map, and a density that makes the
    object about equally opaque whatever its size (``unit_scale``: scene units per volume unit)."""
    a = volume.array
    lo, hi = (float(a.min()), float(a.max())) if a.size else (0.0, 1.0)
    nonzero = a[a != 0]
    labels = looks_like_labels(a)
    extent = float(max(np.asarray(volume.dims) * np.asarray(volume.spacing))) * unit_scale
    return ImportDefaults(value_min=lo, value_max=hi, low=float(np.percentile(nonzero, 5)) if nonzero.size else 1.0,
                          high=hi, label_map=labels, labels=f"1-{int(hi)}" if labels else "",
                          sampling="nearest" if labels else "trilinear",
                          density_scale=round(40.0 / max(extent, 1e-6), 3))


# ---- segmentation -----------------------------------------------------------------------------------------------

def _ranges(text: str, what: str, example: str):
    """(part, first, last) for each 'N' or 'A-B' of ``text`` (separated by spaces, commas or semicolons);
    VolrigError naming a part that is neither."""
    for part in re.split(r"[\s,;]+", text.strip()):
        if not part:
            continue
        m = re.fullmatch(r"(-?\d+)(?:-(-?\d+))?", part)
        if not m:
            raise VolrigError(f"{what}: {part!r} is not {example}")
        yield part, int(m.group(1)), int(m.group(2) or m.group(1))


def labels_text(labels) -> str:
    """[1, 2, 3, 7, 9, 10] -> '1-3, 7, 9-10' (what ``parse_labels`` reads back)."""
    out, run = [], []
    for v in sorted({int(x) for x in labels}):
        if run and v == run[-1] + 1:
            run.append(v)
            continue
        if run:
            out.append(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]))
        run = [v]
    if run:
        out.append(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]))
    return ", ".join(out)


def parse_labels(text: str) -> List[int]:
    """'1 4 7-9' -> [1, 4, 7, 8, 9] (commas and semicolons separate too); VolrigError naming the bad part."""
    out: List[int] = []
    for part, a, b in _ranges(text, "labels", "a number or a range like 7-9"):
        if b < a or b - a > 100000:
            raise VolrigError(f"labels: bad range {part!r}")
        out.extend(range(a, b + 1))
    if not out:
        raise VolrigError("labels: none given")
    return out


@dataclass(frozen=True)
class Segmentation:
    """What is object: values in [lo, hi] (either may be None) and/or one of ``labels``; ``largest`` keeps the
    largest 26-connected part. Hashable, so a cache can key on it; invalid settings raise at construction."""
    lo: Optional[float] = None
    hi: Optional[float] = None
    labels: Optional[Tuple[int, ...]] = None
    largest: bool = False

    def __post_init__(self):
        check_range(self.lo, self.hi)
        if self.labels is not None:
            object.__setattr__(self, "labels", tuple(int(x) for x in self.labels))

    @classmethod
    def of_labels(cls, text: str, largest: bool = False) -> "Segmentation":
        return cls(labels=tuple(parse_labels(text)), largest=largest)

    def mask(self, volume: Volume, name: str = "the volume") -> Volume:
        """The object mask; VolrigError when it is empty."""
        m = segment(volume, lo=self.lo, hi=self.hi, labels=self.labels, largest_component=self.largest)
        if not m.array.any():
            raise VolrigError(f"{name}: the segmentation is empty (check the value range or the labels)")
        return m

    def count(self, array: np.ndarray) -> int:
        """Object voxels by the value criteria alone (fast, for a live count: ``largest`` is not applied)."""
        keep = np.ones(array.shape, bool) if self.labels is None else np.isin(array, self.labels)
        if self.lo is not None:
            keep &= array >= self.lo
        if self.hi is not None:
            keep &= array <= self.hi
        if self.lo is None and self.hi is None and self.labels is None:
            keep &= array != 0
        return int(np.count_nonzero(keep))


def load_mask(path: str, segmentation: Segmentation, voxel_size: Optional[float] = None,
              voxelize_method: str = "auto", **hints) -> Volume:
    """The object mask of a file: a mesh (``volrig.mesh.MESH_EXTENSIONS``) voxelized at ``voxel_size`` (default
    ``volrig.skin.mesh_voxel_size``: the bounding box's longest side / 160, as ``rig_mesh`` and the add-on) by
    ``voxelize_method`` (``voxelize``'s method: "auto" adds the winding number's solid for meshes that are not
    closed),
    else the volume (``hints`` as for ``load_source``) segmented."""
    if path.lower().endswith(MESH_EXTENSIONS):
        from .mesh import read_mesh, voxelize
        from .skin import mesh_voxel_size
        vertices, faces = read_mesh(path)
        if voxel_size is None:
            voxel_size = mesh_voxel_size(vertices)
        return voxelize(vertices, faces, voxel_size, method=voxelize_method)
    return segmentation.mask(load_source(path, **hints), name=path)


# ---- skeleton ---------------------------------------------------------------------------------------------------

def skeleton_of(mask: Volume, metric: str = "euclidean", progress: StepProgress = None) -> Skeleton:
    """The skeleton (thinness scores sorted once) of a mask."""
    return skeletonize(mask, metric, progress=_step(progress, "skeletonize"))


def skeleton_points(skeleton: Skeleton, thinness: Optional[float] = None, count: Optional[int] = None) \
        -> SkeletonPoints:
    """The points at ``thinness`` or the ``count`` highest-scoring ones (exactly one of the two)."""
    if (thinness is None) == (count is None):
        raise VolrigError("give a thinness or a point count (one of the two)")
    return skeleton.top(count) if count is not None else skeleton.at(thinness)


DEFAULT_THINNESS_VOXELS = 0.5  # the thinness when none is given (the add-on's slider, rig_mesh, the CLI), in voxels


def thinness_from_voxels(value: float, metric: str, spacing) -> float:
    """The thinness TP of a value in voxels (the add-on's slider): a Euclidean score is in world units (TP = value
    * the smallest spacing), a chamfer score in grid steps (TP = value)."""
    return float(value) * (min(spacing) if metric == "euclidean" else 1.0)


def voxels_from_thinness(tp: float, metric: str, spacing) -> float:
    """The inverse of ``thinness_from_voxels``."""
    return float(tp) / (min(spacing) if metric == "euclidean" else 1.0)


# ---- rig --------------------------------------------------------------------------------------------------------

def rig_skeleton(points: SkeletonPoints, mask: Volume, *, alpha: float = 0.9, max_edge: Optional[float] = None,
                 bones: Optional[int] = None, roles: bool = True, bind_mode: str = "smooth",
                 progress: StepProgress = None, source: Optional[str] = None, kind: Optional[str] = None,
                 up=None, own_scale: bool = True, rigid: Optional[Volume] = None,
                 bone: Optional[Volume] = None, markers: Optional[dict] = None, plan_weights=None,
                 detail: Optional[list] = None) -> RiggedSkeleton:
    """Skeleton-tree, automatic armature and binding of ``points`` (what ``save_rig`` writes). ``kind`` forces a
    template (humanoid, quadruped, winged, hand, chains), ``up`` gives the world's up direction in the volume's frame,
    ``own_scale=False`` rigs ``points`` themselves rather than autorig's own skeleton (see ``autorig``) and ``rigid``
    is tissue that must not bend (``bind(..., rigid=)``); ``markers`` ({name: point}, see ``autorig``) guide the body
    plan and place the marked joints; ``plan_weights`` and ``detail`` go to ``autorig``. ``bone``: the scan's bone
    tissue, whose articulations then place the limb joints (``autorig(..., bone=)``); with ``rigid`` too, the bone's
    rigid tissue is split into its segments (``volrig.bones.separated``) so that each segment binds wholly to one
    rig bone. Fewer than two points are refused by autorig (lower the thinness)."""
    tree = skeleton_tree(points, mask, alpha=alpha, max_edge=max_edge, progress=_step(progress, "skeleton-tree"))
    rig, fit = autorig_fit(points, tree, mask, bones=bones, roles=roles, progress=_step(progress, "autorig"), kind=kind,
                           up=up, own_scale=own_scale, markers=markers, plan_weights=plan_weights, detail=detail,
                           bone=bone)
    if fit is not None and rigid is not None:
        bone_arr, rigid_arr = _mask_for(points, bone) != 0, _mask_for(points, rigid) != 0
        rigid = (rigid_arr & ~bone_arr) | (separated(fit.segments, bone_arr) & rigid_arr)
    binding = bind(points, rig, mask, mode=bind_mode, progress=_step(progress, "bind"), rigid=rigid)
    if bone is not None and binding.rigid is not None:
        binding.rigid_whole = True  # each segment moves whole with one bone
    return RiggedSkeleton(points, tree, rig, binding, source)


#: A mesh whose skeleton's median radius is under this many voxels (a stick figure, a wire character) is voxelized
#: finer by ``rig_mesh``, up to ``MAX_MESH_VOXELS`` along its longest side: at 1 voxel its limbs break apart and
#: no body plan can be read.
MIN_RADIUS_VOXELS = 2.0
#: autorig's own scale (kCoarseCells in native/src/rig/autorig/coarse.hpp): finer voxels would be resampled away.
MAX_MESH_VOXELS = 400
#: A finer voxelization is held to about this many object voxels (their count grows at most with the cube of the
#: refinement): thin limbs (few voxels) get all of it, a thin sheet of many voxels (a wing) little, so the skin
#: weights' geodesics and the voxelization stay within a few seconds.
MAX_REFINED_OBJECT_VOXELS = 400_000


def _finer_voxels(pts, size: float, voxels: int, min_radius: float, object_voxels: int) -> Optional[int]:
    """The voxel count along the longest side that makes the skeleton's median radius ``min_radius`` voxels, when
    the one used (``voxels``, of ``size``, giving ``object_voxels``) leaves it thinner; None when it is thick enough
    or cannot be refined. A median of one voxel or less says only that the parts are unresolved: as fine as
    ``MAX_MESH_VOXELS`` and ``MAX_REFINED_OBJECT_VOXELS`` allow then."""
    median = float(np.median(pts.radii)) / size if len(pts) else 0.0
    if not min_radius > 0 or median >= min_radius or voxels >= MAX_MESH_VOXELS:
        return None
    want = MAX_MESH_VOXELS if median <= 1.0 + 1e-6 else np.ceil(voxels * min_radius / median)
    room = voxels * (MAX_REFINED_OBJECT_VOXELS / max(object_voxels, 1)) ** (1 / 3)
    finer = int(min(MAX_MESH_VOXELS, want, room))
    return finer if finer >= 1.25 * voxels else None


def mesh_skeleton(vertices, faces, voxel_size: Optional[float] = None, *, voxels: int = MESH_VOXELS,
                  thinness: Optional[float] = None, voxelize_method: str = "auto",
                  min_radius_voxels: float = MIN_RADIUS_VOXELS, progress: ProgressFn = None, staged=None,
                  lattice_phase=None):
    """``rig_mesh``'s first steps: (mask, voxel size, Skeleton, skeleton points at ``thinness`` voxels): the mesh
    voxelized at ``voxel_size`` (default its longest side / ``voxels``; voxelized once more, finer, when its
    skeleton's median radius comes out under ``min_radius_voxels``: ``_finer_voxels``) and skeletonized.
    ``progress`` follows the voxelization, ``staged(step, fraction)`` the skeletonization. ``lattice_phase``
    (x, y, z), fractions of a voxel: the lattice moved by that much from its place (voxel centres half a voxel in
    from the bounding box's low corner), to measure how a result depends on where the samples fall."""
    thinness = DEFAULT_THINNESS_VOXELS if thinness is None else thinness
    v, f = _points(vertices), np.asarray(faces)
    size = mesh_voxel_size(v, voxels) if voxel_size is None else float(voxel_size)
    for attempt in range(2):  # once more, finer, when the parts came out too thin
        anchor = None if lattice_phase is None else v.min(0) + (0.5 + np.asarray(lattice_phase, float)) * size
        mask = voxelize(v, f, size, progress=progress, method=voxelize_method, anchor=anchor)
        sk = skeleton_of(mask, progress=staged)
        pts = skeleton_points(sk, thinness=thinness_from_voxels(thinness, sk.metric, mask.spacing))
        finer = None if voxel_size is not None or attempt else _finer_voxels(pts, size, voxels, min_radius_voxels,
                                                                           int(np.count_nonzero(mask.array)))
        if finer is None:
            break
        voxels, size = finer, mesh_voxel_size(v, finer)
    return mask, size, sk, pts


def rig_mesh(vertices, faces, voxel_size: Optional[float] = None, *, voxels: int = MESH_VOXELS,
             thinness: Optional[float] = None, influences: int = 4, blend: float = SKIN_BLEND,
             progress: ProgressFn = None, skin_points=None, voxelize_method: str = "auto",
             min_radius_voxels: float = MIN_RADIUS_VOXELS, **autorig_options) -> MeshRig:
    """Rig and skin a triangle mesh through its volume: voxelize (``voxel_size``, default the bounding box's longest
    side / ``voxels``), skeletonize, skeleton points at ``thinness`` (in voxels, as the add-on's slider; default
    ``DEFAULT_THINNESS_VOXELS``, half a voxel), autorig
    (``autorig_options``: kind=, up=, bones=, roles=... as ``volrig.autorig`` takes them), bind the skeleton points
    (smooth) and compute the vertices' ``skin_weights`` (``influences``, ``blend``).

    progress: callable(fraction) -> bool|None; False cancels (``volrig.Cancelled``).
    skin_points: (S, 3) points to skin instead of the vertices (same frame), e.g. a Blender mesh's own vertices when
    the triangles voxelized are its evaluated surface after modifiers that change the topology (subdivision,
    mirror). The MeshRig then holds them as ``vertices`` (its ``weights`` are (S, B)) and ``faces`` is empty.
    voxelize_method: ``voxelize``'s method; "auto" (default) adds the generalized winding number's solid to the
    flood fill's for a mesh that is not closed (open parts, missing caps) and takes the flood fill alone for a
    closed one; "flood" as before for any mesh.
    min_radius_voxels: with ``voxel_size`` not given, a mesh whose skeleton's median radius comes out thinner than
    this many voxels is voxelized again, finer (up to ``MAX_MESH_VOXELS``), so thin limbs stay whole; 0: never.
    """
    v = _points(vertices)
    f = np.asarray(faces)
    step = {"skeletonize": (0.15, 0.35), "skeleton-tree": (0.35, 0.5), "autorig": (0.5, 0.65), "bind": (0.65, 0.7)}
    staged = None if progress is None else \
        (lambda name, x: progress(step[name][0] + (step[name][1] - step[name][0]) * x))
    mask, size, sk, pts = mesh_skeleton(v, f, voxel_size, voxels=voxels, thinness=thinness,
                                        voxelize_method=voxelize_method, min_radius_voxels=min_radius_voxels,
                                        progress=_span(progress, 0.0, 0.15), staged=staged)
    r = rig_skeleton(pts, mask, progress=staged, **autorig_options)
    if skin_points is not None:
        v, f = _points(skin_points), np.zeros((0, 3), dtype=np.int64)
    weights = skin_weights(mask, r.rig, v, influences, blend, progress=_span(progress, 0.7, 1.0))
    return MeshRig(v, f, r.rig, weights, mask, size, sk, pts, r.tree, r.binding)


def parse_up(text: str) -> Tuple[float, float, float]:
    """'+z', '-y', 'x' or '0,0.2,1' -> an up direction (x, y, z) in the volume's world frame."""
    t = text.strip().lower().replace(" ", "")
    axes = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
    if t.lstrip("+-") in axes:
        sign = -1.0 if t.startswith("-") else 1.0
        return tuple(sign * c + 0.0 for c in axes[t.lstrip("+-")])
    try:
        v = tuple(float(c) for c in t.split(","))
    except ValueError:
        v = ()
    if len(v) != 3:
        raise VolrigError(f"up: {text!r} is not an axis (+z, -y, x...) or a vector x,y,z")
    return v


def describe_rig(rig: Rig) -> str:
    """'humanoid, fit 0.82 (runner-up chains 0.41)': what autorig found, for messages; how many limb joints the bones
    placed (a rig from the bones) and its note after '; '."""
    text = f"{rig.kind}, fit {rig.fit:.2f}"
    text += f" (runner-up {rig.runner_up} {rig.runner_up_fit:.2f})" if rig.runner_up else ""
    if rig.bone_joints:
        text += f"; {sum(j.moved for j in rig.bone_joints)} of {len(rig.bone_joints)} limb joints from the bones"
    return text + (f"; {rig.note}" if rig.note else "")


def load_rigged(path: str, binding: bool = False) -> RiggedSkeleton:
    """A rig file that holds a rig (and a binding, when ``binding``); VolrigError saying what is missing."""
    saved = load_rig(path)
    if saved.rig is None:
        raise VolrigError(f"{path}: the file holds no rig")
    if binding and saved.binding is None:
        raise VolrigError(f"{path}: the file holds no binding (make it with `volrig rig`)")
    return saved


# ---- frames -----------------------------------------------------------------------------------------------------

def parse_frames(text: str, default: Optional[Tuple[int, int]] = None,
                 bounds: Optional[Tuple[int, int, str]] = None) -> List[int]:
    """'1-48', '5', '1-10,20-30' -> the sorted frame numbers. Empty text gives ``default`` (first, last), or an
    error without one. ``bounds`` (first, last, what) refuses frames outside first..last, naming ``what``."""
    if not text.strip():
        if default is None:
            raise VolrigError("frames: none given")
        return list(range(default[0], default[1] + 1))
    frames = set()
    for part, a, b in _ranges(text, "frames", "a frame or a range FIRST-LAST like 1-48"):
        if bounds is not None and not bounds[0] <= a <= b <= bounds[1]:
            raise VolrigError(f"{bounds[2]} has frames {bounds[0]}-{bounds[1]}; asked for {part}")
        if b < a:
            raise VolrigError(f"frames: empty range {part!r}")
        frames.update(range(a, b + 1))
    return sorted(frames)


def clip_frames(frame_count: int, text: str = "", step: int = 1, anchor: int = 1, what: str = "the clip") \
        -> np.ndarray:
    """0-based indices of a clip's frames: those ``text`` names (1-based as players number them; empty = all)
    that fall on every ``step``-th frame counted from frame ``anchor``. Farm machines given different ranges with
    anchor 1 pick frames of one sequence."""
    if step < 1:
        raise VolrigError(f"the frame step must be at least 1, got {step}")
    numbers = np.array(parse_frames(text, default=(1, frame_count), bounds=(1, frame_count, what)), np.int64)
    kept = numbers[(numbers - anchor) % step == 0]
    if not len(kept):
        raise VolrigError(f"frames {text}: none falls on the step {step} grid (frames {anchor}, {anchor + step}, "
                          "...)")
    return kept - 1


def sequence_number(clip_frame: int, step: int = 1) -> int:
    """The file number of 0-based clip frame ``clip_frame`` baked every ``step`` frames from the clip's first:
    files 1, 2, ... over the whole clip, so split ranges fit one sequence."""
    return int(clip_frame) // step + 1


def mocap_poses(rig: Rig, motion, frames, bone_map=None, root_motion: str = "in_place", up_axis: str = "y",
                scale: Optional[float] = None):
    """(bone map, (F, B, 4, 4) rest-to-pose matrices) driving ``rig`` with ``motion`` at 0-based ``frames``; the
    bone map defaults to the automatic one from the names."""
    from .mocap import animate, default_bone_map
    if bone_map is None:
        bone_map = default_bone_map(motion, rig)
    return bone_map, animate(rig, motion, frames=frames, bone_map=bone_map, root_motion=root_motion,
                             up_axis=up_axis, scale=scale)


# ---- baking to a folder -----------------------------------------------------------------------------------------

def frame_file(folder: str, stem: str, number: int) -> str:
    """``<folder>/<stem>_NNNN.vdb``: frame ``number`` of a VDB sequence."""
    return os.path.join(folder, f"{stem}_{number:04d}.vdb")


class BakeRate:
    """A bake's progress and pace: frames done of ``total`` and frames per second since ``start`` (the first frame
    started; each frame's file is written while the next computes, so the rate is what the whole bake sustains).
    ``bar()`` is the one-line progress bar every bake loop shows (CLI, add-on)."""

    def __init__(self, total: int):
        self.total = int(total)
        self.done = 0
        self.start = time.perf_counter()

    def tick(self) -> None:
        """One more frame done."""
        self.done += 1

    @property
    def per_second(self) -> float:
        elapsed = time.perf_counter() - self.start
        return self.done / elapsed if elapsed > 0 else 0.0

    def bar(self, width: int = 24) -> str:
        """``[#########...............] 12/240 frames, 1.86 frames/s, 2:02 left``."""
        filled = int(width * self.done / self.total) if self.total else width
        text = f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} frames"
        rate = self.per_second
        if self.done and rate > 0:
            left = int(round((self.total - self.done) / rate))
            text += f", {rate:.2f} frames/s, {left // 60}:{left % 60:02d} left"
        return text


def rest_labels(source: Volume, points: SkeletonPoints, binding: Binding, mask: Optional[Volume] = None) -> Volume:
    """The bone label (bone index + 1, 0 = none) of every source voxel as the binding has it at rest: the rest
    pose reconstructed by the Deformer (rigid), on the source's grid. With the object's ``mask``, its voxels no
    sphere covers (a few at the surface) take the label of the nearest covered voxel."""
    frame = Deformer(source, points, binding).frame(rest_pose(binding.weights.shape[1]), mode="rigid", values=False)
    labels = np.zeros(source.array.shape, dtype=np.int16)
    lo = np.array(frame.offset[::-1])  # z, y, x
    hi = np.minimum(lo + frame.bone.array.shape, labels.shape)
    lo_in = np.maximum(lo, 0)
    if (hi > lo_in).all():
        src = tuple(slice(a - o, b - o) for a, b, o in zip(lo_in, hi, lo))
        labels[tuple(slice(a, b) for a, b in zip(lo_in, hi))] = frame.bone.array[src]
    if mask is not None and labels.any():
        _fill_labels(labels, np.asarray(mask.array, dtype=bool) & (labels == 0), source.spacing)
    return source.like(labels)


def _fill_labels(labels: np.ndarray, gap: np.ndarray, spacing) -> None:
    """Gives the ``gap`` voxels, in place, the label of the nearest labelled voxel, found on a grid twice as
    coarse (a few seconds for millions of voxels where the exact transform takes many)."""
    from . import _optional
    ndimage = _optional.scipy_module("scipy.ndimage", "volrig.pipeline.rest_labels with a mask (the rest "
                                     "parts of write_rest_looks, Explode)")
    coarse = labels[::2, ::2, ::2]
    if not coarse.any():
        coarse = labels
    step = 2 if coarse is not labels else 1
    nearest = ndimage.distance_transform_edt(coarse == 0, sampling=np.asarray(spacing[::-1]) * step,
                                             return_distances=False, return_indices=True)
    z, y, x = np.nonzero(gap)
    labels[z, y, x] = coarse[tuple(i[z // step, y // step, x // step] for i in nearest)]


def write_rest_looks(path: str, source: Volume, points: Optional[SkeletonPoints] = None,
                     binding: Optional[Binding] = None, parts=(), mask: Optional[Volume] = None,
                     tissues=(), substitutes=None) -> None:
    """The rest volume with its looks: an OpenVDB file of ``density`` (the source's values, float32); with
    ``parts`` (which need the rig's ``points`` and ``binding``) ``bone`` (``rest_labels``, the object's ``mask``
    filled), each part's ``density_<key>`` and ``mask_<key>`` and ``density_outside`` (``volrig.part_grids``); with
    ``tissues`` (a label map's classes) the ``tissue`` grid of class indices (``volrig.tissue_grid``) and the classes
    in the file's metadata; ``substitutes``
    ({part key: Volume}) replace those parts' ``density_<key>`` (``volrig.parts.substitute_grid``)."""
    values = source.like(source.array.astype(np.float32, copy=False))
    grids = {"density": values}
    if parts:
        if points is None or binding is None:
            raise VolrigError("write_rest_looks: parts need the rig's points and binding")
        labels = rest_labels(source, points, binding, mask)
        grids["bone"] = labels
        grids.update(part_grids(values, labels, parts, outside=True))
        subs = check_substitutes(source, parts, substitutes)
        grids.update(substituted(labels, rest_pose(binding.weights.shape[1]), parts, subs, "trilinear"))
    if tissues:
        grids[TISSUE_GRID] = tissue_grid(source, tissues)
    write_vdb(path, grids, half=False, labels=("bone", TISSUE_GRID),
              metadata=classes_metadata(tissues) if tissues else None)


def check_substitutes(source: Volume, parts, substitutes) -> dict:
    """``{part key: Volume}`` checked against the parts and the source (same axes: co-registered)."""
    out = dict(substitutes or {})
    keys = {p.key for p in parts}
    for key, vol in out.items():
        if key not in keys:
            raise VolrigError(f"substitute for {key!r}: no such part (parts: {', '.join(sorted(keys)) or 'none'})")
        if not isinstance(vol, Volume):
            raise TypeError(f"substitute for {key!r} must be a volrig.Volume, got {type(vol).__name__}")
        if not np.allclose(vol.direction, source.direction):
            raise VolrigError(f"substitute for {key!r}: its axes differ from the source's (co-register it first)")
    return out


def substituted(labels: Volume, matrices, parts, substitutes: dict, sampling: str) -> dict:
    """``{f"density_{key}": grid}`` of each part with a substitute (``volrig.parts.substitute_grid``)."""
    return {f"density_{p.key}": substitute_grid(labels, matrices, p.bones, substitutes[p.key], sampling)
            for p in parts if p.key in substitutes}


def _no_thickness(thickness) -> bool:
    return thickness is None or bool(np.all(np.asarray(thickness, np.float64) == 1.0))


# A bake asked for the bones' lattice tables that knows it will draw at least this many frames builds them at its
# first frame; a shorter one never does (they pay back their build after 12-18 frames on the phantom: docs/deform.md,
# Bakes and the lattice tables).
TABLES_PAY_AFTER = 16


def _whole_in_half(source: Volume) -> bool:
    """Half floats hold every value of ``source`` exactly: whole numbers within +-2048 (a label map's codes)."""
    a = np.asarray(source.array)
    if a.dtype.kind in "iub":
        return a.size == 0 or (int(a.min()) >= -2048 and int(a.max()) <= 2048)
    for z in range(0, a.shape[0], 16):  # (a slab at a time: no temporary the size of the source)
        slab = a[z:z + 16]
        if np.abs(slab).max(initial=0) > 2048 or np.any(slab != np.round(slab)):
            return False
    return True


def lattice_after_for(frames: Optional[int], tables: bool = True) -> Optional[int]:
    """``Deformer.lattice_after`` for a bake of ``frames`` frames: -1 (never) without ``tables``; with them 0 (at the
    first frame) from TABLES_PAY_AFTER frames on, -1 below, None (the Deformer's own default) when not known."""
    if not tables:
        return -1
    if frames is None:
        return None
    return 0 if frames >= TABLES_PAY_AFTER else -1


class FolderBake:
    """Poses of one bound skeleton reconstructed into a VDB sequence in ``folder`` (grids ``density``, half floats,
    and ``bone``, each of ``parts``' ``density_<key>`` and ``mask_<key>``: ``volrig.part_grids``, and each of
    with ``tissues`` the ``tissue`` grid of class indices and the classes in the file's metadata:
    ``volrig.tissue_grid``, label maps baked with nearest sampling; written
    atomically). The Deformer is built once.

    ``track=True`` keeps ``poses.json`` in the folder: the hash of each frame's pose with everything else the
    result depends on (the weights, ``setup``, mode, sampling, ``keep_volume`` and the deformation's revision), so
    ``up_to_date`` tells a frame that needs no
    re-bake; machines baking other frames into the same folder merge their entries. Frames may carry per-bone
    thickness factors (``bake(..., thickness=)``: ``volrig.skin.thicken_volume``; needs ``rig``).

    A frame's file is written on a thread of its own while the next frame computes (the Deformer and the VDB
    writer release the GIL); a failed write raises at the next ``bake`` or at ``finish``, which every bake loop
    calls at its end (it waits for the last write and frees the frames' memory). Frames hold their values as the
    half floats the files store (``Deformer.frame(..., half=True)``); with tissue looks too when half floats hold
    the label map's codes exactly (all within +-2048), else float32.

    A bake draws its frames without the bones' lattice tables (``Deformer.lattice_after`` -1): they would hold
    1-3 bytes per source voxel more for frames about 5% (smooth modes) to 20% (rigid) faster (docs/deform.md,
    "Bakes and the lattice tables").
    ``lattice_tables=True`` builds them when they pay: at the first frame of a bake of ``frames`` (how many it will
    draw, when known) TABLES_PAY_AFTER or more, never in a shorter one, after the Deformer's default 8 frames when
    ``frames`` is not known (``lattice_after_for``). ``lattice_after`` (wins over both): as ``Deformer``'s."""

    def __init__(self, source: Volume, points: SkeletonPoints, binding: Binding, folder: str, stem: str,
                 mode: str = "linear", sampling: str = "trilinear", track: bool = False, setup: str = "",
                 parts=(), rig: Optional[Rig] = None, tissues=(), substitutes=None, keep_volume: bool = True,
                 lattice_after: Optional[int] = None, frames: Optional[int] = None, lattice_tables: bool = False):
        self.folder, self.stem, self.mode, self.sampling = folder, stem, mode, sampling
        self.lattice_after = lattice_after_for(frames, lattice_tables) if lattice_after is None else lattice_after
        self.keep_volume = bool(keep_volume)
        self.source, self.points, self.binding, self.rig = source, points, binding, rig
        self.parts, self.tissues = list(parts), list(tissues)
        self.substitutes = check_substitutes(source, self.parts, substitutes)
        if self.tissues and sampling != "nearest":
            raise VolrigError("tissue looks need the label map's own codes: bake with nearest sampling")
        self.deformer = Deformer(source, points, binding, lattice_after=self.lattice_after)
        self._half = not self.tissues or _whole_in_half(source)
        self._thick = None  # (factors, Deformer of the thickened source, radius_scale) of the last thickness
        self.poses_path = os.path.join(folder, "poses.json") if track else None
        w = binding.weights.tocsr()
        h = hashlib.sha1()
        for a in (w.indptr, w.indices, w.data):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(json.dumps([setup, list(binding.bone_names), mode, sampling]
                            + ([] if self.keep_volume else ["plain blend"]) + [DEFORM_REVISION]
                            + ([[list(p) for p in self.parts]] if self.parts else [])
                            + ([[[t.key, t.codes] for t in self.tissues]] if self.tissues else [])
                            + ([sorted((k, v.path or id(v)) for k, v in self.substitutes.items())]
                               if self.substitutes else [])).encode())
        self.setup_hash = h.hexdigest()
        self.poses = self._read_poses()
        self._writer = None   # the thread writing files, while a bake runs
        self._pending = None  # the last frame's write

    def path(self, number: int) -> str:
        return frame_file(self.folder, self.stem, number)

    def pose_hash(self, matrices, thickness=None) -> str:
        extra = b"" if _no_thickness(thickness) else np.round(np.asarray(thickness, np.float64), 4).tobytes()
        return hashlib.sha1(np.round(np.asarray(matrices, np.float64), 6).tobytes() + extra
                            + self.setup_hash.encode()).hexdigest()

    def up_to_date(self, number: int, matrices, thickness=None) -> bool:
        """The frame's file exists and was baked from this pose, thickness and setup (always False without
        ``track``)."""
        return (self.poses_path is not None and self.poses.get(str(number)) == self.pose_hash(matrices, thickness)
                and os.path.exists(self.path(number)))

    def _deformer_for(self, thickness):
        """The Deformer and radius_scale for per-bone thickness factors (None or all 1: the source's own). A new
        thickness thickens the source once (``volrig.skin.thicken_volume``) and builds a Deformer on it; the last
        one is kept, so a held thickness costs nothing per frame."""
        if _no_thickness(thickness):
            return self.deformer, None
        factors = tuple(np.round(np.asarray(thickness, np.float64), 4))
        if self._thick is None or self._thick[0] != factors:
            from .skin import thicken_volume
            if self.rig is None:
                raise VolrigError("thickness needs the rig: give FolderBake its rig")
            scales = {b: f for b, f in enumerate(factors) if f != 1.0}
            thick, radius_scale = thicken_volume(self.source, self.points, self.binding, self.rig, scales,
                                                 sampling=self.sampling)
            self._thick = None  # free the previous one first
            self._thick = (factors, Deformer(thick, self.points, self.binding, lattice_after=self.lattice_after),
                           radius_scale)
        return self._thick[1], self._thick[2]

    def bake(self, number: int, matrices, progress=None, thickness=None) -> dict:
        """Reconstructs one pose ((B, 4, 4) rest-to-pose matrices; ``thickness``: None or (B,) per-bone thickness
        factors, 1 = unchanged) into frame ``number``'s file; returns the frame's stats. The frame's memory goes back
        to the Deformer for the next one."""
        os.makedirs(self.folder, exist_ok=True)
        deformer, radius_scale = self._deformer_for(thickness)
        frame = deformer.frame(matrices, mode=self.mode, sampling=self.sampling, radius_scale=radius_scale,
                               keep_volume=self.keep_volume, progress=progress, bricks=True,
                               half=self._half)  # (tissue looks read the label map's exact codes)
        self._wait()  # the previous frame's grids are written and freed before this one's are built
        subs = substituted(frame.bone, matrices, self.parts, self.substitutes, self.sampling) if self.substitutes else {}
        grids = frame.vdb(self.path(number), half=True, parts=self.parts, tissues=self.tissues, substitutes=subs)
        stats = frame.stats
        del frame, subs  # the frame's memory goes back to the Deformer for the next one while its file is written
        if self._writer is None:
            self._writer = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="volrig-vdb")
        self._pending = self._writer.submit(self._write, number, self.pose_hash(matrices, thickness), grids)
        return stats

    def finish(self) -> None:
        """Waits for the last frame's file (raising its error, if any) and frees the frames' memory."""
        try:
            self._wait()
        finally:
            if self._writer is not None:
                self._writer.shutdown(wait=True)
                self._writer = None
            self.deformer.release_frame_memory()

    def _wait(self) -> None:
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def _write(self, number: int, pose_hash: str, grids) -> None:
        grids.write(self.path(number))
        if self.poses_path is not None:
            self.poses[str(number)] = pose_hash
            self._write_poses()

    def _read_poses(self) -> dict:
        if self.poses_path is None:
            return {}
        try:
            with open(self.poses_path) as f:
                return json.load(f)
        except (OSError, ValueError):
            return {}

    def _write_poses(self) -> None:
        on_disk = self._read_poses()  # other machines may bake other frames into the same folder
        on_disk.update(self.poses)
        with atomic_output(self.poses_path) as tmp:
            with open(tmp, "w") as f:
                json.dump(on_disk, f, indent=0, sort_keys=True)

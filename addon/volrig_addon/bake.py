"""Baking: each frame of the evaluated rig reconstructs the volume (volrig.Deformer) into
``<cache>/frames/<name>_<frame>.vdb`` (grids ``density`` and ``bone``), and the Volume object plays them.

The weights come from the sphere mesh's vertex groups as they are now (weight painting counts); the points and the
source from the cache. Bone matrices are rest-to-pose in armature space (= volume units): pose_bone.matrix @
bone.matrix_local^-1. A frame is re-baked only when its pose, weights or rig changed (``frames/poses.json``).
Every frame is independent, so a range can be split across machines once the .blend is saved.
"""
import hashlib
import json
import os
import re

import bpy
import numpy as np

import volrig

from . import objects, scans

#: How frames are reconstructed (the bake's "Deform" setting).
DEFORM_MODES = ("rigid", "linear", "dual_quaternion")


def frames_dir(volume_obj) -> str:
    return os.path.join(scans.cache_dir(volume_obj), "frames")


def frame_path(volume_obj, frame: int) -> str:
    """The VDB file of a scene frame; numbered by scene frame so the Volume object's sequence finds it."""
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", volume_obj.name).rstrip("0123456789.") or "volume"
    return os.path.join(frames_dir(volume_obj), f"{safe}_{frame:04d}.vdb")


def parse_frames(text: str, scene=None):
    """'1-48', '5', '1-10,20-30' -> sorted frame list; empty text = the scene's frame range."""
    if not text.strip():
        if scene is None:
            raise ValueError("frames: none given")
        return list(range(scene.frame_start, scene.frame_end + 1))
    frames = set()
    for part in re.split(r"[\s,]+", text.strip()):
        m = re.fullmatch(r"(-?\d+)(?:-(-?\d+))?", part)
        if not m:
            raise ValueError(f"frames: {part!r} is not a frame or a range like 1-48")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) else a
        if b < a:
            raise ValueError(f"frames: empty range {part!r}")
        frames.update(range(a, b + 1))
    return sorted(frames)


class Baker:
    """Everything one bake of a volrig Volume object needs, prepared once (the Deformer's precompute)."""

    def __init__(self, volume_obj, mode: str = "linear"):
        if mode not in DEFORM_MODES:
            raise ValueError(f"deform mode must be one of {', '.join(DEFORM_MODES)}, got {mode!r}")
        if not hasattr(volrig, "Deformer"):
            raise RuntimeError("this volrig has no deform yet (volrig.Deformer); update volrig")
        self.volume_obj = volume_obj
        self.mode = mode
        self.sampling = volume_obj.volrig.sampling
        parts = objects.members(volume_obj)
        if "RIG" not in parts or "SPHERES" not in parts:
            raise ValueError(f"{volume_obj.name} is not rigged: press Rig first")
        self.rig_obj, self.spheres_obj = parts["RIG"], parts["SPHERES"]
        path = scans.rig_path(volume_obj)
        saved = volrig.load_rig(path)
        self.names = [b.name for b in self.rig_obj.data.bones]
        fallback = saved.binding if saved.binding is not None and saved.binding.bone_names == self.names else None
        groups = objects.vertex_groups(self.spheres_obj)
        if len(self.spheres_obj.data.vertices) != len(saved.points):
            raise ValueError(f"{self.spheres_obj.name} has {len(self.spheres_obj.data.vertices)} vertices but the "
                             f"rig file has {len(saved.points)} points: press Rig again")
        self.binding = volrig.Binding.from_groups(groups, self.names, len(saved.points), fallback=fallback)
        self.deformer = volrig.Deformer(scans.source(volume_obj), saved.points, self.binding)
        w = self.binding.weights.tocsr()
        h = hashlib.sha1()
        for a in (w.indptr, w.indices, w.data):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(json.dumps([os.path.basename(path), self.names, mode, self.sampling]).encode())
        self.setup_hash = h.hexdigest()
        self._poses_path = os.path.join(frames_dir(volume_obj), "poses.json")
        try:
            with open(self._poses_path) as f:
                self.poses = json.load(f)
        except (OSError, ValueError):
            self.poses = {}

    def bone_matrices(self, depsgraph) -> np.ndarray:
        """(B, 4, 4) rest-to-pose matrices of the evaluated armature, in the bone order of the binding."""
        arm = self.rig_obj.evaluated_get(depsgraph)
        out = np.empty((len(self.names), 4, 4))
        for b, name in enumerate(self.names):
            pb = arm.pose.bones[name]
            out[b] = np.array(pb.matrix @ pb.bone.matrix_local.inverted())
        # (bones at rest come out of Blender's single precision a hair off the identity: volrig.deform takes them as
        # the identity itself)
        return out

    def pose_hash(self, matrices: np.ndarray) -> str:
        return hashlib.sha1(np.round(matrices, 6).tobytes() + self.setup_hash.encode()).hexdigest()

    def bake_frame(self, scene, frame: int, progress=None, force: bool = False) -> bool:
        """Reconstruct scene frame ``frame`` into its VDB file; False when the file was up to date."""
        scene.frame_set(frame)
        matrices = self.bone_matrices(bpy.context.evaluated_depsgraph_get())
        path = frame_path(self.volume_obj, frame)
        key = self.pose_hash(matrices)
        if not force and self.poses.get(str(frame)) == key and os.path.exists(path):
            return False
        os.makedirs(os.path.dirname(path), exist_ok=True)
        result = self.deformer.frame(matrices, mode=self.mode, sampling=self.sampling, progress=progress)
        result.save(path, half=True)
        self.poses[str(frame)] = key
        self._save_poses()
        return True

    def _save_poses(self) -> None:
        from volrig.files import atomic_output
        # other machines may bake other frames into the same folder: merge with what is on disk
        try:
            with open(self._poses_path) as f:
                on_disk = json.load(f)
        except (OSError, ValueError):
            on_disk = {}
        on_disk.update(self.poses)
        with atomic_output(self._poses_path) as tmp:
            with open(tmp, "w") as f:
                json.dump(on_disk, f, indent=0, sort_keys=True)

    def play(self, scene) -> None:
        """Point the Volume object at the frame sequence over the scene's frame range."""
        s = self.volume_obj.volrig
        s.baked_start, s.baked_end = scene.frame_start, scene.frame_end
        first = frame_path(self.volume_obj, scene.frame_start)
        objects.point_volume_at(self.volume_obj, bpy.path.relpath(first) if bpy.data.filepath else first,
                                (scene.frame_start, scene.frame_end))


def bake(volume_obj, scene, frames, mode: str = "linear", force: bool = False, report=print) -> int:
    """Bake ``frames`` of ``volume_obj`` (blocking; the headless path); returns the number of frames written."""
    baker = Baker(volume_obj, mode)
    current = scene.frame_current
    written = 0
    try:
        for i, frame in enumerate(frames):
            if baker.bake_frame(scene, frame, force=force):
                written += 1
            report(f"volrig: {volume_obj.name} frame {frame} ({i + 1}/{len(frames)})")
    finally:
        scene.frame_set(current)
    baker.play(scene)
    return written


def bake_saved_scene(frames_text: str = "", names=(), mode: str = "", force: bool = False, save: bool = True) -> int:
    """Headless entry (``python -m volrig bake scene.blend``): bake the named volrig Volume objects (all when
    ``names`` is empty) of the open .blend over ``frames_text`` (default: the scene range), then save the .blend so
    ``blender -b scene.blend -a`` renders the sequence."""
    scene = bpy.context.scene
    frames = parse_frames(frames_text, scene)
    targets = [o for o in bpy.data.objects if o.volrig.role == "VOLUME" and (not names or o.name in names)]
    missing = set(names) - {o.name for o in targets}
    if missing:
        raise ValueError(f"no volrig volume named {', '.join(sorted(missing))} in {bpy.data.filepath}")
    if not targets:
        raise ValueError(f"{bpy.data.filepath} holds no volrig volume")
    total = 0
    for obj in targets:
        total += bake(obj, scene, frames, mode or obj.volrig.deform_mode, force)
    if save and bpy.data.filepath:
        bpy.ops.wm.save_mainfile()
    return total

"""Live preview while scrubbing: on every frame change, a rigged volume whose frame is not baked shows a coarse
reconstruction of the current pose (``volrig.deform.coarse_level``: every f-th voxel, f the smallest of 2, 4, 8 that
keeps the coarse grid within ``BUDGET_VOXELS``), written to ``<cache>/preview.vdb`` and shown by the Volume object
itself (with its own material; the object is never hidden, so selections and operators are untouched); a baked
frame gives the object back its baked sequence, and so does the start of a render.

The preview is computed in the frame-change handler itself, synchronously: the coarse level bounds its cost (the
phantom at scale 1, 46 M voxels, previews at a quarter per axis in about 50 ms: ``benchmarks/bench_preview.py``), so
scrubbing never waits on a queue and there is nothing to cancel. The coarse Deformer is built once per rig (the rig
file's time stamp and the sphere mesh's weights are its key) and kept with the scan in memory. Renders never use
the preview: bake for final frames.
"""
import os

import bpy
import numpy as np

import volrig
from volrig.deform import coarse_level

from . import bake, looks, objects, scans, tissue_looks

#: the coarse grid's size limit in voxels (a quarter per axis of the phantom at scale 1 is 0.72 M)
BUDGET_VOXELS = 1_500_000


def factor_for(dims) -> int:
    """The smallest of 2, 4, 8 keeping the coarse grid within BUDGET_VOXELS."""
    n = float(np.prod(dims))
    for f in (2, 4, 8):
        if n / f ** 3 <= BUDGET_VOXELS:
            return f
    return 16


def preview_path(volume_obj) -> str:
    return os.path.join(scans.cache_dir(volume_obj), "preview.vdb")


#: Edits seen per mesh (by the original data-block's address: Blender 3.4 has no session_uid), bumped by depsgraph
#: updates of its geometry (weight painting, vertex group changes from Python; not frame changes), so a preview
#: notices new weights without reading them.
_EDITS = {}
_EPOCH = [0]  # bumped by undo, redo and file loads: every key changes


def _weights_key(spheres_obj) -> tuple:
    """A fingerprint of the sphere mesh's vertex groups that costs nothing per frame: the mesh and how many edits
    of its geometry the depsgraph reported (reading the groups themselves took 0.3 s a frame at 81,000 spheres)."""
    uid = spheres_obj.data.original.as_pointer()
    return uid, _EDITS.get(uid, 0), _EPOCH[0], len(spheres_obj.vertex_groups)


@bpy.app.handlers.persistent
def _geometry_edited(scene, depsgraph) -> None:
    """depsgraph_update_post: counts geometry edits per mesh (cheap: the updates list only)."""
    for u in depsgraph.updates:
        if u.is_updated_geometry and isinstance(u.id, bpy.types.Mesh):
            uid = u.id.original.as_pointer()
            _EDITS[uid] = _EDITS.get(uid, 0) + 1


@bpy.app.handlers.persistent
def _history_changed(*_args) -> None:
    """undo_post, redo_post, load_post: weights may be anything now."""
    _EPOCH[0] += 1


class Preview:
    """One rigged volume's coarse level: its RigState (bone order, binding) and a Deformer on the coarse grid."""

    def __init__(self, volume_obj):
        self.state = bake.RigState(volume_obj)
        source = scans.source(volume_obj)
        self.factor = factor_for(source.dims)
        # no lattice tables, ever: on the coarse grid the balls are faster (the phantom at a quarter per axis: 9.6
        # against 12.2 ms a frame, benchmarks/RESULTS.md, Live preview) and scrubbing never stalls on their build
        self.deformer = volrig.Deformer(*coarse_level(source, self.state.points, self.state.binding, self.factor),
                                        lattice_after=-1)

    @staticmethod
    def key(volume_obj):
        parts = objects.members(volume_obj)
        path = scans.rig_path(volume_obj)
        return (os.path.getmtime(path) if os.path.exists(path) else 0.0, _weights_key(parts["SPHERES"]),
                volume_obj.volrig.sampling)

    @classmethod
    def of(cls, volume_obj) -> "Preview":
        """The object's Preview, rebuilt when its rig file or weights changed."""
        entry = scans._entry(volume_obj)
        key = cls.key(volume_obj)
        held = entry.get("preview")
        if held is None or held[0] != key:
            held = (key, cls(volume_obj))
            entry["preview"] = held
        return held[1]

    def write(self, volume_obj, depsgraph, path: str) -> None:
        """The current pose's coarse frame into ``path`` (atomically)."""
        s = volume_obj.volrig
        matrices = self.state.bone_matrices(depsgraph)
        if s.explode:  # taken apart as the bake does it
            matrices = volrig.explode_matrices(self.state.rig, s.explode, matrices)
        frame = self.deformer.frame(matrices, mode=s.deform_mode, sampling=s.sampling, keep_volume=s.keep_volume,
                                    bricks=True)  # written straight from its bricks (no cropped copy)
        frame.save(path, tissues=tissue_looks.tissues_of(volume_obj))


def showing_preview(volume_obj) -> bool:
    """Whether the Volume object shows the preview file now."""
    data = volume_obj.data
    return not data.is_sequence and bpy.path.abspath(data.filepath) == preview_path(volume_obj)


def restore(volume_obj) -> None:
    """The Volume object back to what it shows without a preview: its baked sequence, else the rest volume."""
    s = volume_obj.volrig
    if s.baked_end >= s.baked_start:
        first = bake.frame_path(volume_obj, s.baked_start)
        objects.point_volume_at(volume_obj, bpy.path.relpath(first) if bpy.data.filepath else first,
                                (s.baked_start, s.baked_end))
    else:
        objects.point_volume_at(volume_obj, looks.shown_at_rest(volume_obj))


def _rigged_volumes(scene):
    for obj in scene.objects:
        if obj.type == "VOLUME" and obj.volrig.role == "VOLUME" and "RIG" in objects.members(obj):
            yield obj


def update(volume_obj, scene, depsgraph) -> bool:
    """Shows the bake of the current frame when there is one, else the coarse preview, on the Volume object itself
    (never hidden, so selections and operators are untouched); True when a preview was made."""
    baked = os.path.exists(bpy.path.abspath(bake.frame_path(volume_obj, scene.frame_current)))
    if baked or not scene.volrig_live_preview:
        if showing_preview(volume_obj):
            restore(volume_obj)
        return False
    path = preview_path(volume_obj)
    Preview.of(volume_obj).write(volume_obj, depsgraph, path)
    objects.point_volume_at(volume_obj, path)
    return True


@bpy.app.handlers.persistent
def on_frame_change(scene, depsgraph=None) -> None:
    """frame_change_post: every rigged volume of the scene; a failure is printed, never raised (a handler that
    raises would break playback)."""
    if bake.posing or _rendering:
        return
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    for obj in list(_rigged_volumes(scene)):
        try:
            update(obj, scene, depsgraph)
        except (volrig.VolrigError, OSError, KeyError) as e:
            print(f"volrig: no preview of {obj.name}: {e}")


_rendering = False


@bpy.app.handlers.persistent
def _render_started(scene, *_args) -> None:
    """Renders use bakes: the previews give way to them and none is made while one runs (a farm's frames stay
    fast)."""
    global _rendering
    _rendering = True
    for obj in list(_rigged_volumes(scene)):
        if showing_preview(obj):
            restore(obj)


@bpy.app.handlers.persistent
def _render_ended(*_args) -> None:
    global _rendering
    _rendering = False


_HANDLERS = ((bpy.app.handlers.frame_change_post, on_frame_change), (bpy.app.handlers.render_init, _render_started),
             (bpy.app.handlers.render_complete, _render_ended), (bpy.app.handlers.render_cancel, _render_ended),
             (bpy.app.handlers.depsgraph_update_post, _geometry_edited),
             (bpy.app.handlers.undo_post, _history_changed), (bpy.app.handlers.redo_post, _history_changed),
             (bpy.app.handlers.load_post, _history_changed))


def register():
    bpy.types.Scene.volrig_live_preview = bpy.props.BoolProperty(
        name="Live Preview", default=True,
        description="While scrubbing, show unbaked frames as a coarse reconstruction (every 2nd to 8th voxel)")
    for handlers, f in _HANDLERS:
        handlers.append(f)


def unregister():
    for handlers, f in _HANDLERS:
        if f in handlers:
            handlers.remove(f)
    del bpy.types.Scene.volrig_live_preview

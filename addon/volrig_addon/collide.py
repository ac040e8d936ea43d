"""Contacts: Find Contacts (``volrig.collide`` / ``volrig.self_collide`` over the scene's frames) marks the
frames where a rigged volume touches another or itself on the timeline; its button is on the Bake panel (bake.py)."""
import bpy
import numpy as np

import volrig
from volrig.collide import contact_runs

from .ops_base import _OnVolume, _ProgressBar, _rigged_volume_of
from .state import RigState


#: The prefix of the timeline markers Find Contacts adds (and replaces on the next run).
CONTACT_MARKER = "contact: "


def _to_frame_of(a_obj, b_obj) -> np.ndarray:
    """B's armature space -> A's (both rigid and of one scale, else a clear error): the two volumes' worlds."""
    rel = np.array(a_obj.matrix_world.inverted() @ b_obj.matrix_world)
    r = rel[:3, :3]
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-4):
        raise volrig.VolrigError(f"{a_obj.name} and {b_obj.name} are scaled differently: contacts need both "
                                 "volumes at one scale (apply the scale or import both in the same units)")
    return rel


class VOLRIG_OT_find_contacts(_OnVolume, bpy.types.Operator):
    """Find the frames of the scene range where this rigged volume touches another selected one (or, alone,
    passes through itself): timeline markers at the first frame of each contact, named with the bones"""
    bl_idname = "volrig.find_contacts"
    bl_label = "Find Contacts"
    rigged = True
    modes = ("OBJECT", "POSE")

    min_distance: bpy.props.IntProperty(
        name="Bones apart", default=2, min=1, max=20,
        description="Self-contact: only bones at least this many bones apart in the rig (2: not parent and child); "
                    "bones touching at rest never count")

    def run(self, context, vol):
        scene = context.scene
        others = list({_rigged_volume_of(o) for o in context.selected_objects} - {vol, None})
        if len(others) > 1:
            raise volrig.VolrigError("select at most one other rigged volume (none: self-contact)")
        a = RigState(vol)
        ca = volrig.Collider(a.points, a.binding, parents=a.parents)
        b = cb = None
        if others:
            b = RigState(others[0])
            cb = volrig.Collider(b.points, b.binding, parents=b.parents)
        frames = list(range(scene.frame_start, scene.frame_end + 1))
        current, results = scene.frame_current, []
        mode, keep = vol.volrig.deform_mode, vol.volrig.keep_volume
        with _ProgressBar(context) as bar:
            try:
                for k, f in enumerate(frames):
                    scene.frame_set(f)
                    depsgraph = context.evaluated_depsgraph_get()
                    ma = a.bone_matrices(depsgraph)
                    if b is None:
                        results.append(volrig.self_collide(ca, ma, min_bone_distance=self.min_distance, mode=mode,
                                                           keep_volume=keep))
                    else:  # B's rest (its armature space) -> B posed -> A's armature space, as they stand now
                        to_a = _to_frame_of(a.rig_obj.evaluated_get(depsgraph), b.rig_obj.evaluated_get(depsgraph))
                        mb = to_a @ b.bone_matrices(depsgraph)
                        results.append(volrig.collide(ca, ma, cb, mb, mode=mode, keep_volume=keep))
                    bar.wm.progress_update(100.0 * (k + 1) / len(frames))
            finally:
                scene.frame_set(current)
        contacts = contact_runs(frames, results)
        for m in [m for m in scene.timeline_markers if m.name.startswith(CONTACT_MARKER)]:
            scene.timeline_markers.remove(m)
        for c in contacts:
            scene.timeline_markers.new(CONTACT_MARKER + c.name, frame=c.first)
        what = f"{vol.name} and {others[0].name}" if others else f"{vol.name} with itself"
        spans = "; ".join(f"{c.first}-{c.last} {c.name}" for c in contacts[:4])
        self.report({"INFO"}, f"volrig: {len(contacts)} contact(s) of {what} over frames {frames[0]}-{frames[-1]}"
                              + (f": {spans}" if spans else ""))
        return {"FINISHED"}


CLASSES = (VOLRIG_OT_find_contacts,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

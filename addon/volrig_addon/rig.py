"""The rig: Rig (skeleton-tree, automatic armature and binding: ``volrig.pipeline.rig_skeleton``), Rebind, Add Walk
Cycle, Thickness per Bone, the rig files in the cache (``_save_rig``), and the Rig panel."""
import os
import uuid

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

import volrig
from volrig import pipeline

from . import looks, markers, objects, scans
from .ops_base import _draw_found, _found_level, _labelled, _OnVolume, _ProgressBar, _props, _settings, _VolrigPanel


#: The Rig button's progress bar: each pipeline step's share.
# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

#: The body plans a rig is fitted to (Rig's Body plan, and Import Drawing's and Rig Mesh's).
BODY_PLANS = [
    ("AUTO", "Best fit", "Fit every template (humanoid, quadruped, winged, hand, chains) and keep the best"),
    ("humanoid", "Humanoid", "Force the humanoid template (head, two arms, two legs: 21 Rigify bones)"),
    ("quadruped", "Quadruped", "Force the quadruped template (four legs, spine, head; tail and neck as found)"),
    ("winged", "Winged", "Force the winged template (two wings, two legs, spine, head; tail as found)"),
    ("chains", "Chains", "Neutral chains along the skeleton's branches (no body roles)"),
    ("hand", "Hand", "Force the hand template (palm, thumb and four fingers of three bones each)"),
]


class RigSettings:
    """How the rig is built and bound, and what the last Rig found."""
    # --- rig ---
    alpha: FloatProperty(name="Alpha", default=0.9, min=0.0, max=1.0,
                         description="Skeleton-tree: 1 weighs edges by length only, lower prefers equal radii")
    bones: IntProperty(name="Bones", default=24, min=1, max=200, description="Bone count target")
    roles: BoolProperty(name="Body roles", default=True,
                        description="Name bones as a humanoid, quadruped, winged body or hand when the shape looks like one")
    body_plan: EnumProperty(name="Body plan", items=BODY_PLANS, default="AUTO",
                            description="The template the rig is fitted to; pick another and press Rig to refit")
    use_scene_up: BoolProperty(name="Scene up", default=True,
                               description="Tell the rig where up is: the scene's +Z seen from the volume (else inferred)")
    rig_kept_points: BoolProperty(name="Kept points", default=False,
                                  description="Rig the kept skeleton points themselves, not autorig's own skeleton "
                                              "of the object (for bones without flesh; the rig then follows the "
                                              "thinness)")
    rig_found: StringProperty(name="Found", description="What the last rig found: kind, fit and runner-up")
    rigid_voxels: IntProperty(name="Rigid voxels", default=0, min=0,
                              description="Voxels of rigid tissue the last Rig or Rebind bound: they move whole, as "
                                          "the rigid layer, while the flesh bends (0: none)")
    bind_mode: EnumProperty(name="Binding", items=[
        ("smooth", "Smooth", "Points near a joint share their weight between its two bones"),
        ("rigid", "Rigid", "Every point follows one bone"),
    ], default="smooth")
    rigid_by: EnumProperty(name="Rigid tissue", default="AUTO", items=[
        ("AUTO", "Automatic", "The tissue table's bone codes (Look > Tissues) when the volume has a table, else none"),
        ("NONE", "None", "Every tissue bends at the joints"),
        ("LABELS", "Labels", "The voxels with these label values do not bend (a label map's bone codes)"),
        ("RANGE", "Value range", "The voxels with values in this range do not bend (a CT's bone, e.g. 300-3000 HU)"),
    ], description="Tissue that must not bend: each connected piece is bound wholly to one bone, its spheres with "
                   "weight 1; only the rest blends across joints (Rig and Rebind)")
    rigid_labels: StringProperty(name="Rigid labels", default="",
                                 description="Label values of the rigid tissue, e.g. 84, 92 or 80-90")
    rigid_low: FloatProperty(name="From", default=300.0, description="Lowest value of the rigid tissue")
    rigid_high: FloatProperty(name="To", default=3000.0, description="Highest value of the rigid tissue")
    rig_file: StringProperty(name="Rig file", description="The .vrig file (points, tree, rig, binding) in the cache")


_RIG_STEPS = {"skeletonize": (0, 30), "skeleton-tree": (30, 55), "autorig": (55, 85), "bind": (85, 100)}


class VOLRIG_OT_rig(_OnVolume, bpy.types.Operator):
    """Build the skeleton-tree, the automatic armature and the binding from the skeleton at the current thinness:
    creates <name>_rig and <name>_spheres"""
    bl_idname = "volrig.rig"
    bl_label = "Rig"

    def run(self, context, vol):
        s = vol.volrig
        with _ProgressBar(context) as bar:
            progress = bar.steps(_RIG_STEPS)
            mask = scans.mask(vol)
            pts = scans.skeleton(vol, progress=progress).at(scans.thinness(vol))
            rigid = scans.rigid(vol)  # the rigid tissue (bone) places the limb joints too (docs/rig.md)
            r = pipeline.rig_skeleton(pts, mask, alpha=s.alpha, bones=s.bones, roles=s.roles, bind_mode=s.bind_mode,
                                      progress=progress, kind=None if s.body_plan == "AUTO" else s.body_plan,
                                      up=objects.scene_up(vol) if s.use_scene_up else None,
                                      own_scale=not s.rig_kept_points, rigid=rigid, bone=rigid,
                                      markers=markers.marker_points(vol) or None)
        _save_rig(vol, r.points, r.tree, r.rig, r.binding)
        s.rig_found = pipeline.describe_rig(r.rig)
        rig_obj = objects.build_armature(vol, r.rig)
        objects.build_spheres(vol, rig_obj, r.points, r.tree, r.binding)
        objects.attach_volume(vol, rig_obj)
        preview = objects.members(vol).get("SKELETON")
        if preview is not None:
            preview.hide_set(True)
        looks.refresh(vol)
        self.report(_found_level(r.rig.note),
                    f"volrig: {s.rig_found}: {len(r.rig)} bones on {len(r.points):,} spheres")
        return {"FINISHED"}


def _save_rig(vol, pts, tree, rig, binding) -> None:
    """Each rig gets a new file (so undo returns to a rig whose file still exists); the objects name it."""
    name = f"rig-{uuid.uuid4().hex[:8]}.vrig"
    volrig.save_rig(os.path.join(scans.cache_dir(vol), name), pts, tree, rig, binding, source="source.vdb")
    vol.volrig.rig_file = name
    vol.volrig.rigid_voxels = 0 if binding.rigid is None else int(np.count_nonzero(binding.rigid))


class VOLRIG_OT_rebind(_OnVolume, bpy.types.Operator):
    """Bind the spheres again to the armature as it is now (after moving, adding or deleting bones in edit mode);
    replaces the vertex groups"""
    bl_idname = "volrig.rebind"
    bl_label = "Rebind"
    modes, rigged = None, True

    def run(self, context, vol):
        parts = objects.members(vol)
        if "SPHERES" not in parts:
            raise volrig.VolrigError(f"{vol.name} has no sphere mesh: press Rig")
        if context.mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")  # edit bones reach the armature on leaving edit mode
        saved = volrig.load_rig(scans.rig_path(vol))
        rig = objects.armature_rig(parts["RIG"])
        mask = scans.mask(vol)
        binding = volrig.bind(saved.points, rig, mask, mode=vol.volrig.bind_mode, rigid=scans.rigid(vol))
        objects.set_vertex_groups(parts["SPHERES"], binding)
        _save_rig(vol, saved.points, saved.tree, rig, binding)
        looks.refresh(vol)
        self.report({"INFO"}, f"volrig: {len(saved.points):,} spheres bound to {len(rig)} bones")
        return {"FINISHED"}


class VOLRIG_OT_walk_cycle(_OnVolume, bpy.types.Operator):
    """Keyframe a procedural walk on a humanoid rig (thighs, shins, feet, arms swing about its left-right axis)"""
    bl_idname = "volrig.walk_cycle"
    bl_label = "Add Walk Cycle"
    modes, rigged = ("OBJECT", "POSE"), True

    frame_start: bpy.props.IntProperty(name="Start", default=1)
    frames: bpy.props.IntProperty(name="Frames", default=24, min=1, max=100000)
    period: FloatProperty(name="Stride", default=24.0, min=1.0, description="Frames per stride")
    amplitude: FloatProperty(name="Amplitude", default=1.0, min=0.0, soft_max=2.0, description="Angle scale")

    def run(self, context, vol):
        from mathutils import Quaternion, Vector
        from volrig.walk import walk_cycle
        rig_obj = objects.members(vol)["RIG"]
        axis, angles = walk_cycle(objects.armature_rig(rig_obj), self.frames, self.period, self.amplitude)
        for name, values in angles.items():
            pb = rig_obj.pose.bones[name]
            pb.rotation_mode = "QUATERNION"
            local_axis = pb.bone.matrix_local.to_3x3().transposed() @ Vector(axis)
            for i, angle in enumerate(values):
                pb.rotation_quaternion = Quaternion(local_axis, float(angle))
                pb.keyframe_insert("rotation_quaternion", frame=self.frame_start + i, group=name)
        scene = context.scene
        scene.frame_start, scene.frame_end = self.frame_start, self.frame_start + self.frames - 1
        scene.frame_set(self.frame_start)
        self.report({"INFO"}, f"volrig: walk on {len(angles)} bones over {self.frames} frames")
        return {"FINISHED"}


class VOLRIG_OT_thickness(_OnVolume, bpy.types.Operator):
    """Give every bone of the rig a keyframable Thickness (1 = as scanned): the bake thickens the volume around a
    bone by it"""
    bl_idname = "volrig.thickness"
    bl_label = "Thickness per Bone"
    modes, rigged = None, True

    def run(self, context, vol):
        for pb in objects.members(vol)["RIG"].pose.bones:
            objects.thickness_property(pb)
        self.report({"INFO"}, "volrig: select a bone in pose mode to set (and key) its thickness; Bake applies it")
        return {"FINISHED"}


class VOLRIG_PT_rig(_VolrigPanel, bpy.types.Panel):
    bl_label = "Rig"

    def draw(self, context):
        s, layout = _settings(self, context)
        vol = s.id_data
        _props(layout.column(align=True), s, "alpha", "bones", "roles", "rig_kept_points")
        row = layout.row(align=True)
        row.prop(s, "body_plan", text="")
        row.prop(s, "use_scene_up", toggle=True, icon="EMPTY_SINGLE_ARROW")
        _labelled(layout, s, "bind_mode", "rigid_by")
        if s.rigid_by == "LABELS":
            layout.prop(s, "rigid_labels")
        elif s.rigid_by == "RANGE":
            row = layout.row(align=True)
            row.prop(s, "rigid_low")
            row.prop(s, "rigid_high")
        markers.draw(layout, vol, context)
        row = layout.row(align=True)
        row.operator("volrig.rig", icon="ARMATURE_DATA")
        row.operator("volrig.rebind", icon="FILE_REFRESH")
        parts = objects.members(vol)
        if "RIG" in parts:
            layout.operator("volrig.walk_cycle", icon="ANIM")
            pb = context.active_pose_bone
            if pb is not None and pb.id_data == parts["RIG"] and objects.THICKNESS in pb:
                layout.prop(pb, f'["{objects.THICKNESS}"]', text=f"{pb.name} thickness", slider=True)
            else:
                layout.operator("volrig.thickness", icon="MOD_THICKNESS")
            layout.label(text=f"{parts['RIG'].name}: {len(parts['RIG'].data.bones)} bones", icon="BONE_DATA")
            if s.rig_found:
                _draw_found(layout, s.rig_found, context)
            if s.rigid_voxels:  # the rigid layer: bones move whole
                layout.label(text=f"rigid layer: {s.rigid_voxels:,} voxels", icon="MOD_SOLIDIFY")
        if "SPHERES" in parts:
            layout.label(text=f"{parts['SPHERES'].name}: {len(parts['SPHERES'].data.vertices):,} spheres",
                         icon="MESH_UVSPHERE")


CLASSES = (VOLRIG_OT_rig, VOLRIG_OT_rebind, VOLRIG_OT_walk_cycle, VOLRIG_OT_thickness, VOLRIG_PT_rig)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

"""Motion capture on the volrig armature: the bone map kept on the Volume object (``volrig.bone_map``, one
BVH joint -> rig bone pair per joint of the last clip; an empty bone leaves the joint unmapped), and the bake of
``volrig.animate``'s matrices to keyframes on the pose bones (location and rotation_quaternion).
The Drive with BVH and Map by Names operators, the bone map's list and the Motion capture panel."""
import os

import bpy
import numpy as np
from bpy.props import CollectionProperty, EnumProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper
from mathutils import Matrix

import volrig
from volrig import pipeline

from . import compat, objects
from .compat import BLEND_RELATIVE
from .ops_base import _OnVolume, _settings, _VolrigPanel


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

class VolrigBonePair(bpy.types.PropertyGroup):
    """One line of the motion capture bone map: a BVH joint and the rig bone it drives."""
    joint: StringProperty(name="BVH joint", description="A joint of the BVH clip")
    bone: StringProperty(name="Rig bone", description="The rig bone this joint drives (empty: not mapped)")


class MocapSettings:
    """The clip that last drove the rig and the bone map."""
    bvh_file: StringProperty(name="BVH", subtype="FILE_PATH", options=BLEND_RELATIVE,
                             description="The clip that last drove the rig")
    bone_map: CollectionProperty(type=VolrigBonePair, name="Bone map",
                                 description="BVH joint -> rig bone; Drive with BVH uses it for the same clip")
    bone_map_index: IntProperty(name="Bone map line", default=0)


def stored_bone_map(volume_obj, motion: volrig.Motion):
    """The map the panel shows, when it was made for this clip's joints; else None."""
    pairs = volume_obj.volrig.bone_map
    if sorted(p.joint for p in pairs) != sorted(motion.names):
        return None
    return {p.joint: p.bone for p in pairs if p.bone}


def store_bone_map(volume_obj, motion: volrig.Motion, bone_map) -> None:
    """Shows ``bone_map`` in the panel: one pair per BVH joint, in the clip's order."""
    pairs = volume_obj.volrig.bone_map
    pairs.clear()
    for name in motion.names:
        p = pairs.add()
        p.joint, p.bone = name, bone_map.get(name, "")


def key_pose(rig_obj, rig: volrig.Rig, matrices: np.ndarray, scene_frames) -> None:
    """Keyframes rest-to-pose matrices (F, B, 4, 4; bones in ``rig``'s order = the armature's) on the pose bones
    at ``scene_frames``, replacing the armature's pose-bone animation."""
    basis = rig.basis_matrices(matrices)
    n = len(scene_frames)
    loc = basis[:, :, :3, 3]
    quat = np.empty((n, len(rig), 4))
    for f in range(n):
        for b in range(len(rig)):
            quat[f, b] = Matrix(basis[f, b, :3, :3].tolist()).to_quaternion()
    # one sign per bone along the clip, so the keys interpolate the short way
    for f in range(1, n):
        flip = np.einsum("bi,bi->b", quat[f], quat[f - 1]) < 0
        quat[f, flip] *= -1
    fcurves = compat.fcurves(rig_obj)
    for fc in [fc for fc in fcurves if fc.data_path.startswith("pose.bones[")]:
        fcurves.remove(fc)
    co = np.empty(2 * n)
    co[0::2] = scene_frames
    for b, name in enumerate(rig.names):
        pb = rig_obj.pose.bones[name]
        pb.rotation_mode = "QUATERNION"
        pb.scale = (1.0, 1.0, 1.0)
        for prop, values in (("location", loc[:, b]), ("rotation_quaternion", quat[:, b])):
            path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].{prop}'
            for i in range(values.shape[1]):
                fc = compat.new_fcurve(fcurves, path, i, name)
                fc.keyframe_points.add(n)
                co[1::2] = values[:, i]
                fc.keyframe_points.foreach_set("co", co)
                for k in fc.keyframe_points:
                    k.interpolation = "LINEAR"
                fc.update()


class VOLRIG_OT_drive_with_bvh(_OnVolume, bpy.types.Operator, ImportHelper):
    """Drive the rig with a motion capture clip (.bvh): retarget it (volrig.animate) and key every pose bone, so
    Bake and render follow. Uses the bone map in the panel when it was made for this clip's joints"""
    bl_idname = "volrig.drive_with_bvh"
    bl_label = "Drive with BVH"
    modes, rigged = ("OBJECT", "POSE"), True

    filename_ext = ".bvh"
    filter_glob: StringProperty(default="*.bvh", options={"HIDDEN"})
    root_motion: EnumProperty(name="Root motion", items=[
        ("in_place", "In place", "The rig walks on the spot (feet still touch the floor)"),
        ("travel", "Travel", "The rig follows the clip's path over the floor, scaled"),
    ], default="in_place")
    up_axis: EnumProperty(name="Clip up axis", items=[("y", "Y", "Y-up clips (most BVH files)"),
                                                      ("z", "Z", "Z-up clips")], default="y")
    first: bpy.props.IntProperty(name="First BVH frame", default=1, min=1)
    last: bpy.props.IntProperty(name="Last BVH frame", default=0, min=0, description="0 = the clip's last frame")
    step: bpy.props.IntProperty(name="Step", default=1, min=1,
                                description="Key every STEP-th clip frame (e.g. 5 plays a 120 fps clip at 24 fps)")
    frame_start: bpy.props.IntProperty(name="Start frame", default=1, description="Scene frame of the first key")

    def run(self, context, vol):
        rig_obj = objects.members(vol)["RIG"]
        path = bpy.path.abspath(self.filepath)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"{path}: no such file")
        motion = volrig.read_bvh(path)
        frames = pipeline.clip_frames(motion.frame_count, f"{self.first}-{self.last or motion.frame_count}",
                                      self.step, anchor=self.first, what=os.path.basename(path))
        rig = objects.armature_rig(rig_obj)
        bone_map = stored_bone_map(vol, motion)
        if bone_map is None:
            bone_map = volrig.default_bone_map(motion, rig)
            store_bone_map(vol, motion, bone_map)  # shown (and editable) even if the retarget fails
        _, matrices = pipeline.mocap_poses(rig, motion, frames, bone_map, root_motion=self.root_motion,
                                           up_axis=self.up_axis)
        key_pose(rig_obj, rig, matrices, self.frame_start + np.arange(len(frames)))
        vol.volrig.bvh_file = path
        scene = context.scene
        scene.frame_start, scene.frame_end = self.frame_start, self.frame_start + len(frames) - 1
        fps = motion.fps / self.step
        scene.render.fps = max(1, round(fps))
        scene.render.fps_base = scene.render.fps / fps
        scene.frame_set(self.frame_start)
        self.report({"INFO"}, f"volrig: {len(frames)} frames of {os.path.basename(path)} keyed on "
                              f"{len(bone_map)} mapped bones of {len(rig)}, {fps:.4g} fps")
        return {"FINISHED"}


class VOLRIG_OT_reset_bone_map(_OnVolume, bpy.types.Operator):
    """Fill the bone map again from the names of the last clip's joints and the rig's bones"""
    bl_idname = "volrig.reset_bone_map"
    bl_label = "Map by Names"
    modes, rigged = None, True

    @classmethod
    def poll(cls, context):
        return super().poll(context) and bool(cls.volume(context).volrig.bvh_file)

    def run(self, context, vol):
        motion = volrig.read_bvh(bpy.path.abspath(vol.volrig.bvh_file))
        bone_map = volrig.default_bone_map(motion, objects.armature_rig(objects.members(vol)["RIG"]))
        store_bone_map(vol, motion, bone_map)
        self.report({"INFO"}, f"volrig: {len(bone_map)} of {len(motion.names)} joints mapped by name")
        return {"FINISHED"}


class VOLRIG_UL_bone_map(bpy.types.UIList):
    """One line per BVH joint: its name and the rig bone it drives (pick from the armature's bones)."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        rig = objects.members(data.id_data).get("RIG")
        row = layout.row(align=True)
        row.label(text=item.joint, icon="BONE_DATA" if item.bone else "BLANK1")
        if rig is not None:
            row.prop_search(item, "bone", rig.data, "bones", text="")
        else:
            row.prop(item, "bone", text="")


class VOLRIG_PT_mocap(_VolrigPanel, bpy.types.Panel):
    bl_label = "Motion capture"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s, layout = _settings(self, context)
        row = layout.row(align=True)
        row.operator("volrig.drive_with_bvh", icon="ARMATURE_DATA")
        row.operator("volrig.reset_bone_map", icon="FILE_REFRESH")
        if s.bvh_file:
            layout.label(text=bpy.path.basename(s.bvh_file), icon="FILE")
        if len(s.bone_map):
            mapped = sum(1 for p in s.bone_map if p.bone)
            layout.label(text=f"Bone map: {mapped} of {len(s.bone_map)} joints drive a bone")
            layout.template_list("VOLRIG_UL_bone_map", "", s, "bone_map", s, "bone_map_index", rows=6)
        else:
            layout.label(text="Bone map: made from the names on the first drive")


CLASSES = (VOLRIG_OT_drive_with_bvh, VOLRIG_OT_reset_bone_map, VOLRIG_UL_bone_map, VOLRIG_PT_mocap)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

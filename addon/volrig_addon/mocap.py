"""Motion capture on the volrig armature: the bone map kept on the Volume object (``volrig.bone_map``, one
BVH joint -> rig bone pair per joint of the last clip; an empty bone leaves the joint unmapped), and the bake of
``volrig.animate``'s matrices to keyframes on the pose bones (location and rotation_quaternion)."""
import bpy
import numpy as np
from mathutils import Matrix

import volrig

from . import compat


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

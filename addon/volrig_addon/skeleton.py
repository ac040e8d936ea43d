"""The skeleton: Skeletonize (the thinness skeleton, computed once; the Thinness slider re-thresholds it: scans.py)
and the Skeleton panel."""
import bpy
import numpy as np

from . import objects, scans
from .ops_base import _OnVolume, _ProgressBar, _settings, _VolrigPanel


class VOLRIG_OT_skeletonize(_OnVolume, bpy.types.Operator):
    """Segment the volume and compute its thinness skeleton once; the Thinness slider then re-thresholds it"""
    bl_idname = "volrig.skeletonize"
    bl_label = "Skeletonize"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            mask = scans.mask(vol)
            sk = scans.skeleton(vol, progress=bar.steps({"skeletonize": (0, 100)}))
        vol.volrig.mask_count = int(np.count_nonzero(mask.array))
        objects.update_skeleton_preview(vol)
        self.report({"INFO"}, f"volrig: {sk.object_count:,} object voxels; {vol.volrig.point_count:,} skeleton points "
                              f"at thinness {vol.volrig.thinness:g}")
        return {"FINISHED"}


class VOLRIG_PT_skeleton(_VolrigPanel, bpy.types.Panel):
    bl_label = "Skeleton"

    def draw(self, context):
        s, layout = _settings(self, context)
        layout.prop(s, "metric")
        layout.operator("volrig.skeletonize", icon="OUTLINER_OB_POINTCLOUD")
        layout.prop(s, "thinness", slider=True)
        row = layout.row()
        row.label(text=f"{s.point_count:,} points" if s.point_count >= 0 else "not skeletonized yet")
        row.prop(s, "show_spheres")


CLASSES = (VOLRIG_OT_skeletonize, VOLRIG_PT_skeleton)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

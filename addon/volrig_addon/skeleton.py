"""The skeleton: Skeletonize (the thinness skeleton, computed once; the Thinness slider re-thresholds it: scans.py)
and the Skeleton panel."""
import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from volrig.pipeline import DEFAULT_THINNESS_VOXELS

from . import objects, scans
from .ops_base import _OnVolume, _ProgressBar, _settings, _VolrigPanel


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

def _thinness_changed(self, context):
    objects.update_skeleton_preview(self.id_data)


class SkeletonSettings:
    """The distance metric and the thinness the skeleton is kept at."""
    metric: EnumProperty(name="Metric", items=[
        ("euclidean", "Euclidean", "Exact Euclidean distance, anisotropic spacing honoured (thinness 0 .. 1.416)"),
        ("chamfer345", "Chamfer <3,4,5>", "The thesis' chamfer distance (thinness 0 .. 4.077, grid units)"),
    ], default="euclidean")
    thinness: FloatProperty(name="Thinness", default=DEFAULT_THINNESS_VOXELS, min=0.0, max=4.1, soft_max=1.42,
                            precision=3, step=1, update=_thinness_changed,
                            description="Keep voxels whose thinness score exceeds this, in voxels (Euclidean: "
                                        "0 .. 1.416; chamfer <3,4,5>: 0 .. 4.077); larger = fewer spheres")
    point_count: IntProperty(name="Points", default=-1)
    show_spheres: BoolProperty(name="Spheres", default=True, update=_thinness_changed,
                               description="Show the skeleton's spheres scaled by radius (else points only)")


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

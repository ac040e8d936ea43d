"""Import and segment: the Import Volume operator (NRRD, MetaImage, NIfTI, OpenVDB, raw; File > Import too), the
import of a volume's samples into a new cache folder and Volume object (``import_samples``, also for drawings and
straightened volumes), Preview Mask, and the Volume and Segment panels (the Segment panel also holds the thickness
and medial surface and pore network buttons: medial.py)."""
import os
import uuid

import bpy
import numpy as np
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, IntVectorProperty,
                       StringProperty)
from bpy_extras.io_utils import ImportHelper

import volrig
from volrig import pipeline
from volrig.volume import FORMATS, format_of

from . import materials, objects, scans
from .compat import BLEND_RELATIVE
from .ops_base import _OnVolume, _reported, _settings, _VolrigPanel


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

UNIT_SCALES = [
    ("MM", "mm to m", "Volume units are millimetres (medical scans); 1 mm = 0.001 Blender units", 0),
    ("CM", "cm to m", "Volume units are centimetres; 1 cm = 0.01 Blender units", 1),
    ("M", "m", "Volume units are metres; no scaling", 2),
    ("CUSTOM", "Custom", "Blender units per volume unit", 3),
]
UNIT_FACTOR = {"MM": 0.001, "CM": 0.01, "M": 1.0}


def _segmentation_changed(self, context):
    scans.update_mask_count(self.id_data)


class VolumeSettings:
    """Where the volume came from (read-only in the UI) and how it is segmented."""
    # --- the source (read-only in the UI) ---
    source: StringProperty(name="Source", description="The file the volume was imported from (never modified)")
    cache_dir: StringProperty(name="Cache", subtype="DIR_PATH", options=BLEND_RELATIVE,
                              description="Folder holding this volume's source copy, rig file and baked frames")
    dims: IntVectorProperty(name="Voxels", size=3, description="Grid size (x, y, z)")
    spacing: FloatVectorProperty(name="Spacing", size=3, precision=4, description="Voxel size (x, y, z)")
    origin: FloatVectorProperty(name="Origin", size=3, precision=3, description="World position of voxel 0")
    value_min: FloatProperty(name="Minimum")
    value_max: FloatProperty(name="Maximum")
    unit_scale: FloatProperty(name="Unit scale", default=0.001, min=1e-9, precision=6,
                              description="Blender units per volume unit")

    # --- segmentation ---
    segment_by: EnumProperty(name="Segment by", items=[
        ("RANGE", "Range", "Object = samples between Low and High"),
        ("LABELS", "Labels", "Object = samples equal to one of the labels (label maps)"),
    ], default="RANGE", update=_segmentation_changed)
    low: FloatProperty(name="Low", default=1.0, update=_segmentation_changed,
                       description="Lowest object value (e.g. Hounsfield units)")
    high: FloatProperty(name="High", default=1e9, update=_segmentation_changed, description="Highest object value")
    labels: StringProperty(name="Labels", default="1", update=_segmentation_changed,
                           description="Object labels: numbers and ranges, e.g. '1 4 7-9'")
    largest: BoolProperty(name="Largest part only", default=True, update=_segmentation_changed,
                          description="Keep only the largest connected part of the object")
    mask_count: IntProperty(name="Object voxels", default=-1)


class VOLRIG_OT_import_volume(bpy.types.Operator, ImportHelper):
    """Import a volume (NRRD, MetaImage, NIfTI, DICOM, TIFF, VTK image data, OpenVDB or raw) for rigging"""
    bl_idname = "volrig.import_volume"
    bl_label = "Import Volume"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default=";".join("*" + e for e in FORMATS), options={"HIDDEN"})
    unit: EnumProperty(name="Units", items=UNIT_SCALES, default="MM")
    custom_scale: FloatProperty(name="Scale", default=1.0, min=1e-9, precision=6,
                                description="Blender units per volume unit (Custom)")
    name: StringProperty(name="Name", default="", description="Object name (default: the file name)")
    grid: StringProperty(name="VDB grid", default="", description="VDB files: grid to read (default density)")
    raw_dims: IntVectorProperty(name="Raw size", size=3, default=(0, 0, 0), min=0,
                                description="Raw files: voxels along x, y, z")
    raw_dtype: EnumProperty(name="Raw type", items=[(t, t, "") for t in (
        "uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64")], default="uint8")
    raw_spacing: FloatVectorProperty(name="Raw spacing", size=3, default=(1.0, 1.0, 1.0), min=1e-9)
    raw_big_endian: bpy.props.BoolProperty(name="Big-endian", default=False)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "name")
        layout.prop(self, "unit")
        if self.unit == "CUSTOM":
            layout.prop(self, "custom_scale")
        layout.prop(self, "grid")
        box = layout.box()
        box.label(text="Raw files (.raw .bin .img)")
        box.prop(self, "raw_dims")
        box.prop(self, "raw_dtype")
        box.prop(self, "raw_spacing")
        box.prop(self, "raw_big_endian")

    @_reported
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"{path}: no such file")
        raw = format_of(path) == "raw" and min(self.raw_dims) > 0
        vol = pipeline.float_samples(pipeline.load_source(
            path, dims=tuple(self.raw_dims) if raw else None, dtype=self.raw_dtype, spacing=tuple(self.raw_spacing),
            big_endian=self.raw_big_endian, grid=self.grid))
        scale = self.custom_scale if self.unit == "CUSTOM" else UNIT_FACTOR[self.unit]
        base = self.name or os.path.basename(path).split(".")[0] or "volume"
        obj = import_samples(context, vol, base, scale, source=path)
        x, y, z = vol.dims
        self.report({"INFO"}, f"volrig: {obj.name}: {x} x {y} x {z} voxels, spacing {tuple(vol.spacing)}; "
                              f"cache {scans.cache_dir(obj)}")
        return {"FINISHED"}


def import_samples(context, vol: volrig.Volume, name: str, unit_scale: float, source: str = ""):
    """Write ``vol`` (float32 samples) into a new cache folder as source.vdb and make its Volume object."""
    key = uuid.uuid4().hex[:8]
    root = scans.cache_root()
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in name)
    rel = os.path.join(root, f"{safe}-{key}")
    folder = bpy.path.abspath(rel)
    os.makedirs(folder, exist_ok=True)
    scans.write_source(folder, vol, source)
    obj = objects.create_volume_object(context, name, os.path.join(rel, "source.vdb"), unit_scale,
                                       vol.grid_to_world())
    s = obj.volrig
    s.source, s.cache_dir = source, rel
    scans.remember_source(obj, vol)
    s.dims, s.spacing, s.origin = vol.dims, vol.spacing, vol.origin
    d = pipeline.import_defaults(vol, unit_scale)
    s.value_min, s.value_max, s.low, s.high = d.value_min, d.value_max, d.low, d.high
    s.preset, s.sampling, s.density_scale = "LABELS" if d.label_map else "SOFT_TISSUE", d.sampling, d.density_scale
    if d.label_map:
        s.segment_by, s.labels = "LABELS", d.labels
    scans.update_mask_count(obj)
    materials.update_volume_material(obj)
    _take_tissue_table(obj, vol, source)
    for o in context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


def _take_tissue_table(obj, vol: volrig.Volume, source: str) -> None:
    """A label map with its tissue table beside the file (``volrig.find_tissue_table``; integer values, at most
    256 of them), or a frame baked with tissue looks (its classes in its metadata: ``volrig.tissues.file_classes``):
    segmented as its body codes, per-tissue looks on (nearest sampling), and Automatic rigid tissue then binds its
    bone."""
    some = np.unique(vol.array[:: max(1, vol.array.shape[0] // 32)])
    if not source or len(some) > 256 or not np.array_equal(some, np.round(some)):
        return
    codes = np.unique(vol.array)
    baked = volrig.tissues.file_classes(source)
    table = "" if baked else volrig.find_tissue_table(source, codes)
    if not table and not baked:
        return
    s = obj.volrig
    if baked:
        body = sorted({c for t in baked for c in t.codes} & {int(c) for c in codes})
    else:
        body = volrig.tissues.body_codes(volrig.read_tissue_table(table), codes)
    s.segment_by, s.labels = "LABELS", pipeline.labels_text(body)
    s.tissue_table = table
    s.use_tissues = True
    scans.update_mask_count(obj)


class VOLRIG_OT_preview_mask(_OnVolume, bpy.types.Operator):
    """Show the segmentation mask over the scan as <name>_mask (updated each time it is pressed)"""
    bl_idname = "volrig.preview_mask"
    bl_label = "Preview Mask"

    def run(self, context, vol):
        mask = scans.mask(vol)
        count = int(np.count_nonzero(mask.array))
        objects.update_mask_preview(vol, mask)
        vol.volrig.mask_count = count
        self.report({"INFO"}, f"volrig: mask of {count:,} voxels shown as {vol.name}_mask")
        return {"FINISHED"}


def menu_import(self, context):
    self.layout.operator(VOLRIG_OT_import_volume.bl_idname, text="Volume for rigging (volrig)")


class VOLRIG_PT_volume(_VolrigPanel, bpy.types.Panel):
    bl_label = "Volume"

    @classmethod
    def poll(cls, context):
        return True  # the import button is always there

    def draw(self, context):
        layout = self.layout
        layout.operator("volrig.import_volume", icon="IMPORT")
        layout.operator("volrig.import_drawing", icon="IMAGE_DATA")
        vol = objects.volume_of(context.active_object)
        if vol is None:
            layout.label(text="Select a volrig volume, or import one")
            return
        s = vol.volrig
        col = layout.column(align=True)
        col.label(text=vol.name, icon="VOLUME_DATA")
        x, y, z = s.dims
        col.label(text=f"{x} x {y} x {z} voxels")
        col.label(text="spacing " + " x ".join(f"{v:g}" for v in s.spacing))
        col.label(text=f"values {s.value_min:g} .. {s.value_max:g}")
        col.prop(s, "unit_scale")
        if s.source:
            col.label(text=bpy.path.basename(s.source), icon="FILE")


class VOLRIG_PT_segment(_VolrigPanel, bpy.types.Panel):
    bl_label = "Segment"

    def draw(self, context):
        s, layout = _settings(self, context)
        layout.prop(s, "segment_by", expand=True)
        if s.segment_by == "RANGE":
            row = layout.row(align=True)
            row.prop(s, "low")
            row.prop(s, "high")
        else:
            layout.prop(s, "labels")
        layout.prop(s, "largest")
        layout.label(text=f"{s.mask_count:,} voxels in range" if s.mask_count >= 0 else "invalid segmentation",
                     icon="INFO" if s.mask_count > 0 else "ERROR")
        layout.operator("volrig.preview_mask", icon="HIDE_OFF")
        layout.operator("volrig.show_thickness", icon="MOD_THICKNESS")  # (one row each: the sidebar is narrow)
        layout.prop(s, "plane_t")
        layout.operator("volrig.medial_surface", icon="SURFACE_NSURFACE")
        layout.operator("volrig.pore_network", icon="MESH_UVSPHERE")


CLASSES = (VOLRIG_OT_import_volume, VOLRIG_OT_preview_mask, VOLRIG_PT_volume, VOLRIG_PT_segment)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)

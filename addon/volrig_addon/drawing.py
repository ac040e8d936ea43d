"""Import Drawing: a front-view drawing (PNG) becomes a rigged, coloured volume (``volrig.drawing`` does the work).

The drawing is inflated (``volrig.drawing.colour_labels``) into a label volume whose labels index the drawing's
colours, imported like any volume (``volume.import_samples``), segmented by those labels, rendered through the
drawing's palette (the LABELS look with the object's ``volrig_palette``), skeletonized and rigged with the chosen body
plan and the scene's +Z as up (the drawing's up). Labels are resampled nearest when the volume is baked in a pose, so
the colours stay on their parts. Optionally a mesh follows the volume through Blender's Volume to Mesh modifier.
"""
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

import volrig
from volrig import drawing as drawings

from . import materials
from .ops_base import _reported
from .rig import BODY_PLANS
from .volume import import_samples


def body_plan_property():
    """The Body plan option of Import Drawing and Rig Mesh: the template the rig is fitted to (the Rig panel's)."""
    return EnumProperty(name="Body plan", items=BODY_PLANS,
                        description="The template the rig is fitted to (Best fit: every template, the best kept)")


def drawing_volume(context, path: str, *, height: float, resolution: int, depth_scale: float, gap: int,
                   body_plan: str = "AUTO"):
    """Imports the drawing at ``path`` as a volrig Volume object ``height`` Blender units tall, coloured and set up
    to rig (``body_plan``, scene up); returns the object (not yet rigged)."""
    labels, palette = drawings.colour_labels(path, resolution=resolution, depth_scale=depth_scale, gap=gap)
    tall = labels.array.any(axis=(1, 2)).sum() * labels.spacing[2]
    name = os.path.splitext(os.path.basename(path))[0] or "drawing"
    obj = import_samples(context, labels, name, height / tall, source=path)
    s = obj.volrig
    s.segment_by, s.labels, s.preset, s.sampling = "LABELS", f"1-{len(palette)}", "LABELS", "nearest"
    s.body_plan, s.use_scene_up = body_plan, True
    linear = np.where(palette <= 0.04045, palette / 12.92, ((palette + 0.055) / 1.055) ** 2.4)  # sRGB -> scene
    obj["volrig_palette"] = [float(c) for c in linear.ravel()]
    whole_labels_only(materials.update_volume_material(obj))
    return obj


def whole_labels_only(mat) -> None:
    """Makes the volume material opaque only where the label grid holds a whole label (within 0.05). Cycles
    interpolates the grid, so across the surface a part labelled 3 passes through 1 and 2: without this, every part
    would wear a thin shell of colour 1 over its own colour. The volume material's own nodes are kept (it is still
    updated by ``materials.update_volume_material``); a test multiplies its opacity."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    if "volrig whole label" in nodes:
        return
    rounded = nodes.new("ShaderNodeMath")
    rounded.operation = "ROUND"
    whole = nodes.new("ShaderNodeMath")
    whole.name = whole.label = "volrig whole label"
    whole.operation = "COMPARE"
    whole.inputs[2].default_value = 0.05
    solid = nodes.new("ShaderNodeMath")
    solid.operation = "MULTIPLY"
    density = nodes["volrig density"].outputs["Fac"]
    links.new(density, rounded.inputs[0])
    links.new(density, whole.inputs[0])
    links.new(rounded.outputs[0], whole.inputs[1])
    links.new(nodes["volrig opacity"].outputs[0], solid.inputs[0])
    links.new(whole.outputs[0], solid.inputs[1])
    for shader in ("volrig scatter", "volrig absorb", "volrig glow_density"):
        target = nodes[shader].inputs["Density"] if shader != "volrig glow_density" else nodes[shader].inputs[1]
        links.new(solid.outputs[0], target)


def add_mesh(context, volume_obj):
    """A mesh object showing ``volume_obj``'s surface through a Volume to Mesh modifier (it follows the baked
    frames), in the volume's collection."""
    mesh = bpy.data.meshes.new(volume_obj.name + "_mesh")
    obj = bpy.data.objects.new(mesh.name, mesh)
    volume_obj.users_collection[0].objects.link(obj)
    mod = obj.modifiers.new("volrig surface", "VOLUME_TO_MESH")
    mod.object = volume_obj
    mod.threshold = 0.5
    obj.matrix_world = volume_obj.matrix_world.copy()
    return obj


class VOLRIG_OT_import_drawing(bpy.types.Operator, ImportHelper):
    """Import a front-view drawing (PNG with transparency, or on a light background): inflate it into a rounded
    volume coloured by the drawing and rig it (the drawing's up is the scene's +Z)"""
    bl_idname = "volrig.import_drawing"
    bl_label = "Import Drawing"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.png", options={"HIDDEN"})
    height: FloatProperty(name="Height", default=2.0, min=1e-6, description="The figure's height in Blender units")
    resolution: IntProperty(name="Resolution", default=200, min=32, max=2000,
                            description="Voxels along the drawing's longer side (larger drawings are scaled down)")
    depth_scale: FloatProperty(name="Roundness", default=1.0, min=0.05, max=4.0,
                               description="Depth of the parts relative to round cross-sections (lower: flatter)")
    gap: IntProperty(name="Gap", default=0, min=0, max=20,
                     description="Voxels between a part drawn in front (an arm across the body) and what is behind")
    body_plan: body_plan_property()
    rig: BoolProperty(name="Rig", default=True, description="Skeletonize and rig the volume after importing it")
    mesh: BoolProperty(name="Mesh", default=False,
                       description="Also add a mesh of the surface (Volume to Mesh modifier; follows the bake)")

    @_reported
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"{path}: no such file")
        obj = drawing_volume(context, path, height=self.height, resolution=self.resolution,
                             depth_scale=self.depth_scale, gap=self.gap, body_plan=self.body_plan)
        if self.rig:
            for op in (bpy.ops.volrig.skeletonize, bpy.ops.volrig.rig):
                if op() != {"FINISHED"}:
                    raise volrig.VolrigError(f"{obj.name}: imported, but {op.idname()} failed (see the report)")
        if self.mesh:
            add_mesh(context, obj)
        context.view_layer.objects.active = obj
        self.report({"INFO"}, f"volrig: {obj.name} from {os.path.basename(path)}"
                              + (f": {obj.volrig.rig_found}" if self.rig else ""))
        return {"FINISHED"}


def menu_import(self, context):
    self.layout.operator(VOLRIG_OT_import_drawing.bl_idname, text="Drawing as a rigged volume (volrig)")


def register():
    bpy.utils.register_class(VOLRIG_OT_import_drawing)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(VOLRIG_OT_import_drawing)

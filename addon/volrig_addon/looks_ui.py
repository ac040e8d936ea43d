"""Looks and tissues: the Look panel (transfer function, density, highlight; the word on Cycles and grids).
The Parts panel (under Look): the rig's parts in a list, each with visible, colour and opacity (looks.py), the
*Find Parts* button, and the *Explode* factor the bake applies. The Tissues panel (under Look): a label map's
tissue classes in a list, each with visible, colour and opacity (tissue_looks.py), and the tissue table."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, StringProperty)

from . import engines, looks, materials, objects, tissue_looks
from .compat import BLEND_RELATIVE
from .ops_base import _labelled, _OnVolume, _settings, _VolrigPanel


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

#: The transfer-function presets (materials.PRESETS and the lumen view); stored by position: append only.
PRESET_ITEMS = [
    ("CT_BONE", "CT bone", "Dense values opaque and bone-white, soft values transparent"),
    ("SOFT_TISSUE", "Soft tissue", "Low values reddish and translucent, dense values white"),
    ("LABELS", "Label map", "One colour per integer label"),
    ("GREY", "Grey", "Density proportional to the value"),
    ("LUMEN", "Lumen view", "The segmented range clear, every other value an opaque pink wall: for cameras "
                            "inside a hollow organ (Fly Through sets it)"),
]


def _look_changed(self, context):
    materials.update_volume_material(self.id_data)


def _parts_toggled(self, context):
    looks.parts_toggled(self.id_data)


def _substitute_changed(self, context):
    looks.substitute_changed(self.id_data)


def _tissues_toggled(self, context):
    tissue_looks.toggled(self.id_data)


class VolrigPart(bpy.types.PropertyGroup):
    """One line of the Parts list: a group of bones ("left arm") and its look (see looks.py)."""
    key: StringProperty(name="Key", description="The part's grids: density_<key> and mask_<key>")
    bones: StringProperty(name="Bones", description="The part's bones, comma-separated")
    visible: BoolProperty(name="Visible", default=True, update=_look_changed,
                          description="Show the part's voxels (hidden: rendered as if they were empty)")
    colored: BoolProperty(name="Colour", default=False, update=_look_changed,
                          description="Give the part its own colour instead of the transfer function's")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, default=(0.9, 0.15, 0.1), min=0.0, max=1.0,
                               update=_look_changed)
    opacity: FloatProperty(name="Opacity", default=1.0, min=0.0, soft_max=1.0, max=10.0, update=_look_changed,
                           description="The part's opacity, a factor on the transfer function's")
    preset: EnumProperty(name="Transfer function", update=_look_changed, items=[
        ("VOLUME", "Volume's", "The volume's transfer function (with this part's colour and opacity)")]
        + [item for item in PRESET_ITEMS if item[0] != "LUMEN"],
        description="The part's own transfer function over its values (the volume's value range), or the volume's")
    substitute: StringProperty(name="Substitute", subtype="FILE_PATH", options=BLEND_RELATIVE,
                               update=_substitute_changed,
                               description="Take this part's values from another volume file in the same world frame "
                                           "(any voxel size): the full-resolution scan under a downsampled one, or "
                                           "another co-registered scan (its values through the same transfer "
                                           "function); empty: the volume's own")


class VolrigTissue(bpy.types.PropertyGroup):
    """One line of the Tissues list: a class of a label map's codes ("bone": 84, 92, 172) and its look
    (tissue_looks.py)."""
    key: StringProperty(name="Key", description="The class's name in the material's nodes (a part key)")
    codes: StringProperty(name="Codes", description="The label map's codes in this class, comma-separated")
    visible: BoolProperty(name="Visible", default=True, update=_look_changed,
                          description="Show the class's voxels (hidden: rendered as if they were empty)")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, default=(0.8, 0.8, 0.8), min=0.0, max=1.0,
                               update=_look_changed)
    opacity: FloatProperty(name="Opacity", default=1.0, min=0.0, soft_max=1.0, max=100.0, precision=3,
                           update=_look_changed,
                           description="The class's opacity (times the Density multiplier)")


class LookSettings:
    """The transfer function, the highlight, and the looks by part and by tissue."""
    preset: EnumProperty(name="Transfer function", items=PRESET_ITEMS, default="SOFT_TISSUE", update=_look_changed)
    density_scale: FloatProperty(name="Density", default=1.0, min=0.0, soft_max=100.0, update=_look_changed,
                                 description="Density multiplier (per Blender unit of the scaled object)")
    highlight_bone: StringProperty(name="Highlight bone", update=_look_changed,
                                   description="Make this bone's part of the volume glow (needs a baked frame)")
    highlight_strength: FloatProperty(name="Glow", default=2.0, min=0.0, soft_max=20.0, update=_look_changed)
    highlight_color: FloatVectorProperty(name="Glow colour", subtype="COLOR", size=3, default=(1.0, 0.35, 0.05),
                                         min=0.0, max=1.0, update=_look_changed)
    use_parts: BoolProperty(name="Per-part looks", default=False, update=_parts_toggled,
                            description="Give each part of the rig its own look (visible, colour, opacity): the rest "
                                        "volume and every baked frame get two grids per part (bakes take about "
                                        "twice as long; bake again for frames baked without them)")
    parts: CollectionProperty(type=VolrigPart, name="Parts",
                              description="The rig's parts (bone groups), each with its own look")
    parts_index: IntProperty(name="Part", default=0)
    use_tissues: BoolProperty(name="Per-tissue looks", default=False, update=_tissues_toggled,
                              description="Label maps: give each tissue class (skin, muscle, bone, ... from the "
                                          "tissue table, or each label without one) its own colour, opacity and "
                                          "visibility; the rest volume and every baked frame get one grid per "
                                          "class, baked with nearest sampling")
    tissue_table: StringProperty(name="Tissue table", subtype="FILE_PATH", options=BLEND_RELATIVE,
                                 update=_tissues_toggled,
                                 description="A TSV or CSV file of tissue codes and names (code, name per line), "
                                             "matched against volrig's tissue classes; empty: one class per label")
    tissues: CollectionProperty(type=VolrigTissue, name="Tissues",
                                description="The label map's tissue classes, each with its own look")
    tissues_index: IntProperty(name="Tissue", default=0)
    explode: FloatProperty(name="Explode", default=0.0, min=0.0, soft_max=2.0,
                           description="Bake each part moved away from its parent by this many times its length "
                                       "(animatable; added to the animated pose)")


class VOLRIG_PT_look(_VolrigPanel, bpy.types.Panel):
    bl_label = "Look"

    def draw(self, context):
        s, layout = _settings(self, context)
        vol = s.id_data
        col = layout.column()
        col.active = not s.use_tissues  # (per-tissue looks colour the volume instead)
        _labelled(col, s, "preset", text="Transfer")
        layout.prop(s, "density_scale")
        rig = objects.members(vol).get("RIG")
        split = layout.split(factor=0.45)
        split.label(text="Highlight")
        if rig is not None:
            split.prop_search(s, "highlight_bone", rig.data, "bones", text="")
        else:
            split.prop(s, "highlight_bone", text="")
        split = layout.split(factor=0.45)
        split.label(text="Glow")
        row = split.row(align=True)
        row.prop(s, "highlight_strength", text="")
        row.prop(s, "highlight_color", text="")
        if engines.known() and not engines.cycles_renders_grids():
            box = layout.box()
            box.label(text="Cycles here renders no VDBs", icon="ERROR")  # (engines.NO_GRIDS, in lines the
            box.label(text="(built without NanoVDB):")                  # sidebar's width holds)
            box.label(text="rendering with EEVEE; use a")
            box.label(text="blender.org build for Cycles")
            mat = vol.data.materials[0] if len(vol.data.materials) else None
            if engines.check_material(mat):
                box.label(text=f"{engines.grids_read(mat)} grids: EEVEE reads {engines.EEVEE_GRIDS}",
                          icon="ERROR")
                box.label(text="hide some tissues or parts")


class _UnderLook(_VolrigPanel):
    """The panels under the Look panel (Parts, Tissues)."""
    bl_parent_id = "VOLRIG_PT_look"


class VOLRIG_OT_find_parts(_OnVolume, bpy.types.Operator):
    """Group the rig's bones into parts (left arm, spine, head ... from the bone names; one part per chain
    otherwise), keeping the looks of parts already listed, and write the rest volume's part grids"""
    bl_idname = "volrig.find_parts"
    bl_label = "Find Parts"
    rigged = True

    def run(self, context, vol):
        n = looks.refresh(vol)
        self.report({"INFO"}, f"volrig: {n} parts (bake again for the frames' part grids)")
        return {"FINISHED"}


class _LookList:
    """A list of looks, a line each: visible (the eye), the name on ``_split`` of the width, then the colour (behind
    a toggle where ``_coloured_toggle``) and the opacity."""
    _split = 0.5
    _coloured_toggle = True

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.split(factor=self._split)
        left = row.row(align=True)
        left.prop(item, "visible", text="", icon="HIDE_OFF" if item.visible else "HIDE_ON", emboss=False)
        left.label(text=item.name)
        right = row.row(align=True)
        right.active = item.visible
        if self._coloured_toggle:
            right.prop(item, "colored", text="", icon="COLOR")
        if not self._coloured_toggle or item.colored:
            right.prop(item, "color", text="")
        right.prop(item, "opacity", text="", slider=True)


class VOLRIG_UL_parts(_LookList, bpy.types.UIList):
    """One line per part: visible, name, own colour, opacity."""


class VOLRIG_PT_parts(_UnderLook, bpy.types.Panel):
    bl_label = "Parts"

    def draw(self, context):
        s, layout = _settings(self, context)
        layout.prop(s, "use_parts")
        if s.use_parts and s.baked_end >= s.baked_start:
            layout.label(text="Bake again if frames were baked without parts", icon="INFO")
        if s.use_parts:
            layout.operator("volrig.find_parts", icon="GROUP_BONE")
        if s.use_parts and len(s.parts):
            layout.template_list("VOLRIG_UL_parts", "", s, "parts", s, "parts_index", rows=6)
            if 0 <= s.parts_index < len(s.parts):
                part = s.parts[s.parts_index]
                layout.label(text=part.bones.replace(",", ", "), icon="BONE_DATA")
                layout.prop(part, "preset")
                layout.prop(part, "substitute")
        layout.prop(s, "explode")


class VOLRIG_OT_find_tissues(_OnVolume, bpy.types.Operator):
    """Group the label map's codes into tissue classes (from the tissue table; one per label without one), keeping
    the looks of classes already listed, and write the rest volume's tissue grids"""
    bl_idname = "volrig.find_tissues"
    bl_label = "Find Tissues"

    def run(self, context, vol):
        n = tissue_looks.refresh(vol)
        self.report({"INFO"}, f"volrig: {n} tissue classes (bake again for the frames' tissue grids)")
        return {"FINISHED"}


class VOLRIG_UL_tissues(_LookList, bpy.types.UIList):
    """One line per tissue class: visible, name, colour, opacity."""
    _split = 0.45
    _coloured_toggle = False


class VOLRIG_PT_tissues(_UnderLook, bpy.types.Panel):
    bl_label = "Tissues"

    def draw(self, context):
        s, layout = _settings(self, context)
        layout.prop(s, "use_tissues")
        if not s.use_tissues:
            return
        layout.prop(s, "tissue_table")
        if s.baked_end >= s.baked_start:
            layout.label(text="Bake again if frames were baked without tissues", icon="INFO")
        if s.sampling != "nearest":
            layout.label(text="Label maps bake with Nearest sampling", icon="ERROR")
        layout.operator("volrig.find_tissues", icon="MATERIAL")
        if len(s.tissues):
            layout.template_list("VOLRIG_UL_tissues", "", s, "tissues", s, "tissues_index", rows=6)
            if 0 <= s.tissues_index < len(s.tissues):
                layout.label(text="codes " + s.tissues[s.tissues_index].codes.replace(",", ", "))


CLASSES = (VOLRIG_PT_look, VOLRIG_OT_find_parts, VOLRIG_UL_parts, VOLRIG_PT_parts, VOLRIG_OT_find_tissues,
           VOLRIG_UL_tissues, VOLRIG_PT_tissues)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

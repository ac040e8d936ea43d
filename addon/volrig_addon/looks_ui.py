"""Looks and tissues: the Look panel (transfer function, density, highlight; the word on Cycles and grids).
The Parts panel (under Look): the rig's parts in a list, each with visible, colour and opacity (looks.py), the
*Find Parts* button, and the *Explode* factor the bake applies. The Tissues panel (under Look): a label map's
tissue classes in a list, each with visible, colour and opacity (tissue_looks.py), and the tissue table."""
import bpy

from . import engines, looks, objects, tissue_looks
from .ops_base import _labelled, _OnVolume, _settings, _VolrigPanel


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


def _look_line(layout, item, split, coloured_toggle):
    """A list line: visible (the eye), name, then colour (behind a toggle for parts) and opacity."""
    row = layout.split(factor=split)
    left = row.row(align=True)
    left.prop(item, "visible", text="", icon="HIDE_OFF" if item.visible else "HIDE_ON", emboss=False)
    left.label(text=item.name)
    right = row.row(align=True)
    right.active = item.visible
    if coloured_toggle:
        right.prop(item, "colored", text="", icon="COLOR")
    if not coloured_toggle or item.colored:
        right.prop(item, "color", text="")
    right.prop(item, "opacity", text="", slider=True)


class VOLRIG_UL_parts(bpy.types.UIList):
    """One line per part: visible, name, own colour, opacity."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        _look_line(layout, item, 0.5, coloured_toggle=True)


class VOLRIG_PT_parts(_VolrigPanel, bpy.types.Panel):
    bl_label = "Parts"
    bl_parent_id = "VOLRIG_PT_look"

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


class VOLRIG_UL_tissues(bpy.types.UIList):
    """One line per tissue class: visible, name, colour, opacity."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        _look_line(layout, item, 0.45, coloured_toggle=False)


class VOLRIG_PT_tissues(_VolrigPanel, bpy.types.Panel):
    bl_label = "Tissues"
    bl_parent_id = "VOLRIG_PT_look"

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

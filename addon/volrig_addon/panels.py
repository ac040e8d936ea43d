"""The "volrig" tab of the 3D view's sidebar: Volume, Segment, Skeleton, Rig, Motion capture, Look and Bake panels
for the volrig set of the active object."""
import bpy

from . import engines, objects


def _settings(panel, context):
    """(the volrig settings of the active object's volume, the panel's layout)."""
    return objects.volume_of(context.active_object).volrig, panel.layout


def _props(layout, settings, *names) -> None:
    for name in names:
        layout.prop(settings, name)


def _labelled(layout, settings, *names, text: str = "") -> None:
    """Drop-downs and text fields with their names on the left half (the sidebar's default cuts them to a few
    letters: "Bindi...", "Rigid ..."); ``text`` replaces a single property's name."""
    for name in names:
        split = layout.split(factor=0.45)
        split.label(text=text or settings.bl_rna.properties[name].name)
        split.prop(settings, name, text="")


class _VolrigPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "volrig"

    @classmethod
    def poll(cls, context):
        return objects.volume_of(context.active_object) is not None


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
            if s.rig_found:  # "humanoid, fit 0.93 (runner-up chains 0.61)": kind and fit, then the runner-up
                found, _, runner_up = s.rig_found.partition(" (")
                col = layout.column(align=True)
                col.label(text=found, icon="INFO")
                if runner_up:
                    col.label(text=runner_up.rstrip(")"), icon="BLANK1")
            if s.rigid_voxels:  # the rigid layer: bones move whole
                layout.label(text=f"rigid layer: {s.rigid_voxels:,} voxels", icon="MOD_SOLIDIFY")
        if "SPHERES" in parts:
            layout.label(text=f"{parts['SPHERES'].name}: {len(parts['SPHERES'].data.vertices):,} spheres",
                         icon="MESH_UVSPHERE")


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


class VOLRIG_PT_centerline(_VolrigPanel, bpy.types.Panel):
    """Fly-through and straightening along the centerline of a tubular object (airways, colon, vessels)."""
    bl_label = "Centerline"

    def draw(self, context):
        s, layout = _settings(self, context)
        vol = s.id_data
        layout.prop(s, "fly_ends", expand=True)
        if s.fly_ends == "POINTS":
            col = layout.column(align=True)
            col.prop(s, "fly_start")
            col.prop(s, "fly_end")
        box = layout.box()
        box.label(text="Fly-through", icon="CAMERA_DATA")
        col = box.column(align=True)
        _props(col, s, "frames_per_mm", "look_ahead", "fly_fov", "fly_light", "fly_frame_start")
        box.operator("volrig.fly_through", icon="VIEW_CAMERA")
        parts = objects.members(vol)
        if "CAMERA" in parts:
            box.label(text=f"{parts['CAMERA'].name}: frames {context.scene.frame_start} .. "
                           f"{context.scene.frame_end}", icon="INFO")
        box = layout.box()
        box.label(text="Straighten", icon="IPO_LINEAR")
        box.prop(s, "straighten_radius")
        box.operator("volrig.straighten", icon="VOLUME_DATA")
        row = box.row(align=True)
        row.prop(s, "straighten_bones")
        row.prop(s, "straighten_frames")
        box.operator("volrig.straightening_rig", icon="ARMATURE_DATA")


class VOLRIG_PT_bake(_VolrigPanel, bpy.types.Panel):
    bl_label = "Bake"

    def draw(self, context):
        s, layout = _settings(self, context)
        _labelled(layout, s, "deform_mode")
        row = layout.row()
        row.active = s.deform_mode != "rigid"
        row.prop(s, "keep_volume")
        _labelled(layout, s, "sampling", "bake_frames")
        layout.prop(s, "lattice_tables")
        row = layout.row(align=True)
        row.operator("volrig.bake", icon="RENDER_ANIMATION")
        row.operator("volrig.show_rest", icon="VOLUME_DATA")
        layout.prop(context.scene, "volrig_live_preview")
        layout.operator("volrig.find_contacts", icon="MOD_PHYSICS")
        if s.baked_end >= s.baked_start:
            layout.label(text=f"plays frames {s.baked_start} .. {s.baked_end}")


CLASSES = (VOLRIG_PT_volume, VOLRIG_PT_segment, VOLRIG_PT_skeleton, VOLRIG_PT_rig, VOLRIG_PT_mocap, VOLRIG_PT_look,
           VOLRIG_PT_centerline, VOLRIG_PT_bake)


def register():
    bpy.utils.register_class(VOLRIG_UL_bone_map)
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
    bpy.utils.unregister_class(VOLRIG_UL_bone_map)

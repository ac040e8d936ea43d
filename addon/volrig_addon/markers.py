"""Markers: the Rig panel's Markers step (as Mixamo and AccuRIG ask for the chin, wrists, knees and groin). The
user picks a joint's name and clicks the volume in the viewport: the marker goes half-way through the part under
the mouse (``volrig.ray_marker``), where the joint lies, and the next missing name is picked. Markers are Empties
parented to the volume (saved with the .blend, moved with G like any object); Rig passes them to autorig as hard
constraints of its body plan (``autorig(markers=)``)."""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatVectorProperty

import volrig

from . import objects, scans
from .ops_base import _OnVolume, _reported

#: The markers the panel asks for first, in this order: with them the plan and every limb come out right.
ASKED = ("chin", "wrist.L", "wrist.R", "groin", "knee.L", "knee.R")


def markers_of(volume_obj) -> dict:
    """{marker name: Empty} of the volume's markers."""
    return {o.volrig.marker: o for o in bpy.data.objects
            if o.volrig.role == "MARKER" and o.volrig.volume == volume_obj}


def marker_points(volume_obj) -> dict:
    """{marker name: (x, y, z)} in the volume's own frame (volrig's world), for autorig's ``markers``."""
    to_volume = volume_obj.matrix_world.inverted_safe()
    return {name: tuple(to_volume @ o.matrix_world.translation) for name, o in markers_of(volume_obj).items()}


def missing(volume_obj) -> list:
    """The asked-for markers not placed yet, in ASKED order."""
    have = markers_of(volume_obj)
    return [n for n in ASKED if n not in have]


def place(volume_obj, name: str, point) -> bpy.types.Object:
    """Creates or moves the Empty of marker ``name`` to ``point`` (the volume's frame)."""
    if name not in volrig.MARKER_NAMES:
        raise volrig.VolrigError(f"unknown marker {name!r}")
    obj = markers_of(volume_obj).get(name)
    if obj is None:
        obj = objects._new_object(volume_obj, f"{volume_obj.name}_marker_{name}", None, "MARKER")
        obj.volrig.marker = name
        obj.empty_display_type = "SPHERE"
        obj.show_in_front = True
        obj.show_name = True
        obj.parent = volume_obj
    s = volume_obj.volrig  # a sphere 1.5% of the volume's longest side across
    obj.empty_display_size = 0.015 * max(d * h for d, h in zip(s.dims, s.spacing))
    obj.matrix_parent_inverse.identity()
    obj.location = tuple(float(v) for v in point)
    return obj


def _advance(settings, volume_obj) -> bool:
    """Picks the next missing marker's name; False when none is missing."""
    left = missing(volume_obj)
    if left:
        settings.marker_name = left[0]
    return bool(left)


class VOLRIG_OT_place_marker(_OnVolume, bpy.types.Operator):
    """Click on the volume to place the chosen marker inside the part under the mouse; the next missing marker is
    picked after each click (right-click or Esc: done)"""
    bl_idname = "volrig.place_marker"
    bl_label = "Place Markers"

    location: FloatVectorProperty(name="Location", size=3, options={"SKIP_SAVE"},
                                  description="Place the chosen marker here (world), without clicking")
    use_location: BoolProperty(name="Use Location", default=False, options={"SKIP_SAVE"})

    def run(self, context, vol):
        from mathutils import Vector
        point = vol.matrix_world.inverted_safe() @ Vector(self.location)
        place(vol, vol.volrig.marker_name, point)
        _advance(vol.volrig, vol)
        return {"FINISHED"}

    @_reported
    def invoke(self, context, event):
        vol = self.volume(context)
        if self.use_location:
            return self.run(context, vol)
        if context.area is None or context.area.type != "VIEW_3D":
            raise volrig.VolrigError("place markers in a 3D viewport")
        self._vol = vol
        self._mask = scans.mask(vol)
        context.window_manager.modal_handler_add(self)
        self._say(context)
        return {"RUNNING_MODAL"}

    def _say(self, context):
        context.area.header_text_set(f"volrig: click the {self._vol.volrig.marker_name} "
                                     "(right-click or Esc: done; middle mouse and wheel move the view)")

    def modal(self, context, event):
        if event.type in {"RIGHTMOUSE", "ESC"}:
            context.area.header_text_set(None)
            return {"FINISHED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"PASS_THROUGH"}
        point = self._ray(context, event)
        if point is None:
            self.report({"WARNING"}, "volrig: the click missed the volume's object")
            return {"RUNNING_MODAL"}
        place(self._vol, self._vol.volrig.marker_name, point)
        if not _advance(self._vol.volrig, self._vol):
            context.area.header_text_set(None)
            self.report({"INFO"}, "volrig: every asked-for marker is placed: press Rig")
            return {"FINISHED"}
        self._say(context)
        return {"RUNNING_MODAL"}

    def _ray(self, context, event):
        """The marker point (volume frame) under the mouse, or None."""
        from bpy_extras import view3d_utils
        xy = (event.mouse_region_x, event.mouse_region_y)
        origin = view3d_utils.region_2d_to_origin_3d(context.region, context.region_data, xy)
        direction = view3d_utils.region_2d_to_vector_3d(context.region, context.region_data, xy)
        to_volume = self._vol.matrix_world.inverted_safe()
        o = to_volume @ origin
        d = to_volume.to_3x3() @ direction
        p = volrig.ray_marker(self._mask, tuple(o), tuple(d))
        return None if p is None else tuple(float(v) for v in p)


class VOLRIG_OT_clear_markers(_OnVolume, bpy.types.Operator):
    """Remove the volume's markers (the rig then finds its body plan alone)"""
    bl_idname = "volrig.clear_markers"
    bl_label = "Clear Markers"

    name: EnumProperty(name="Marker", items=[("ALL", "All", "Every marker")] +
                       [(n, n, f"The {n} marker") for n in volrig.MARKER_NAMES], default="ALL")

    def run(self, context, vol):
        gone = [o for n, o in markers_of(vol).items() if self.name in ("ALL", n)]
        for o in gone:
            bpy.data.objects.remove(o, do_unlink=True)
        _advance(vol.volrig, vol)
        self.report({"INFO"}, f"volrig: {len(gone)} marker(s) removed")
        return {"FINISHED"}


def draw(layout, vol) -> None:
    """The Rig panel's Markers box: the name to place, Place and Clear, what is placed and what is missing."""
    box = layout.box()
    placed = markers_of(vol)
    row = box.row(align=True)
    row.label(text=f"Markers ({len(placed)})", icon="EMPTY_SINGLE_ARROW")
    if placed:
        row.operator("volrig.clear_markers", text="", icon="X")
    row = box.row(align=True)
    row.prop(vol.volrig, "marker_name", text="")
    row.operator("volrig.place_marker", text="Place", icon="RESTRICT_SELECT_OFF")
    left = missing(vol)
    if placed and left:
        box.label(text="missing: " + ", ".join(left), icon="INFO")
    elif not placed:
        box.label(text="optional: click " + ", ".join(ASKED[:5]), icon="INFO")


CLASSES = (VOLRIG_OT_place_marker, VOLRIG_OT_clear_markers)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

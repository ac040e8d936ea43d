"""Markers: the Rig and Mesh panels' Markers step (as Mixamo and AccuRIG ask for the chin, wrists, knees and
groin). The user picks a joint's name and clicks the volume or the mesh in the viewport: the marker goes half-way
through the part under the mouse (a volume: ``volrig.ray_marker`` on its mask; a mesh: between where the ray
enters and leaves its surface), where the joint lies, and the next missing name is picked. Markers are Empties
parented to their object (saved with the .blend, moved with G like any object); Rig and Rig Mesh pass them to
autorig, whose body plan they constrain (``autorig(markers=)``)."""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatVectorProperty

import numpy as np

import volrig

from . import objects, scans
from .ops_base import _reported, draw_wrapped

#: The markers the panel asks for first, in this order: with them the plan and every limb come out right.
# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

class MarkerSettings:
    """The joint the next click places."""
    marker_name: EnumProperty(name="Marker", items=[(n, n, f"Place the {n} marker") for n in volrig.MARKER_NAMES],
                              default="chin", description="The joint the next click places")


ASKED = ("chin", "wrist.L", "wrist.R", "groin", "knee.L", "knee.R")


def target(context):
    """The object markers go on: the active object's volrig volume, else the active mesh (or the mesh a Rig Mesh
    armature deforms: its ``volrig_mesh``), as the Mesh panel's ``mesh_rig._target``."""
    obj = context.active_object
    vol = objects.volume_of(obj)
    if vol is not None or obj is None:
        return vol
    if obj.type == "ARMATURE":
        return obj.get("volrig_mesh")
    return obj if obj.type == "MESH" and obj.volrig.role == "NONE" else None


def markers_of(obj) -> dict:
    """{marker name: Empty} of the object's markers (its children with role MARKER)."""
    return {o.volrig.marker: o for o in obj.children if o.volrig.role == "MARKER"}


def marker_points(obj) -> dict:
    """{marker name: (x, y, z)} in the object's own frame (a volume's: volrig's world; a mesh's: its vertices'),
    for autorig's ``markers``."""
    to_local = obj.matrix_world.inverted_safe()
    return {name: tuple(to_local @ o.matrix_world.translation) for name, o in markers_of(obj).items()}


def missing(obj) -> list:
    """The asked-for markers not placed yet, in ASKED order."""
    have = markers_of(obj)
    return [n for n in ASKED if n not in have]


def _size(obj) -> float:
    """The object's longest side in its own frame."""
    if obj.type == "VOLUME":
        return max(d * h for d, h in zip(obj.volrig.dims, obj.volrig.spacing))
    box = np.array([tuple(c) for c in obj.bound_box])
    return float((box.max(0) - box.min(0)).max())


def place(obj, name: str, point) -> bpy.types.Object:
    """Creates or moves the Empty of marker ``name`` to ``point`` (the object's frame)."""
    if name not in volrig.MARKER_NAMES:
        raise volrig.VolrigError(f"unknown marker {name!r}")
    marker = markers_of(obj).get(name)
    if marker is None:
        marker = bpy.data.objects.new(f"{obj.name}_marker_{name}", None)
        for coll in obj.users_collection or (bpy.context.scene.collection,):
            coll.objects.link(marker)
        marker.volrig.role = "MARKER"
        marker.volrig.marker = name
        marker.empty_display_type = "SPHERE"
        marker.show_in_front = True
        marker.show_name = True
        marker.parent = obj
    marker.empty_display_size = 0.03 * _size(obj)  # a sphere 3% of the object's longest side across
    marker.matrix_parent_inverse.identity()
    marker.location = tuple(float(v) for v in point)
    return marker


def mesh_ray_marker(obj, origin, direction):
    """A mesh's marker under a ray (the object's frame): half-way between where the ray first enters its surface
    and where it leaves it again; None when it misses."""
    from mathutils import Vector
    o, d = Vector(origin), Vector(direction).normalized()
    hit, enter, _, _ = obj.ray_cast(o, d)
    if not hit:
        return None
    step = 1e-4 * _size(obj)
    hit, leave, _, _ = obj.ray_cast(enter + step * d, d)
    return tuple(enter if not hit else 0.5 * (enter + leave))


def _advance(settings, volume_obj) -> bool:
    """Picks the next missing marker's name; False when none is missing."""
    left = missing(volume_obj)
    if left:
        settings.marker_name = left[0]
    return bool(left)


class _OnTarget:
    """Undoable operators on the markers' object (a volrig volume or a mesh), in object mode."""
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT" and target(context) is not None

    @_reported
    def execute(self, context):
        return self.run(context, target(context))


def _inside(region, event) -> bool:
    return 0 <= event.mouse_x - region.x < region.width and 0 <= event.mouse_y - region.y < region.height


def _view(area, event):
    """(the 3D view's main region, the mouse in its coordinates) when the mouse is over the view itself, else None
    (over the sidebar, the toolbar or a header, which overlap the view: the operator starts from the sidebar's
    button, whose region is not the view's)."""
    regions = {r.type: r for r in area.regions}
    if any(t in regions and _inside(regions[t], event) for t in ("UI", "TOOLS", "HEADER", "TOOL_HEADER")):
        return None
    view = regions.get("WINDOW")
    if view is None or not _inside(view, event):
        return None
    return view, (event.mouse_x - view.x, event.mouse_y - view.y)


class VOLRIG_OT_place_marker(_OnTarget, bpy.types.Operator):
    """Click on the volume or mesh to place the chosen marker inside the part under the mouse; the next missing
    marker is picked after each click (right-click or Esc: done)"""
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
        vol = target(context)
        if self.use_location:
            return self.run(context, vol)
        if context.area is None or context.area.type != "VIEW_3D":
            raise volrig.VolrigError("place markers in a 3D viewport")
        self._vol = vol
        self._mask = scans.mask(vol) if vol.type == "VOLUME" else None
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
        if event.type != "LEFTMOUSE" or event.value != "PRESS" or _view(context.area, event) is None:
            return {"PASS_THROUGH"}  # navigation, and clicks on the sidebar or the header
        point = self._ray(context, event)
        if point is None:
            self.report({"WARNING"}, f"volrig: the click missed {self._vol.name}")
            return {"RUNNING_MODAL"}
        place(self._vol, self._vol.volrig.marker_name, point)
        if not _advance(self._vol.volrig, self._vol):
            context.area.header_text_set(None)
            self.report({"INFO"}, "volrig: every asked-for marker is placed: press Rig")
            return {"FINISHED"}
        self._say(context)
        return {"RUNNING_MODAL"}

    def _ray(self, context, event):
        """The marker point (the object's frame) under the mouse, or None."""
        from bpy_extras import view3d_utils
        region, xy = _view(context.area, event)
        rv3d = context.area.spaces.active.region_3d
        origin = view3d_utils.region_2d_to_origin_3d(region, rv3d, xy)
        direction = view3d_utils.region_2d_to_vector_3d(region, rv3d, xy)
        to_volume = self._vol.matrix_world.inverted_safe()
        o = to_volume @ origin
        d = to_volume.to_3x3() @ direction
        if self._mask is None:
            return mesh_ray_marker(self._vol, o, d)
        p = volrig.ray_marker(self._mask, tuple(o), tuple(d))
        return None if p is None else tuple(float(v) for v in p)


class VOLRIG_OT_clear_markers(_OnTarget, bpy.types.Operator):
    """Remove the markers (the rig then finds its body plan alone)"""
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


def draw(layout, vol, context=None) -> None:
    """The Rig and Mesh panels' Markers box: the name to place, Place and Clear, what is placed and what is missing."""
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
        draw_wrapped(box, "missing: " + ", ".join(left), context, icon="INFO")
    elif not placed:
        draw_wrapped(box, "optional: chin, wrists, groin, knees", context, icon="INFO")


CLASSES = (VOLRIG_OT_place_marker, VOLRIG_OT_clear_markers)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

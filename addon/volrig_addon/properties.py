"""What the add-on stores on Blender objects (``Object.volrig``), so a saved .blend knows how its volume was
imported, segmented, skeletonized and rigged. Every setting lives on the ``<name>`` Volume object; the rig, the
sphere mesh and the skeleton preview point back to it.

Each feature module declares its own settings, beside its operators and panel: a plain class of properties
(``volume.VolumeSettings``, ``skeleton.SkeletonSettings``, ...) and the property groups of its lists
(``mocap.VolrigBonePair``, ``looks_ui.VolrigPart``, ``looks_ui.VolrigTissue``). ``VolrigObject`` joins them into the
one group ``Object.volrig`` (Blender collects the properties of such mix-in classes), so every setting keeps its
name and place (``obj.volrig.thinness``) and .blend files saved before the split read the same. Here: what every
volrig object stores (its role and its Volume), and the registration."""
import bpy
from bpy.props import EnumProperty, PointerProperty, StringProperty

from . import bake, flythrough, looks_ui, markers, medial, mocap, rig, skeleton, volume


def _volume_object(self, obj):
    return obj.type == "VOLUME" and obj.volrig.role == "VOLUME"


class VolrigObject(volume.VolumeSettings, skeleton.SkeletonSettings, medial.MedialSettings, rig.RigSettings,
                   markers.MarkerSettings, mocap.MocapSettings, looks_ui.LookSettings, flythrough.CenterlineSettings,
                   bake.BakeSettings, bpy.types.PropertyGroup):
    role: EnumProperty(name="Role", items=[
        ("NONE", "None", "Not a volrig object"),
        ("VOLUME", "Volume", "The imported (and baked) volume; holds every setting"),
        ("RIG", "Rig", "The armature"),
        ("SPHERES", "Spheres", "One vertex per skeleton sphere, bound to the armature"),
        ("SKELETON", "Skeleton preview", "The skeleton points at the current thinness"),
        ("MASK", "Mask preview", "The segmentation mask"),
        ("THICKNESS", "Thickness", "The segmented object coloured by its local thickness"),
        ("MEDIAL", "Medial surface",
         "The medial surface of the object's plates coloured by thickness, its rods as edges"),
        ("PORES", "Pore network", "The pore space's network: spheres (pores) and cylinders (throats) by size"),
        ("PATH", "Centerline", "The fly-through's Bezier curve along the centerline"),
        ("CAMERA", "Fly-through camera", "The camera flying along the centerline"),
        ("LIGHT", "Headlight", "The point light riding with the fly-through camera"),
        ("LUMEN", "Lumen wall", "The wall around the segmented lumen, seen from inside"),
        ("MARKER", "Marker", "A joint the user placed for the rig (its name in marker)"),
    ], default="NONE")
    marker: StringProperty(name="Marker", description="The joint this marker names (volrig.MARKER_NAMES)")
    volume: PointerProperty(name="Volume", type=bpy.types.Object, poll=_volume_object,
                            description="The volrig Volume object this object belongs to")


#: The property groups Object.volrig holds lists of, registered before it.
ITEM_GROUPS = (mocap.VolrigBonePair, looks_ui.VolrigPart, looks_ui.VolrigTissue)


def register():
    for cls in ITEM_GROUPS:
        bpy.utils.register_class(cls)
    bpy.utils.register_class(VolrigObject)
    bpy.types.Object.volrig = PointerProperty(type=VolrigObject)


def unregister():
    del bpy.types.Object.volrig
    bpy.utils.unregister_class(VolrigObject)
    for cls in reversed(ITEM_GROUPS):
        bpy.utils.unregister_class(cls)

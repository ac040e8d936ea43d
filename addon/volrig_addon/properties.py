"""What the add-on stores on Blender objects (``Object.volrig``), so a saved .blend knows how its volume was
imported, segmented, skeletonized and rigged. Every setting lives on the ``<name>`` Volume object; the rig, the
sphere mesh and the skeleton preview point back to it."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, IntVectorProperty, PointerProperty, StringProperty)

import volrig
from volrig.deform import MODE_INFO, SAMPLING_INFO
from volrig.pipeline import DEFAULT_THINNESS_VOXELS

from . import compat, looks, materials, objects, scans, tissue_looks

UNIT_SCALES = [
    ("MM", "mm to m", "Volume units are millimetres (medical scans); 1 mm = 0.001 Blender units", 0),
    ("CM", "cm to m", "Volume units are centimetres; 1 cm = 0.01 Blender units", 1),
    ("M", "m", "Volume units are metres; no scaling", 2),
    ("CUSTOM", "Custom", "Blender units per volume unit", 3),
]
UNIT_FACTOR = {"MM": 0.001, "CM": 0.01, "M": 1.0}


#: The transfer-function presets (materials.PRESETS and the lumen view); stored by position: append only.
PRESET_ITEMS = [
    ("CT_BONE", "CT bone", "Dense values opaque and bone-white, soft values transparent"),
    ("SOFT_TISSUE", "Soft tissue", "Low values reddish and translucent, dense values white"),
    ("LABELS", "Label map", "One colour per integer label"),
    ("GREY", "Grey", "Density proportional to the value"),
    ("LUMEN", "Lumen view", "The segmented range clear, every other value an opaque pink wall: for cameras "
                            "inside a hollow organ (Fly Through sets it)"),
]


def _menu(info):
    """EnumProperty items from volrig's {name: (label, description)} (volrig.deform.MODE_INFO, SAMPLING_INFO)."""
    return [(name, label, description) for name, (label, description) in info.items()]


def _segmentation_changed(self, context):
    scans.update_mask_count(self.id_data)


def _thinness_changed(self, context):
    objects.update_skeleton_preview(self.id_data)


def _look_changed(self, context):
    materials.update_volume_material(self.id_data)


def _parts_toggled(self, context):
    looks.parts_toggled(self.id_data)


def _substitute_changed(self, context):
    looks.substitute_changed(self.id_data)


def _tissues_toggled(self, context):
    tissue_looks.toggled(self.id_data)


def _volume_object(self, obj):
    return obj.type == "VOLUME" and obj.volrig.role == "VOLUME"


BLEND_RELATIVE = compat.BLEND_RELATIVE


class VolrigBonePair(bpy.types.PropertyGroup):
    """One line of the motion capture bone map: a BVH joint and the rig bone it drives."""
    joint: StringProperty(name="BVH joint", description="A joint of the BVH clip")
    bone: StringProperty(name="Rig bone", description="The rig bone this joint drives (empty: not mapped)")


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
    key: StringProperty(name="Key", description="The class's grid: tissue_<key>")
    codes: StringProperty(name="Codes", description="The label map's codes in this class, comma-separated")
    visible: BoolProperty(name="Visible", default=True, update=_look_changed,
                          description="Show the class's voxels (hidden: rendered as if they were empty)")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, default=(0.8, 0.8, 0.8), min=0.0, max=1.0,
                               update=_look_changed)
    opacity: FloatProperty(name="Opacity", default=1.0, min=0.0, soft_max=1.0, max=100.0, precision=3,
                           update=_look_changed,
                           description="The class's opacity (times the Density multiplier)")


class VolrigObject(bpy.types.PropertyGroup):
    role: EnumProperty(name="Role", items=[
        ("NONE", "None", "Not a volrig object"),
        ("VOLUME", "Volume", "The imported (and baked) volume; holds every setting"),
        ("RIG", "Rig", "The armature"),
        ("SPHERES", "Spheres", "One vertex per skeleton sphere, bound to the armature"),
        ("SKELETON", "Skeleton preview", "The skeleton points at the current thinness"),
        ("MASK", "Mask preview", "The segmentation mask"),
        ("THICKNESS", "Thickness", "The segmented object coloured by its local thickness"),
        ("MEDIAL", "Medial surface", "The medial surface of the object's plates coloured by thickness, its rods as edges"),
        ("PATH", "Centerline", "The fly-through's Bezier curve along the centerline"),
        ("CAMERA", "Fly-through camera", "The camera flying along the centerline"),
        ("LIGHT", "Headlight", "The point light riding with the fly-through camera"),
        ("LUMEN", "Lumen wall", "The wall around the segmented lumen, seen from inside"),
        ("MARKER", "Marker", "A joint the user placed for the rig (its name in marker)"),
    ], default="NONE")
    marker: StringProperty(name="Marker", description="The joint this marker names (volrig.MARKER_NAMES)")
    volume: PointerProperty(name="Volume", type=bpy.types.Object, poll=_volume_object,
                            description="The volrig Volume object this object belongs to")

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

    # --- skeleton ---
    metric: EnumProperty(name="Metric", items=[
        ("euclidean", "Euclidean", "Exact Euclidean distance, anisotropic spacing honoured (thinness 0 .. 1.416)"),
        ("chamfer345", "Chamfer <3,4,5>", "The thesis' chamfer distance (thinness 0 .. 4.077, grid units)"),
    ], default="euclidean")
    plane_t: FloatProperty(name="Plate t", default=5.0, min=1.0, soft_max=30.0, precision=1,
                           description="Plane-like threshold of Medial Surface, in voxels: plates whose sides lie "
                                       "more than t apart around their rim get a medial surface (larger: only the "
                                       "larger plates; at least 5 against noise)")
    thinness: FloatProperty(name="Thinness", default=DEFAULT_THINNESS_VOXELS, min=0.0, max=4.1, soft_max=1.42,
                            precision=3, step=1, update=_thinness_changed,
                            description="Keep voxels whose thinness score exceeds this, in voxels (Euclidean: "
                                        "0 .. 1.416; chamfer <3,4,5>: 0 .. 4.077); larger = fewer spheres")
    point_count: IntProperty(name="Points", default=-1)
    show_spheres: BoolProperty(name="Spheres", default=True, update=_thinness_changed,
                               description="Show the skeleton's spheres scaled by radius (else points only)")

    # --- rig ---
    alpha: FloatProperty(name="Alpha", default=0.9, min=0.0, max=1.0,
                         description="Skeleton-tree: 1 weighs edges by length only, lower prefers equal radii")
    bones: IntProperty(name="Bones", default=24, min=1, max=200, description="Bone count target")
    roles: BoolProperty(name="Body roles", default=True,
                        description="Name bones as a humanoid, quadruped or hand when the shape looks like one")
    body_plan: EnumProperty(name="Body plan", items=[
        ("AUTO", "Best fit", "Fit every template (humanoid, quadruped, hand, chains) and keep the best"),
        ("humanoid", "Humanoid", "Force the humanoid template (head, two arms, two legs: 21 Rigify bones)"),
        ("quadruped", "Quadruped", "Force the quadruped template (four legs, spine, head; tail and neck as found)"),
        ("chains", "Chains", "Neutral chains along the skeleton's branches (no body roles)"),
        ("hand", "Hand", "Force the hand template (palm, thumb and four fingers of three bones each)"),
    ], default="AUTO", description="The template the rig is fitted to; pick another and press Rig to refit")
    use_scene_up: BoolProperty(name="Scene up", default=True,
                               description="Tell the rig where up is: the scene's +Z seen from the volume (else inferred)")
    rig_kept_points: BoolProperty(name="Kept points", default=False,
                                  description="Rig the kept skeleton points themselves, not autorig's own skeleton "
                                              "of the object (for bones without flesh; the rig then follows the "
                                              "thinness)")
    rig_found: StringProperty(name="Found", description="What the last rig found: kind, fit and runner-up")
    marker_name: EnumProperty(name="Marker", items=[(n, n, f"Place the {n} marker") for n in volrig.MARKER_NAMES],
                              default="chin", description="The joint the next click places")
    rigid_voxels: IntProperty(name="Rigid voxels", default=0, min=0,
                              description="Voxels of rigid tissue the last Rig or Rebind bound: they move whole, as "
                                          "the rigid layer, while the flesh bends (0: none)")
    bind_mode: EnumProperty(name="Binding", items=[
        ("smooth", "Smooth", "Points near a joint share their weight between its two bones"),
        ("rigid", "Rigid", "Every point follows one bone"),
    ], default="smooth")
    rigid_by: EnumProperty(name="Rigid tissue", default="AUTO", items=[
        ("AUTO", "Automatic", "The tissue table's bone codes (Look > Tissues) when the volume has a table, else none"),
        ("NONE", "None", "Every tissue bends at the joints"),
        ("LABELS", "Labels", "The voxels with these label values do not bend (a label map's bone codes)"),
        ("RANGE", "Value range", "The voxels with values in this range do not bend (a CT's bone, e.g. 300-3000 HU)"),
    ], description="Tissue that must not bend: each connected piece is bound wholly to one bone, its spheres with "
                   "weight 1; only the rest blends across joints (Rig and Rebind)")
    rigid_labels: StringProperty(name="Rigid labels", default="",
                                 description="Label values of the rigid tissue, e.g. 84, 92 or 80-90")
    rigid_low: FloatProperty(name="From", default=300.0, description="Lowest value of the rigid tissue")
    rigid_high: FloatProperty(name="To", default=3000.0, description="Highest value of the rigid tissue")
    rig_file: StringProperty(name="Rig file", description="The .vrig file (points, tree, rig, binding) in the cache")

    # --- motion capture ---
    bvh_file: StringProperty(name="BVH", subtype="FILE_PATH", options=BLEND_RELATIVE,
                             description="The clip that last drove the rig")
    bone_map: CollectionProperty(type=VolrigBonePair, name="Bone map",
                                 description="BVH joint -> rig bone; Drive with BVH uses it for the same clip")
    bone_map_index: IntProperty(name="Bone map line", default=0)

    # --- look ---
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

    # --- centerline: fly-through and straightening ---
    fly_ends: EnumProperty(name="Ends", items=[
        ("AUTO", "Automatic", "From the end of the thickest terminal branch (a trachea, a tube's wide end) to the "
                              "end farthest from it along the object"),
        ("POINTS", "Points", "From Start to End (volume units, e.g. mm in the scan's frame)"),
    ], default="AUTO")
    fly_start: FloatVectorProperty(name="Start", size=3, precision=2,
                                   description="Where the centerline starts (volume units, on the object)")
    fly_end: FloatVectorProperty(name="End", size=3, precision=2,
                                 description="Where the centerline ends (volume units, on the object)")
    frames_per_mm: FloatProperty(name="Frames per mm", default=1.0, min=0.01, soft_max=20.0,
                                 description="Frames per volume unit of the centerline: the camera's speed")
    look_ahead: FloatProperty(name="Look ahead", default=10.0, min=0.0, soft_max=100.0,
                              description="The camera looks along the centerline's tangent averaged over this "
                                          "length ahead of it (volume units)")
    fly_fov: FloatProperty(name="Field of view", default=100.0, min=10.0, max=170.0,
                           description="The camera's field of view, degrees (endoscopes: 90 to 140)")
    fly_light: FloatProperty(name="Headlight", default=1.0, min=0.0, soft_max=10.0,
                             description="The headlight's power, relative (it follows the lumen's radius)")
    fly_frame_start: IntProperty(name="First frame", default=1,
                                 description="Scene frame where the fly-through and the straightening start")
    straighten_radius: FloatProperty(name="Radius", default=0.0, min=0.0,
                                     description="Straighten: half the width of the straightened volume (volume "
                                                 "units); 0 = 1.5 times the widest radius plus two voxels")
    straighten_bones: IntProperty(name="Bones", default=12, min=1, max=200,
                                  description="Straightening rig: bones along the centerline (equal arc pieces)")
    straighten_frames: IntProperty(name="Frames", default=48, min=2, max=100000,
                                   description="Straightening rig: frames from curved to straight")

    # --- bake ---
    deform_mode: EnumProperty(name="Deform", items=_menu(MODE_INFO), default="linear")
    keep_volume: BoolProperty(name="Keep Volume at Bends", default=True,
                              description="Smooth modes: bent limbs keep their volume and meet at the bend's "
                                          "bisector plane (off: the plain blend)")
    sampling: EnumProperty(name="Sampling", items=_menu(SAMPLING_INFO), default="trilinear")
    lattice_tables: BoolProperty(name="Lattice Tables", default=False,
                                 description="Bake with the bones' lattice tables (built at the first frame of a "
                                             "bake of 16 frames or more): frames about 5% (smooth) to 20% (rigid) "
                                             "faster for 1-3 bytes per source voxel more memory")
    bake_frames: StringProperty(name="Frames", default="",
                                description="Frames to bake, e.g. '1-48' or '1-10,20'; empty = the scene range")
    baked_start: IntProperty(name="Baked from", default=0)
    baked_end: IntProperty(name="Baked to", default=-1)


def register():
    bpy.utils.register_class(VolrigBonePair)
    bpy.utils.register_class(VolrigPart)
    bpy.utils.register_class(VolrigTissue)
    bpy.utils.register_class(VolrigObject)
    bpy.types.Object.volrig = PointerProperty(type=VolrigObject)


def unregister():
    del bpy.types.Object.volrig
    bpy.utils.unregister_class(VolrigObject)
    bpy.utils.unregister_class(VolrigTissue)
    bpy.utils.unregister_class(VolrigPart)
    bpy.utils.unregister_class(VolrigBonePair)

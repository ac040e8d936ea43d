"""Rig Mesh: a mesh object rigged and skinned through its volume (``volrig.rig_mesh`` does the work), deformed by
Blender's own Armature modifier; thickness editing as shape keys driven by a keyframable pose-bone property.

What Rig Mesh makes, for a mesh object ``<name>``:

- ``<name>_rig``   an armature (bones named as autorig names them, in the mesh's own frame, placed at the mesh's
                   world matrix); the mesh is parented to it keeping its world position. Its custom property
                   ``volrig_mesh`` points at the mesh.
- on the mesh:     one vertex group per bone holding ``MeshRig.weights`` (at most four per vertex, summing to 1) and
                   an Armature modifier ``volrig`` at the top of the stack (Preserve Volume: dual quaternions).
- thickness keys:  per bone a shape key ``thickness.<bone>`` holding the vertices moved as for thickness factor 2
                   (``volrig.skin.thickness_offsets``, linear in the factor), its value driven by the pose bone's
                   custom property ``volrig_thickness`` (1 = unchanged, 0 .. 4) minus 1. Pose-bone properties can be
                   keyframed, so thickness animates; shape keys act before the Armature modifier, so a thicker
                   limb still follows its bone.

The surface voxelized is the mesh as evaluated (its modifiers applied, the ``volrig`` Armature modifier off), in the
object's local frame; the weights are computed for the original vertices (``mesh.vertices``), the ones the Armature
modifier deforms when it comes first in the stack. A modifier that changes the topology (Subdivision, Mirror,
Solidify) and stays below it works on the deformed mesh; moved above it, the Armature modifier gets that modifier's
vertices and Blender carries the vertex groups through it (interpolated by Subdivision, copied by Mirror, whose
vertex group mirroring renames .L to .R).
"""
import time

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

import volrig
from volrig import pipeline
from volrig.skin import MESH_VOXELS, SKIN_BLEND, thickness_offsets

from . import drawing, objects
from . import markers as marker_ui
from .ops_base import _draw_found, _found_level, _reported, draw_wrapped

MODIFIER = "volrig"
THICKNESS = objects.THICKNESS
KEY_PREFIX = "thickness."
#: Rig Mesh makes thickness keys by default below this many vertices
THICKNESS_KEYS_BELOW = 200_000


def armature_of(mesh_obj):
    """The armature of a mesh rigged by Rig Mesh (its ``volrig`` Armature modifier's object), or None."""
    mod = mesh_obj.modifiers.get(MODIFIER) if mesh_obj is not None and mesh_obj.type == "MESH" else None
    return mod.object if mod is not None and mod.type == "ARMATURE" else None


def rigged_mesh(obj):
    """The mesh Rig Mesh rigged, given it or its armature; None otherwise."""
    if obj is None:
        return None
    if obj.type == "ARMATURE":
        mesh = obj.get("volrig_mesh")
        return mesh if isinstance(mesh, bpy.types.Object) and armature_of(mesh) == obj else None
    return obj if armature_of(obj) is not None else None


def new_mesh_object(context, name, vertices, faces, smooth=False):
    """A new mesh object ``name`` in the scene's collection from (V, 3) vertices and faces (vertex index lists, e.g.
    ``volrig.read_mesh``'s triangles), selected and active: for scripts and tests."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, p)) for p in vertices], [], [tuple(map(int, t)) for t in faces])
    me.polygons.foreach_set("use_smooth", [bool(smooth)] * len(me.polygons))
    me.update()
    obj = bpy.data.objects.new(name, me)
    context.scene.collection.objects.link(obj)
    for o in context.view_layer.objects:
        if o is not None:  # (None: an object removed since the view layer was last updated)
            o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


def _mesh_arrays(mesh):
    """(vertices (V, 3) float64, triangles (T, 3) int64) of a Blender mesh, loop triangles computed."""
    mesh.calc_loop_triangles()
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    tris = np.empty(3 * len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return co.reshape(-1, 3).astype(np.float64), tris.reshape(-1, 3).astype(np.int64)


def evaluated_triangles(context, obj):
    """The mesh object's surface as evaluated (modifiers and shape keys applied, the ``volrig`` Armature modifier
    and the thickness keys of an earlier Rig Mesh left out) in its local frame: (vertices, triangles)."""
    mod = obj.modifiers.get(MODIFIER)
    shown = mod.show_viewport if mod is not None else None
    if mod is not None:
        mod.show_viewport = False
    key = obj.data.shape_keys
    muted = [(kb, kb.mute) for kb in key.key_blocks if kb.name.startswith(KEY_PREFIX)] if key is not None else []
    for kb, _ in muted:
        kb.mute = True
    try:
        depsgraph = context.evaluated_depsgraph_get()
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        try:
            return _mesh_arrays(mesh)
        finally:
            evaluated.to_mesh_clear()
    finally:
        if mod is not None:
            mod.show_viewport = shown
        for kb, was in muted:
            kb.mute = was


def vertex_positions(obj) -> np.ndarray:
    """(V, 3) the original mesh's vertices (``mesh.vertices``, local frame): what the Armature modifier deforms."""
    co = np.empty(3 * len(obj.data.vertices), dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def set_weights(obj, names, weights) -> None:
    """One vertex group per bone (``names``) holding column b of the (V, B) CSR ``weights``; groups of those names
    are replaced. Vertices of equal weight go in one ``VertexGroup.add`` call."""
    w = weights.tocsc()
    for b, name in enumerate(names):
        old = obj.vertex_groups.get(name)
        if old is not None:
            obj.vertex_groups.remove(old)
        vg = obj.vertex_groups.new(name=name)
        rows = w.indices[w.indptr[b]:w.indptr[b + 1]]
        values = w.data[w.indptr[b]:w.indptr[b + 1]]
        keep = values > 0
        rows, values = rows[keep], values[keep]
        if not len(rows):
            continue
        order = np.argsort(values, kind="stable")
        rows, values = rows[order], values[order]
        cuts = np.flatnonzero(np.diff(values)) + 1
        for part_rows, value in zip(np.split(rows, cuts), values[np.concatenate([[0], cuts])]):
            vg.add(part_rows.tolist(), float(value), "REPLACE")


def read_weights(obj, names):
    """The weights the vertex groups ``names`` hold now, as a (V, B) CSR matrix, rows normalized (as the Armature
    modifier does); vertices in none of them get an empty row (a scipy CSR matrix; without scipy, volrig's own CSR
    of the same arrays)."""
    from volrig import _optional
    column = {obj.vertex_groups[n].index: b for b, n in enumerate(names) if n in obj.vertex_groups}
    rows, cols, vals = [], [], []
    for v in obj.data.vertices:
        for g in v.groups:
            b = column.get(g.group)
            if b is not None and g.weight > 0:
                rows.append(v.index)
                cols.append(b)
                vals.append(g.weight)
    shape = (len(obj.data.vertices), len(names))
    data, indices, indptr = _optional.coo_arrays(np.array(vals, dtype=np.float64), rows, cols, shape)
    row = np.repeat(np.arange(shape[0]), np.diff(indptr))
    sums = np.bincount(row, weights=data, minlength=shape[0])
    scale = np.where(sums > 0, 1.0 / np.where(sums > 0, sums, 1.0), 0.0)
    return _optional.csr_matrix(data * scale[row], indices, indptr, shape)


def _move_first(obj, mod) -> None:
    index = list(obj.modifiers).index(mod)
    if index == 0:
        return
    if hasattr(obj.modifiers, "move"):  # Blender 4.x
        obj.modifiers.move(index, 0)
        return
    with bpy.context.temp_override(object=obj, active_object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=0)


def remove_thickness_keys(obj) -> None:
    """Removes the mesh's ``thickness.<bone>`` shape keys (and their drivers)."""
    key = obj.data.shape_keys
    if key is None:
        return
    for kb in [k for k in key.key_blocks if k.name.startswith(KEY_PREFIX)]:
        kb.driver_remove("value")
        obj.shape_key_remove(kb)


def unrig(obj) -> None:
    """Undoes Rig Mesh on ``obj``: its thickness keys, its bones' vertex groups, the Armature modifier and the
    armature go; the mesh keeps its world position."""
    arm = armature_of(obj)
    remove_thickness_keys(obj)
    if arm is not None:
        for bone in arm.data.bones:
            vg = obj.vertex_groups.get(bone.name)
            if vg is not None:
                obj.vertex_groups.remove(vg)
    mod = obj.modifiers.get(MODIFIER)
    if mod is not None:
        obj.modifiers.remove(mod)
    if arm is not None and obj.parent == arm:
        world = obj.matrix_world.copy()
        obj.parent = None
        obj.matrix_world = world
    if arm is not None and arm.get("volrig_mesh") == obj:
        objects._remove(arm)


def add_thickness_keys(obj, arm, rig: volrig.Rig, weights, progress=None) -> int:
    """Per bone with weights a shape key ``thickness.<bone>`` (the vertices thickened by factor 2), its value driven
    by the pose bone's ``volrig_thickness`` - 1; replaces earlier thickness keys. Returns the number of keys."""
    remove_thickness_keys(obj)
    co = vertex_positions(obj)
    if obj.data.shape_keys is None:
        obj.shape_key_add(name="Basis", from_mix=False)
    else:
        co = np.empty(3 * len(co), dtype=np.float32)
        obj.data.shape_keys.reference_key.data.foreach_get("co", co)
        co = co.reshape(-1, 3).astype(np.float64)
    w = weights.tocsc()
    made = 0
    for b, name in enumerate(rig.names):
        if progress is not None:
            progress(b / len(rig.names))
        pb = arm.pose.bones.get(name)
        if pb is None or w.indptr[b + 1] == w.indptr[b]:
            continue
        objects.thickness_property(pb)
        kb = obj.shape_key_add(name=KEY_PREFIX + name, from_mix=False)
        kb.slider_min, kb.slider_max = -1.0, 3.0
        moved = co + thickness_offsets(rig, weights, co, {b: 2.0})
        kb.data.foreach_set("co", moved.astype(np.float32).ravel())
        driver = kb.driver_add("value").driver
        driver.type = "SCRIPTED"
        var = driver.variables.new()
        var.name, var.type = "thickness", "SINGLE_PROP"
        var.targets[0].id_type = "OBJECT"
        var.targets[0].id = arm
        var.targets[0].data_path = f'pose.bones["{bpy.utils.escape_identifier(name)}"]["{THICKNESS}"]'
        driver.expression = "thickness - 1"  # a simple expression: Blender evaluates it without Python
        made += 1
    revalidate_drivers(obj)
    return made


def revalidate_drivers(obj) -> None:
    """Clears the invalid flag of the thickness drivers and evaluates them again. A driver evaluated while the
    depsgraph's copy of the armature lacks the pose bones' ``volrig_thickness`` (set from Python, which does not tag
    the armature) is flagged invalid and stays 0 (thickness -1) until edited: the armature is tagged and evaluated,
    then the flags cleared."""
    key = obj.data.shape_keys
    if key is None or key.animation_data is None:
        return
    arm = armature_of(obj)
    if arm is not None:
        arm.update_tag()
    bpy.context.view_layer.update()
    for fc in key.animation_data.drivers:
        if fc.data_path.startswith(f'key_blocks["{KEY_PREFIX}'):
            fc.driver.is_valid = True
    key.update_tag()
    bpy.context.view_layer.update()


def rig_mesh_object(context, obj, *, kind=None, up=None, voxels=MESH_VOXELS, blend=SKIN_BLEND,
                    preserve_volume=False, thickness_keys=True, progress=None, markers=None):
    """Rigs the mesh object ``obj`` (see the module's docstring); replaces an earlier Rig Mesh of it once the new
    rig is computed. Returns (armature object, volrig.MeshRig, seconds spent writing the vertex groups)."""
    if obj.type != "MESH":
        raise volrig.VolrigError(f"{obj.name} is not a mesh")
    if context.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    verts, tris = evaluated_triangles(context, obj)
    if not len(tris):
        raise volrig.VolrigError(f"{obj.name} has no faces: Rig Mesh needs a surface that encloses a volume")
    own = vertex_positions(obj)
    if not len(own):
        raise volrig.VolrigError(f"{obj.name} has no vertices of its own (its surface comes from modifiers): "
                                 "nothing for the Armature modifier to deform")
    same = own.shape == verts.shape and np.array_equal(own, verts)
    scaled = (lambda f: progress(0.9 * f)) if progress is not None else None
    try:
        mr = volrig.rig_mesh(verts, tris, voxels=voxels, blend=blend, kind=kind, up=up, progress=scaled,
                             skin_points=None if same else own, markers=markers)
    except volrig.Cancelled:
        raise
    except volrig.VolrigError as e:  # e.g. "voxelize: the mesh encloses no voxel centre ... (an open surface ...)"
        raise volrig.VolrigError(f"{obj.name}: {e}") from e
    unrig(obj)  # only now: a failed Rig Mesh (not an undo step) leaves an earlier rig as it was
    arm = bpy.data.objects.new(obj.name + "_rig", bpy.data.armatures.new(obj.name + "_rig"))
    for coll in obj.users_collection or (context.scene.collection,):
        coll.objects.link(arm)
    objects.fill_armature(arm, mr.rig, obj.matrix_world.copy())
    arm["volrig_mesh"] = obj
    world = obj.matrix_world.copy()
    obj.parent = arm
    obj.matrix_parent_inverse.identity()
    obj.matrix_world = world
    t0 = time.perf_counter()
    set_weights(obj, mr.rig.names, mr.weights)
    seconds = time.perf_counter() - t0
    mod = obj.modifiers.new(MODIFIER, "ARMATURE")
    mod.object = arm
    mod.use_vertex_groups, mod.use_bone_envelopes = True, False
    mod.use_deform_preserve_volume = bool(preserve_volume)
    _move_first(obj, mod)
    if thickness_keys:
        add_thickness_keys(obj, arm, mr.rig, mr.weights,
                           progress=(lambda f: progress(0.9 + 0.1 * f)) if progress is not None else None)
    obj["volrig_rig_found"] = pipeline.describe_rig(mr.rig)
    return arm, mr, seconds


def _target(context):
    obj = context.active_object
    if obj is None:
        return None
    if obj.type == "ARMATURE":
        return rigged_mesh(obj)
    return obj if obj.type == "MESH" and obj.volrig.role == "NONE" else None


class VOLRIG_OT_rig_mesh(bpy.types.Operator):
    """Rig and skin the active mesh through its volume: an armature fitted to it, one vertex group per bone and an
    Armature modifier, so posing the armature deforms the mesh (replaces an earlier Rig Mesh)"""
    bl_idname = "volrig.rig_mesh"
    bl_label = "Rig Mesh"
    bl_options = {"REGISTER", "UNDO"}

    body_plan: drawing.body_plan_property()
    use_scene_up: BoolProperty(name="Scene up", default=True,
                               description="Tell the rig where up is: the scene's +Z seen from the mesh (else "
                                           "inferred)")
    voxels: IntProperty(name="Voxels", default=MESH_VOXELS, min=16, max=1000,
                        description="Voxels along the mesh's longest side (finer: slower, thinner parts kept)")
    blend: FloatProperty(name="Blend", default=SKIN_BLEND, min=0.05, max=5.0,
                         description="Weight falloff across joints, in limb radii (larger: smoother, smaller: stiffer)")
    preserve_volume: BoolProperty(name="Preserve volume", default=False,
                                  description="Dual quaternion skinning: bent joints keep their volume")
    thickness_keys: EnumProperty(name="Thickness keys", items=[
        ("AUTO", "Auto", f"Thickness shape keys for meshes under {THICKNESS_KEYS_BELOW:,} vertices"),
        ("ON", "On", "A thickness shape key per bone, driven by the pose bone's volrig_thickness"),
        ("OFF", "Off", "No thickness keys (Thickness Keys adds them later)"),
    ], default="AUTO")

    @classmethod
    def poll(cls, context):
        return _target(context) is not None

    @_reported
    def execute(self, context):
        obj = _target(context)
        keys = self.thickness_keys == "ON" or (self.thickness_keys == "AUTO"
                                               and len(obj.data.vertices) < THICKNESS_KEYS_BELOW)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            arm, mr, _ = rig_mesh_object(
                context, obj, kind=None if self.body_plan == "AUTO" else self.body_plan,
                up=objects.scene_up(obj) if self.use_scene_up else None, voxels=self.voxels, blend=self.blend,
                preserve_volume=self.preserve_volume, thickness_keys=keys,
                progress=lambda f: wm.progress_update(100 * f), markers=marker_ui.marker_points(obj) or None)
        finally:
            wm.progress_end()
        for o in context.view_layer.objects:
            o.select_set(False)
        arm.select_set(True)
        context.view_layer.objects.active = arm
        self.report(_found_level(mr.rig.note), f"volrig: {obj['volrig_rig_found']}: {len(mr.rig)} bones, "
                              f"{len(obj.data.vertices):,} vertices skinned")
        return {"FINISHED"}


class VOLRIG_OT_thickness_keys(bpy.types.Operator):
    """Make (or remake) the thickness shape keys of the mesh rigged by Rig Mesh from its armature and its vertex
    groups as they are now: per bone a key driven by the pose bone's volrig_thickness"""
    bl_idname = "volrig.thickness_keys"
    bl_label = "Thickness Keys"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return rigged_mesh(context.active_object) is not None

    @_reported
    def execute(self, context):
        obj = rigged_mesh(context.active_object)
        arm = armature_of(obj)
        mode = context.mode
        if mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")
        rig = objects.armature_rig(arm)
        made = add_thickness_keys(obj, arm, rig, read_weights(obj, rig.names))
        if mode == "POSE":
            bpy.ops.object.mode_set(mode="POSE")
        self.report({"INFO"}, f"volrig: {made} thickness keys on {obj.name}")
        return {"FINISHED"}


class VOLRIG_PT_mesh(bpy.types.Panel):
    """Rig Mesh for the active mesh; its rig and the active bone's thickness once rigged."""
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "volrig"
    bl_label = "Mesh"

    @classmethod
    def poll(cls, context):
        return _target(context) is not None

    def draw(self, context):
        layout = self.layout
        obj = _target(context)
        marker_ui.draw(layout, obj, context)
        layout.operator(VOLRIG_OT_rig_mesh.bl_idname, icon="ARMATURE_DATA")
        arm = armature_of(obj)
        if arm is None:
            layout.label(text=f"{obj.name}: {len(obj.data.vertices):,} vertices", icon="MESH_DATA")
            return
        col = layout.column(align=True)
        col.label(text=f"{arm.name}: {len(arm.data.bones)} bones", icon="BONE_DATA")
        found = obj.get("volrig_rig_found", "")
        if found:
            _draw_found(col, found, context)
        mod = obj.modifiers[MODIFIER]
        layout.prop(mod, "use_deform_preserve_volume")
        layout.operator(VOLRIG_OT_thickness_keys.bl_idname, icon="SHAPEKEY_DATA")
        bone = arm.data.bones.active
        pb = arm.pose.bones.get(bone.name) if bone is not None else None
        if pb is not None and THICKNESS in pb:
            layout.prop(pb, f'["{THICKNESS}"]', text=f"{pb.name} thickness", slider=True)
        else:
            draw_wrapped(layout, "Select a bone: its thickness shows here", context, icon="BLANK1")


CLASSES = (VOLRIG_OT_rig_mesh, VOLRIG_OT_thickness_keys, VOLRIG_PT_mesh)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

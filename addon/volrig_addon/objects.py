"""The Blender objects of one rigged volume (docs/DESIGN.md, Blender object model), all in the collection ``<name>``:

- ``<name>``          Volume object showing source.vdb, later the baked VDB sequence; holds every setting.
- ``<name>_mask``     preview Volume object (child of ``<name>``) showing the segmentation mask.
- ``<name>_thickness`` Volume object (child of ``<name>``): the mask coloured by its local thickness.
- ``<name>_medial``   Mesh (child of ``<name>``): the medial surface of the plates, a ``thickness`` point attribute
                      coloured through a ramp, the rods as loose edges (``rod`` edge attribute) with a ``radius``
                      point attribute, made tubes by the ``volrig rods`` geometry nodes.
- ``<name>_pores``    Mesh (child of ``<name>``): the segmented pore space's network (volrig.pore_network), a sphere
                      a pore (its inscribed diameter) and a cylinder a throat, coloured by a ``thickness`` point
                      attribute (the diameter) through the thickness ramp.
- ``<name>_skeleton`` preview mesh: one vertex per skeleton point at the current thinness, spheres instanced.
- ``<name>_rig``      Armature built from the rig's joints in volume units (roll 0), scaled into the scene.
- ``<name>_spheres``  Mesh parented to the rig: one vertex per rig point with a ``radius`` attribute, the
                      skeleton-tree as edges, one vertex group per bone, an Armature modifier.
Volume units (e.g. mm) are kept inside the objects; each object's matrix scales them into Blender units.
"""
import os

import bpy
import numpy as np
from mathutils import Matrix

import volrig

from . import compat, materials, scans
from .state import THICKNESS, armature_rig, members, vertex_groups, volume_of  # noqa: F401  (objects.* as before)

SPHERE_NODES = "volrig spheres"
ROD_NODES = "volrig rods"


def _collection_of(volume_obj):
    return volume_obj.users_collection[0] if volume_obj.users_collection else bpy.context.scene.collection


def _new_object(volume_obj, name, data, role):
    obj = bpy.data.objects.new(name, data)
    _collection_of(volume_obj).objects.link(obj)
    obj.volrig.role = role
    obj.volrig.volume = volume_obj
    return obj


def _remove(obj) -> None:
    data = obj.data
    bpy.data.objects.remove(obj, do_unlink=True)
    if data is not None and data.users == 0:
        for kind, coll in ((bpy.types.Mesh, bpy.data.meshes), (bpy.types.Armature, bpy.data.armatures),
                           (bpy.types.Volume, bpy.data.volumes)):
            if isinstance(data, kind):
                coll.remove(data)
                return  # data is gone: asking it anything more raises


def placement(unit_scale: float, grid_to_world=None) -> Matrix:
    """The Volume object's matrix: the grid frame (origin + spacing * index, where volrig computes) turned into the
    patient frame (``volrig.Volume.grid_to_world()``, LPS), scaled into Blender units. Blender's axes are taken as
    LPS: +x the patient's left, +y posterior, +z superior, so a patient faces -Y like a Blender character (the
    front view shows the face)."""
    g = Matrix.Identity(4) if grid_to_world is None else Matrix([list(map(float, r)) for r in np.asarray(grid_to_world)])
    return Matrix.Scale(unit_scale, 4) @ g


def create_volume_object(context, name: str, vdb_path: str, unit_scale: float, grid_to_world=None):
    """A Volume object in a new collection ``name`` showing ``vdb_path`` (a grid-frame VDB), placed by
    ``placement``; the armature, the sphere mesh and the previews take its matrix, so all that volrig computes in
    the grid frame lands on the volume."""
    coll = bpy.data.collections.new(name)
    context.scene.collection.children.link(coll)
    data = bpy.data.volumes.new(name)
    data.filepath = vdb_path
    obj = bpy.data.objects.new(name, data)
    coll.objects.link(obj)
    obj.matrix_world = placement(unit_scale, grid_to_world)
    obj.volrig.role = "VOLUME"
    obj.volrig.unit_scale = unit_scale
    return obj


def _cached_preview(volume_obj, prefix: str, write) -> str:
    """Cache path (relative, as the Volume data wants it) of ``<prefix>_<key>.vdb`` for the current segmentation,
    written by ``write(path)`` when missing; earlier ``<prefix>_*.vdb`` files are removed (a new name per
    segmentation, so Blender reloads it)."""
    import hashlib
    folder = scans.cache_dir(volume_obj)
    key = hashlib.sha1(repr(scans.segmentation_key(volume_obj)).encode()).hexdigest()[:10]
    path = os.path.join(folder, f"{prefix}_{key}.vdb")
    if not os.path.exists(path):
        write(path)
    for old in os.listdir(folder):
        if old.startswith(prefix + "_") and old.endswith(".vdb") and old != os.path.basename(path):
            os.remove(os.path.join(folder, old))
    return os.path.join(volume_obj.volrig.cache_dir, os.path.basename(path))


def _child(volume_obj, role: str, suffix: str, data, material) -> bpy.types.Object:
    """The object of ``role`` over the scan (parented to it, in its frame), made when missing with new data from
    ``data`` (``bpy.data.volumes`` or ``bpy.data.meshes``) and the material ``material()``."""
    obj = members(volume_obj).get(role)
    if obj is None:
        name = volume_obj.name + suffix
        obj = _new_object(volume_obj, name, data.new(name), role)
        obj.parent = volume_obj
        obj.matrix_parent_inverse.identity()
        obj.data.materials.append(material())
    return obj


def update_mask_preview(volume_obj, mask: volrig.Volume) -> bpy.types.Object:
    """Shows ``mask`` as ``<name>_mask``: a Volume object over the scan (parented to it) whose grid is the mask,
    written to the cache as mask_<key>.vdb."""
    rel = _cached_preview(volume_obj, "mask", lambda path: volrig.write_vdb(path, {"density": mask}))
    obj = _child(volume_obj, "MASK", "_mask", bpy.data.volumes, _mask_material)
    obj.data.filepath = rel
    return obj


def update_thickness(volume_obj, mask: volrig.Volume, progress=None) -> tuple:
    """Shows the mask coloured by its local thickness as ``<name>_thickness`` (grids ``density``: the mask,
    ``thickness``: world units; cached as thickness_<key>.vdb). Returns (object, thickness values of the mask)."""

    computed = []

    def write(path):
        computed.append(volrig.local_thickness(mask, progress=progress))
        volrig.write_vdb(path, {"density": mask, "thickness": computed[0]}, half=False)

    rel = _cached_preview(volume_obj, "thickness", write)
    # freshly computed, or the cached file of this segmentation
    t = computed[0] if computed else volrig.load(os.path.join(scans.cache_dir(volume_obj), os.path.basename(rel)),
                                                 grid="thickness")
    values = t.array[t.array > 0]
    obj = _child(volume_obj, "THICKNESS", "_thickness", bpy.data.volumes,
                 lambda: materials.thickness_material(volume_obj.name))
    obj.data.filepath = rel
    s = volume_obj.volrig
    extent = max(d * sp for d, sp in zip(s.dims, s.spacing)) * s.unit_scale
    top = float(np.percentile(values, 99)) if values.size else 1.0
    materials.set_thickness_range(obj.active_material, top, density=40.0 / max(extent, 1e-9))
    return obj, values


def update_medial_surface(volume_obj, ms) -> bpy.types.Object:
    """Shows a ``volrig.MedialSurface`` as ``<name>_medial``, parented to the scan (its vertices are in the grid
    frame, volume units, as the scan object's own space): triangles with a ``thickness`` point attribute, and the
    rods as loose edges (``thickness`` there: twice the rod radius); replaces the mesh's geometry when it exists."""
    verts = [np.asarray(ms.vertices, dtype=np.float64).reshape(-1, 3)]
    thick = [np.asarray(ms.thickness, dtype=np.float64)]
    edges = []
    offset = len(verts[0])
    for line, radii in zip(ms.rods, ms.rod_radii):
        verts.append(np.asarray(line, dtype=np.float64))
        thick.append(2.0 * np.asarray(radii, dtype=np.float64))
        idx = np.arange(offset, offset + len(line))
        edges.append(np.stack([idx[:-1], idx[1:]], axis=1))
        offset += len(line)
    co = np.concatenate(verts)
    values = np.concatenate(thick)
    faces = np.asarray(ms.faces, dtype=np.int32).reshape(-1, 3)
    obj = _child(volume_obj, "MEDIAL", "_medial", bpy.data.meshes, lambda: materials.medial_material(volume_obj.name))
    mesh = obj.data
    mesh.clear_geometry()
    mesh.vertices.add(len(co))
    mesh.vertices.foreach_set("co", co.astype(np.float32).ravel())
    rod_edges = np.concatenate(edges).astype(np.int32) if edges else np.zeros((0, 2), np.int32)
    if len(rod_edges):
        mesh.edges.add(len(rod_edges))
        mesh.edges.foreach_set("vertices", rod_edges.ravel())
    if len(faces):
        mesh.loops.add(3 * len(faces))
        mesh.loops.foreach_set("vertex_index", faces.ravel())
        mesh.polygons.add(len(faces))
        mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * len(faces), 3, dtype=np.int32))
        mesh.polygons.foreach_set("loop_total", np.full(len(faces), 3, dtype=np.int32))
    mesh.update(calc_edges=True, calc_edges_loose=True)
    attr = mesh.attributes.get("thickness") or mesh.attributes.new("thickness", "FLOAT", "POINT")
    attr.data.foreach_set("value", values.astype(np.float32))
    # The rods as tubes (geometry nodes): the loose edges, of the rods' radii.
    loose = np.zeros(len(mesh.edges), dtype=bool)
    mesh.edges.foreach_get("is_loose", loose)
    rod = mesh.attributes.get("rod") or mesh.attributes.new("rod", "BOOLEAN", "EDGE")
    rod.data.foreach_set("value", loose)
    radius = np.where(np.arange(len(co)) >= len(verts[0]), values / 2.0, 0.0)
    attr = mesh.attributes.get("radius") or mesh.attributes.new("radius", "FLOAT", "POINT")
    attr.data.foreach_set("value", radius.astype(np.float32))
    if obj.modifiers.get(ROD_NODES) is None:
        obj.modifiers.new(ROD_NODES, "NODES").node_group = rod_nodes()
    top = float(np.percentile(values, 99)) if values.size else 1.0
    materials.set_medial_range(obj.active_material, top)
    return obj


def _sphere(segments: int = 10, rings: int = 6):
    """A unit UV sphere: (vertices, triangles)."""
    verts = [(0.0, 0.0, 1.0)]
    for r in range(1, rings):
        t = np.pi * r / rings
        verts += [(np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t))
                  for a in 2 * np.pi * np.arange(segments) / segments]
    verts.append((0.0, 0.0, -1.0))
    tris, last = [], len(verts) - 1
    for k in range(segments):
        k1 = (k + 1) % segments
        tris.append((0, 1 + k, 1 + k1))
        tris.append((last, 1 + (rings - 2) * segments + k1, 1 + (rings - 2) * segments + k))
        for r in range(rings - 2):
            a, b = 1 + r * segments, 1 + (r + 1) * segments
            tris += [(a + k, b + k, b + k1), (a + k, b + k1, a + k1)]
    return np.array(verts), np.array(tris)


def _cylinders(p0, p1, radius, segments: int = 8):
    """Open cylinders of ``radius`` from each p0 to p1: (vertices, triangles), 2 x segments vertices each."""
    axis = p1 - p0
    length = np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
    w = axis / length
    helper = np.where(np.abs(w[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(w, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(w, u)
    a = 2 * np.pi * np.arange(segments) / segments
    ring = np.cos(a)[None, :, None] * u[:, None, :] + np.sin(a)[None, :, None] * v[:, None, :]
    ring = ring * radius[:, None, None]
    verts = np.concatenate([p0[:, None, :] + ring, p1[:, None, :] + ring], axis=1).reshape(-1, 3)
    k = np.arange(segments)
    k1 = (k + 1) % segments
    one = np.concatenate([np.stack([k, segments + k, segments + k1], 1), np.stack([k, segments + k1, k1], 1)])
    tris = (one[None, :, :] + (2 * segments * np.arange(len(p0)))[:, None, None]).reshape(-1, 3)
    return verts, tris


def update_pore_network(volume_obj, net, origin, spacing) -> bpy.types.Object:
    """Shows a ``volrig.PoreNetwork`` of the scan's segmentation as ``<name>_pores``, parented to the scan (grid
    frame, volume units): a sphere of its inscribed diameter at each pore, a cylinder of its inscribed diameter along
    each throat, the ``thickness`` point attribute (the diameter) coloured through the thickness ramp; replaces the
    mesh's geometry when it exists."""
    # The network's coordinates run from the image's corner; the grid frame puts voxel centres at origin + i spacing.
    centres = net.pore_coords + np.asarray(origin, float) - 0.5 * np.asarray(spacing, float)
    unit, unit_tris = _sphere()
    radius = net.pore_diameter / 2.0
    sv = (centres[:, None, :] + radius[:, None, None] * unit[None, :, :]).reshape(-1, 3)
    st = (unit_tris[None, :, :] + (len(unit) * np.arange(len(centres)))[:, None, None]).reshape(-1, 3)
    p0, p1 = centres[net.throat_conns[:, 0]], centres[net.throat_conns[:, 1]]
    cv, ct = _cylinders(p0, p1, net.throat_diameter / 2.0)
    co = np.concatenate([sv, cv])
    tris = np.concatenate([st, ct + len(sv)]).astype(np.int32)
    values = np.concatenate([np.repeat(net.pore_diameter, len(unit)), np.repeat(net.throat_diameter, 16)])
    obj = _child(volume_obj, "PORES", "_pores", bpy.data.meshes,
                 lambda: materials.medial_material(volume_obj.name + " pores"))
    mesh = obj.data
    mesh.clear_geometry()
    mesh.vertices.add(len(co))
    mesh.vertices.foreach_set("co", co.astype(np.float32).ravel())
    mesh.loops.add(3 * len(tris))
    mesh.loops.foreach_set("vertex_index", tris.ravel())
    mesh.polygons.add(len(tris))
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * len(tris), 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(tris), 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    attr = mesh.attributes.get("thickness") or mesh.attributes.new("thickness", "FLOAT", "POINT")
    attr.data.foreach_set("value", values.astype(np.float32))
    materials.set_medial_range(obj.active_material, float(np.percentile(values, 99)) if values.size else 1.0)
    return obj


def _mask_material():
    mat = bpy.data.materials.get("volrig mask")
    if mat is None:
        mat = bpy.data.materials.new("volrig mask")
        compat.use_nodes(mat)
        nodes = mat.node_tree.nodes
        nodes.clear()
        vol = nodes.new("ShaderNodeVolumeScatter")
        vol.inputs["Color"].default_value = (0.2, 0.8, 1.0, 1.0)
        vol.inputs["Density"].default_value = 0.5
        out = nodes.new("ShaderNodeOutputMaterial")
        mat.node_tree.links.new(vol.outputs["Volume"], out.inputs["Volume"])
    return mat


# ---- spheres drawn by geometry nodes: an icosphere instanced on each vertex, scaled by its radius ----

def _new_socket(group, name, in_out, socket_type):
    if hasattr(group, "interface"):  # Blender 4.0+
        group.interface.new_socket(name=name, in_out=in_out, socket_type=socket_type)
    elif in_out == "INPUT":
        group.inputs.new(socket_type, name)
    else:
        group.outputs.new(socket_type, name)


def _geometry_group(name):
    """A new geometry-nodes group ``name`` with one geometry input and output: (group, input node, output node)."""
    group = bpy.data.node_groups.new(name, "GeometryNodeTree")
    _new_socket(group, "Geometry", "INPUT", "NodeSocketGeometry")
    _new_socket(group, "Geometry", "OUTPUT", "NodeSocketGeometry")
    return group, group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")


def sphere_nodes():
    """The shared geometry-nodes group that shows each vertex's sphere (``radius`` attribute) and keeps the edges."""
    group = bpy.data.node_groups.get(SPHERE_NODES)
    if group is not None:
        return group
    group, gin, gout = _geometry_group(SPHERE_NODES)
    n = group.nodes
    ico = n.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value = 1.0
    ico.inputs["Subdivisions"].default_value = 1
    radius = n.new("GeometryNodeInputNamedAttribute")
    radius.data_type = "FLOAT"
    radius.inputs["Name"].default_value = "radius"
    inst = n.new("GeometryNodeInstanceOnPoints")
    join = n.new("GeometryNodeJoinGeometry")
    link = group.links.new
    link(gin.outputs[0], inst.inputs["Points"])
    link(ico.outputs["Mesh"], inst.inputs["Instance"])
    link(next(o for o in radius.outputs if o.enabled), inst.inputs["Scale"])
    link(gin.outputs[0], join.inputs[0])
    link(inst.outputs["Instances"], join.inputs[0])
    link(join.outputs[0], gout.inputs[0])
    for i, node in enumerate((gin, radius, ico, inst, join, gout)):
        node.location = (200 * i, 0)
    return group


def rod_nodes():
    """The shared geometry-nodes group that turns a mesh's ``rod`` edges into tubes of the ``radius`` point
    attribute (the other attributes, ``thickness`` among them, carried along) and keeps the mesh."""
    group = bpy.data.node_groups.get(ROD_NODES)
    if group is not None:
        return group
    group, gin, gout = _geometry_group(ROD_NODES)
    n = group.nodes
    rod, radius = n.new("GeometryNodeInputNamedAttribute"), n.new("GeometryNodeInputNamedAttribute")
    rod.data_type, radius.data_type = "BOOLEAN", "FLOAT"
    rod.inputs["Name"].default_value, radius.inputs["Name"].default_value = "rod", "radius"
    to_curve, set_radius = n.new("GeometryNodeMeshToCurve"), n.new("GeometryNodeSetCurveRadius")
    circle, to_mesh = n.new("GeometryNodeCurvePrimitiveCircle"), n.new("GeometryNodeCurveToMesh")
    circle.inputs["Resolution"].default_value = 8
    circle.inputs["Radius"].default_value = 1.0
    join = n.new("GeometryNodeJoinGeometry")
    link = group.links.new
    link(gin.outputs[0], to_curve.inputs["Mesh"])
    link(next(o for o in rod.outputs if o.enabled), to_curve.inputs["Selection"])
    link(to_curve.outputs["Curve"], set_radius.inputs["Curve"])
    link(next(o for o in radius.outputs if o.enabled), set_radius.inputs["Radius"])
    link(set_radius.outputs["Curve"], to_mesh.inputs["Curve"])
    link(circle.outputs["Curve"], to_mesh.inputs["Profile Curve"])
    link(gin.outputs[0], join.inputs[0])
    link(to_mesh.outputs["Mesh"], join.inputs[0])
    link(join.outputs[0], gout.inputs[0])
    for i, node in enumerate((gin, rod, to_curve, radius, set_radius, circle, to_mesh, join, gout)):
        node.location = (200 * i, 0)
    return group


def _show_spheres(obj, show: bool) -> None:
    mod = obj.modifiers.get("volrig spheres")
    if show and mod is None:
        mod = obj.modifiers.new("volrig spheres", "NODES")
        mod.node_group = sphere_nodes()
        mod.show_render = False
    elif mod is not None:
        mod.show_viewport = show


def _set_points(mesh, centers, radii, edges=None) -> None:
    mesh.clear_geometry()
    mesh.vertices.add(len(centers))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(centers, dtype=np.float32).ravel())
    if edges is not None and len(edges):
        mesh.edges.add(len(edges))
        mesh.edges.foreach_set("vertices", np.ascontiguousarray(edges, dtype=np.int32).ravel())
    attr = mesh.attributes.get("radius") or mesh.attributes.new("radius", "FLOAT", "POINT")
    attr.data.foreach_set("value", np.ascontiguousarray(radii, dtype=np.float32))
    mesh.update()


def update_skeleton_preview(volume_obj) -> None:
    """Re-threshold the kept skeleton at the current thinness and show its points (instant: no recomputation).
    Does nothing until Skeletonize has computed the skeleton in this session."""
    s = volume_obj.volrig
    sk = scans.skeleton(volume_obj, compute=False)
    if sk is None:
        return
    pts = sk.at(scans.thinness(volume_obj))
    s.point_count = len(pts)
    obj = members(volume_obj).get("SKELETON")
    if obj is None:
        obj = _new_object(volume_obj, volume_obj.name + "_skeleton", bpy.data.meshes.new(volume_obj.name + "_skeleton"),
                          "SKELETON")
        obj.matrix_world = volume_obj.matrix_world
    _set_points(obj.data, pts.centers, pts.radii)
    _show_spheres(obj, s.show_spheres)


# ---- the rig ----

def scene_up(volume_obj):
    """The scene's +Z as a direction in the volume's own frame (volrig's world: voxels at spacing and origin), for
    autorig's ``up``: whichever way the scan was imported or turned, up is where the user sees it."""
    from mathutils import Vector
    d = volume_obj.matrix_world.to_3x3().inverted_safe() @ Vector((0.0, 0.0, 1.0))
    return tuple(d.normalized())


def build_armature(volume_obj, rig: volrig.Rig):
    """``<name>_rig``: one bone per rig bone from rig.heads()/rig.tails() in volume units (roll 0, so each bone's
    rest matrix equals Rig.rest_matrices), parents from rig.parents; replaces an existing one."""
    old = members(volume_obj).get("RIG")
    name = volume_obj.name + "_rig"
    if old is not None:
        _remove(old)
    arm = bpy.data.armatures.new(name)
    obj = _new_object(volume_obj, name, arm, "RIG")
    fill_armature(obj, rig, volume_obj.matrix_world if volume_obj.parent is None else
                  volume_obj.parent.matrix_world @ volume_obj.matrix_local)
    return obj


def fill_armature(obj, rig: volrig.Rig, matrix_world) -> None:
    """Gives the (new, empty) armature object ``obj`` the rig's bones (in its own frame, roll 0: each bone's rest
    matrix equals Rig.rest_matrices), shown as sticks in front, placed at ``matrix_world``."""
    obj.data.display_type = "STICK"
    obj.show_in_front = True
    obj.matrix_world = matrix_world
    _edit_armature(obj, lambda: _add_bones(obj.data, rig))


def _edit_armature(obj, edit) -> None:
    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    if bpy.context.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        edit()
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
        view_layer.objects.active = previous if previous is not None and previous.name in view_layer.objects else obj


def _add_bones(arm, rig: volrig.Rig) -> None:
    heads, tails = rig.heads(), rig.tails()
    ebs = []
    for b, name in enumerate(rig.names):
        eb = arm.edit_bones.new(name)
        eb.head, eb.tail, eb.roll = tuple(heads[b]), tuple(tails[b]), 0.0
        ebs.append(eb)
    for b, p in enumerate(rig.parents):
        if p >= 0:
            ebs[b].parent = ebs[p]
            ebs[b].use_connect = bool(np.allclose(heads[b], tails[p]))


def thickness_property(pose_bone) -> None:
    """Gives ``pose_bone`` its ``volrig_thickness`` (1) with its slider range, unless it has one."""
    if THICKNESS not in pose_bone:
        pose_bone[THICKNESS] = 1.0
    pose_bone.id_properties_ui(THICKNESS).update(
        min=0.0, max=4.0, soft_min=0.0, soft_max=4.0, default=1.0, step=1, precision=3,
        description="Thickness around this bone (1 = as scanned or modelled; keyframable)")


def build_spheres(volume_obj, rig_obj, points: volrig.SkeletonPoints, tree, binding: volrig.Binding):
    """``<name>_spheres``: one vertex per point, ``radius``, tree edges, vertex groups from the binding, Armature
    modifier, parented to the rig; replaces an existing one."""
    old = members(volume_obj).get("SPHERES")
    if old is not None:
        _remove(old)
    name = volume_obj.name + "_spheres"
    obj = _new_object(volume_obj, name, bpy.data.meshes.new(name), "SPHERES")
    _set_points(obj.data, points.centers, points.radii, tree.edges if tree is not None else None)
    obj.parent = rig_obj
    obj.matrix_parent_inverse = Matrix.Identity(4)
    obj.matrix_basis = Matrix.Identity(4)
    set_vertex_groups(obj, binding)
    mod = obj.modifiers.new("Armature", "ARMATURE")
    mod.object = rig_obj
    mod.use_vertex_groups = True
    _show_spheres(obj, True)
    obj.display_type = "WIRE"
    obj.hide_render = True
    return obj


def set_vertex_groups(spheres_obj, binding: volrig.Binding) -> None:
    """One vertex group per bone holding its weights (existing groups are replaced)."""
    spheres_obj.vertex_groups.clear()
    for name, (idx, w) in zip(binding.bone_names, binding.groups()):
        vg = spheres_obj.vertex_groups.new(name=name)
        if not len(idx):
            continue
        values, inverse = np.unique(w, return_inverse=True)
        for k, value in enumerate(values):
            vg.add(idx[inverse == k].tolist(), float(value), "REPLACE")


def attach_volume(volume_obj, rig_obj) -> None:
    """Parent the Volume object to the rig without moving it, so moving the rig object moves the bake too."""
    world = volume_obj.matrix_world.copy()
    volume_obj.parent = rig_obj
    volume_obj.matrix_parent_inverse = Matrix.Identity(4)
    volume_obj.matrix_world = world


def point_volume_at(volume_obj, path: str, sequence=None) -> None:
    """Show ``path`` on the Volume object; ``sequence`` = (first frame, last frame) plays files numbered by scene
    frame (``<name>_0001.vdb`` ...)."""
    data = volume_obj.data
    data.filepath = path
    if sequence is None:
        data.is_sequence = False
    else:
        first, last = sequence
        data.is_sequence = True
        data.frame_start = first
        data.frame_duration = last - first + 1
        data.frame_offset = first - 1  # file number = scene frame
        data.sequence_mode = "EXTEND"
    # Forget the grids read before, so the new file is read; the depsgraph loads it. (Loading here as well, on the
    # original data-block, leaves Blender 5.x's evaluated volume with empty bounds at the current frame: EEVEE then
    # culls it and renders nothing until the frame changes.)
    data.grids.unload()

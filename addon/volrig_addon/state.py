"""The state of one volrig Volume object's set that the bake, the looks and the materials share: its members by
role, the rig its armature and sphere mesh describe now (``RigState``), its parts, their substitutes and its tissue
classes as the looks list them, and the tissues' rest file. Imports only ``scans`` (which imports no sibling), so
every module of the add-on can import it at the top.
"""
import os

import bpy
import numpy as np

import volrig
from volrig import pipeline

from . import scans


def volume_of(obj):
    """The volrig Volume object ``obj`` belongs to (itself for the Volume), or None."""
    if obj is None:
        return None
    if obj.volrig.role == "VOLUME":
        return obj
    v = obj.volrig.volume
    return v if v is not None and v.volrig.role == "VOLUME" else None


def members(volume_obj):
    """Objects of the set by role: {"RIG": obj, "SPHERES": obj, ...} (those that exist)."""
    out = {}
    for o in bpy.data.objects:
        if o.volrig.role != "VOLUME" and o.volrig.volume == volume_obj:
            out[o.volrig.role] = o
    return out


def armature_rig(rig_obj) -> volrig.Rig:
    """The rig the armature describes now (after the user's edits), bones in the armature's order."""
    bones = list(rig_obj.data.bones)
    if not bones:
        raise volrig.VolrigError(f"{rig_obj.name} has no bones")
    index = {b.name: i for i, b in enumerate(bones)}
    heads = np.array([tuple(b.head_local) for b in bones])
    tails = np.array([tuple(b.tail_local) for b in bones])
    parents = [index[b.parent.name] if b.parent else -1 for b in bones]
    return volrig.Rig.from_bones(heads, tails, [b.name for b in bones], parents)


def vertex_groups(spheres_obj):
    """The weights the vertex groups hold now: {group name: (vertex indices, weights)}."""
    names = [vg.name for vg in spheres_obj.vertex_groups]
    idx = [[] for _ in names]
    w = [[] for _ in names]
    for v in spheres_obj.data.vertices:
        for g in v.groups:
            if g.weight > 0:
                idx[g.group].append(v.index)
                w[g.group].append(g.weight)
    return {n: (np.array(i, dtype=np.int64), np.array(x, dtype=np.float64)) for n, i, x in zip(names, idx, w)}


#: the pose-bone property holding a bone's thickness factor (1 = as scanned or modelled, 0 .. 4); keyframable.
#: Meshes read it through their thickness shape keys' drivers, volumes at bake time.
THICKNESS = "volrig_thickness"


class RigState:
    """A rigged volrig Volume object as the deformation sees it now: its armature and sphere mesh, the rig file's
    points, the bone names in the armature's order and the binding from the sphere mesh's vertex groups (weight
    painting counts)."""

    def __init__(self, volume_obj):
        self.volume_obj = volume_obj
        parts = members(volume_obj)
        if "RIG" not in parts or "SPHERES" not in parts:
            raise volrig.VolrigError(f"{volume_obj.name} is not rigged: press Rig first")
        self.rig_obj, self.spheres_obj = parts["RIG"], parts["SPHERES"]
        self.path = scans.rig_path(volume_obj)
        saved = volrig.load_rig(self.path)
        self.points = saved.points
        self.names = [b.name for b in self.rig_obj.data.bones]
        fallback = saved.binding if saved.binding is not None and saved.binding.bone_names == self.names else None
        groups = vertex_groups(self.spheres_obj)
        if len(self.spheres_obj.data.vertices) != len(saved.points):
            raise volrig.VolrigError(f"{self.spheres_obj.name} has {len(self.spheres_obj.data.vertices)} vertices "
                                     f"but the rig file has {len(saved.points)} points: press Rig again")
        self.binding = volrig.Binding.from_groups(groups, self.names, len(saved.points), fallback=fallback)
        self.rig = armature_rig(self.rig_obj)

    @property
    def parents(self):
        """Each bone's parent index in the armature (-1 for roots)."""
        index = {name: b for b, name in enumerate(self.names)}
        return [index[b.parent.name] if b.parent else -1 for b in self.rig_obj.data.bones]

    def thickness(self, depsgraph):
        """(B,) each bone's thickness factor now (its pose bone's ``volrig_thickness``, keyframable; 1 when unset),
        or None when every bone is at 1."""
        arm = self.rig_obj.evaluated_get(depsgraph)
        out = np.array([float(arm.pose.bones[name].get(THICKNESS, 1.0)) for name in self.names])
        return None if np.all(out == 1.0) else out

    def bone_matrices(self, depsgraph) -> np.ndarray:
        """(B, 4, 4) rest-to-pose matrices of the evaluated armature, in the bone order of the binding."""
        arm = self.rig_obj.evaluated_get(depsgraph)
        out = np.empty((len(self.names), 4, 4))
        for b, name in enumerate(self.names):
            pb = arm.pose.bones[name]
            out[b] = np.array(pb.matrix @ pb.bone.matrix_local.inverted())
        # (bones at rest come out of Blender's single precision a hair off the identity: volrig.deform takes them as
        # the identity itself)
        return out


def parts_of(volume_obj):
    """The object's parts as ``volrig.Part`` (bone indices in the armature's order), for the bake and the
    material; none while per-part looks are off."""
    rig = members(volume_obj).get("RIG")
    if rig is None or not volume_obj.volrig.use_parts:
        return []
    index = {b.name: i for i, b in enumerate(rig.data.bones)}
    out = []
    for p in volume_obj.volrig.parts:
        bones = [index[name] for name in p.bones.split(",") if name in index]
        if bones:
            out.append(volrig.Part(p.name, p.key, bones))
    return out


_LOADED = {}  # substitute file -> (modification time, Volume): loaded once per change


def substitutes_of(volume_obj) -> dict:
    """``{part key: Volume}`` of the parts given a substitute file (per-part looks on), loaded once per change of
    the file; VolrigError naming the part when a file cannot be read."""
    if not volume_obj.volrig.use_parts:
        return {}
    out = {}
    for p in volume_obj.volrig.parts:
        if not p.substitute:
            continue
        path = bpy.path.abspath(p.substitute)
        try:
            stamp = os.path.getmtime(path)
            held = _LOADED.get(path)
            if held is None or held[0] != stamp:
                held = _LOADED[path] = (stamp, volrig.load(path))
        except (OSError, ValueError) as e:
            raise volrig.VolrigError(f"the substitute of part {p.name!r}: {e}") from e
        out[p.key] = held[1]
    used = {bpy.path.abspath(p.substitute) for p in volume_obj.volrig.parts if p.substitute}
    for path in set(_LOADED) - used:  # (a full-resolution substitute no longer used is not kept)
        del _LOADED[path]
    return out


def tissues_of(volume_obj):
    """The object's tissue classes as ``volrig.Tissue`` with their looks from the list; none while per-tissue looks
    are off."""
    s = volume_obj.volrig
    if not s.use_tissues:
        return []
    return [volrig.Tissue(t.name, t.key, [int(c) for c in t.codes.split(",") if c], tuple(t.color), t.opacity,
                          t.visible) for t in s.tissues]


def tissues_rest_file(volume_obj) -> str:
    """The rest volume with the tissue grids when per-part looks are off."""
    return os.path.join(scans.cache_dir(volume_obj), "tissues.vdb")


def write_tissues_rest(volume_obj) -> None:
    """The rest volume with the tissue grids (no rig needed)."""
    pipeline.write_rest_looks(tissues_rest_file(volume_obj), scans.source(volume_obj), tissues=tissues_of(volume_obj))

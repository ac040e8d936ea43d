"""Along the centerline of a tubular volrig volume (issue 20; docs/ALGORITHMS.md §9): a fly-through (a Bezier
curve on the centerline, a camera keyed along it looking down the averaged tangent, a headlight riding with it and
the wall seen from inside), the straightened volume (curved planar reformation) beside the original, and the
straightening animation through the rig machinery (a chain armature along the centerline keyed from its curved
rest to a straight line; Bake then straightens the organ). The numbers come from ``volrig.centerline``.

Objects of a volume's set made here (roles): ``<name>_path`` (PATH, curve, child of the volume),
``<name>_camera`` (CAMERA), ``<name>_light`` (LIGHT, child of the camera), ``<name>_lumen`` (LUMEN, the wall as a
Volume object, child of the volume). Fly Through again replaces them.

The Fly Through, Straighten and Animate Straightening operators and the Centerline panel are here too.
"""
import os

import bpy
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, IntProperty
import numpy as np
from mathutils import Matrix, Vector

import volrig
from volrig.centerline import STRAIGHTENING_BONES, flight_frames, flight_path, lumen_wall, straightening_rig

from . import compat, engines, materials, objects, scans, staging
from .bake import exit_with
from .ops_base import _OnVolume, _ProgressBar, _props, _settings, _VolrigPanel
from .rig import _save_rig
from .volume import import_samples

#: The headlight's power for a lumen of radius 1 Blender unit (W); it scales with the radius squared, so the wall
#: at the lumen's radius is lit alike in a trachea and in a bronchus a tenth as wide.
# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

class CenterlineSettings:
    """Where the centerline runs, the fly-through's camera and the straightening."""
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
    straighten_bones: IntProperty(name="Bones", default=STRAIGHTENING_BONES, min=1, max=200,
                                  description="Straightening rig: bones along the centerline (equal arc pieces)")
    straighten_frames: IntProperty(name="Frames", default=48, min=2, max=100000,
                                   description="Straightening rig: frames from curved to straight")


LIGHT_POWER = 80.0


def centerline(volume_obj, progress=None) -> volrig.Centerline:
    """The centerline the fly-through and straightening follow: from the Start to the End point (volume units)
    when Ends is Points, else from the end of the thickest terminal branch to the farthest end."""
    s = volume_obj.volrig
    points = s.fly_ends == "POINTS"
    return flight_path(scans.mask(volume_obj), tuple(s.fly_start) if points else None,
                       tuple(s.fly_end) if points else None, progress=progress)


def _replace(volume_obj, role, name, data):
    old = objects.members(volume_obj).get(role)
    if old is not None:
        objects._remove(old)
    if data is None:
        return None
    return objects._new_object(volume_obj, name, data, role)


def _child_of_volume(obj, volume_obj) -> None:
    obj.parent = volume_obj
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = Matrix.Identity(4)


def build_path(volume_obj, line: volrig.Centerline, spacing: float = 2.0):
    """``<name>_path``: a 3-D Bezier curve (automatic handles) through the centerline every ``spacing`` volume
    units, in the volume's own units (a child of the volume, so it sits on the scan)."""
    name = volume_obj.name + "_path"
    curve = bpy.data.curves.new(name, "CURVE")
    curve.dimensions = "3D"
    n = max(int(np.ceil(line.length / spacing)) + 1, 2)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line.points, axis=0), axis=1))])
    q = np.linspace(0.0, s[-1], n)
    pts = np.stack([np.interp(q, s, line.points[:, a]) for a in range(3)], axis=1)
    spline = curve.splines.new("BEZIER")
    spline.bezier_points.add(n - 1)
    spline.bezier_points.foreach_set("co", pts.astype(np.float32).ravel())
    for bp in spline.bezier_points:
        bp.handle_left_type = bp.handle_right_type = "AUTO"
    curve.path_duration = n
    obj = _replace(volume_obj, "PATH", name, curve)
    _child_of_volume(obj, volume_obj)
    return obj


def _keys(id_data, path: str, frames, values, group: str = "") -> None:
    """Linear keyframes of an (F, C) array on property ``path`` of ``id_data`` at ``frames``, written in bulk."""
    values = np.asarray(values, dtype=np.float64).reshape(len(frames), -1)
    curves = compat.fcurves(id_data)
    for c in range(values.shape[1]):
        fc = curves.find(path, index=c)
        if fc is not None:
            curves.remove(fc)
        fc = compat.new_fcurve(curves, path, c, group)
        fc.keyframe_points.add(len(frames))
        co = np.stack([np.asarray(frames, dtype=np.float64), values[:, c]], axis=1).astype(np.float32)
        fc.keyframe_points.foreach_set("co", co.ravel())
        fc.keyframe_points.foreach_set("interpolation", np.full(len(frames), 1, dtype=np.int32))  # LINEAR
        fc.update()


def _continuous(quats: np.ndarray) -> np.ndarray:
    """Quaternions (F, 4) with signs chosen so each is on the same side as the one before (no spins)."""
    q = quats.copy()
    for k in range(1, len(q)):
        if np.dot(q[k], q[k - 1]) < 0:
            q[k] = -q[k]
    return q


def camera_keys(matrix_world, flight) -> tuple:
    """World locations (F, 3) and rotation quaternions (F, 4, w first) of a camera flying ``flight`` (volume
    units) in a volume placed by ``matrix_world``: the camera looks down its -Z, so -Z is the view direction and +Y
    the flight's up."""
    M = np.array(matrix_world)
    A = M[:3, :3]
    loc = flight.positions @ A.T + M[:3, 3]
    quats = np.empty((len(flight), 4))
    for k, (d, u) in enumerate(zip(flight.directions, flight.ups)):
        z = -(A @ d)
        z /= np.linalg.norm(z)
        y = A @ u
        y -= (y @ z) * z
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        quats[k] = tuple(Matrix([tuple(x), tuple(y), tuple(z)]).transposed().to_quaternion())
    return loc, _continuous(quats)


def build_lumen(volume_obj, mask: volrig.Volume):
    """``<name>_lumen``: the wall around the segmented lumen as a Volume object (``volrig.centerline.lumen_wall``:
    only a shell a few voxels thick is stored, so Cycles marches the wall alone), child of the volume, with the
    wall material; written to the cache as lumen_<key>.vdb."""
    import hashlib
    folder = scans.cache_dir(volume_obj)
    key = hashlib.sha1(repr(scans.segmentation_key(volume_obj)).encode()).hexdigest()[:10]
    path = os.path.join(folder, f"lumen_{key}.vdb")
    if not os.path.exists(path):
        volrig.write_vdb(path, {"density": lumen_wall(mask)})
    name = volume_obj.name + "_lumen"
    obj = _replace(volume_obj, "LUMEN", name, bpy.data.volumes.new(name))
    _child_of_volume(obj, volume_obj)
    obj.data.filepath = os.path.join(volume_obj.volrig.cache_dir, os.path.basename(path))
    spacing = min(volume_obj.volrig.spacing) * volume_obj.volrig.unit_scale
    obj.data.materials.append(materials.lumen_wall_material(obj.name + " wall", 8.0 / max(spacing, 1e-12)))
    return obj


def fly_through(context, volume_obj, progress=None) -> dict:
    """Builds the fly-through of ``volume_obj`` from its settings (Ends, Start, End, Frames per mm, Look ahead,
    Field of view, Light) and returns what it made: {"line", "flight", "path", "camera", "light", "lumen"}."""
    s = volume_obj.volrig
    scene = context.scene
    line = centerline(volume_obj, progress)
    # (the flight ends where the lumen narrows below two voxels: there the wall's soft edge fills the view)
    flight = flight_frames(line, s.frames_per_mm, s.look_ahead, min_radius=2.0 * max(s.spacing))
    scale = float(np.cbrt(abs(np.linalg.det(np.array(volume_obj.matrix_world)[:3, :3]))))  # Blender units per unit
    path = build_path(volume_obj, line)

    cam_data = bpy.data.cameras.new(volume_obj.name + "_camera")
    cam_data.lens_unit = "FOV"
    cam_data.angle = np.radians(s.fly_fov)
    cam_data.clip_start = max(0.05 * float(flight.radii.min()) * scale, 1e-6)
    cam_data.clip_end = max(2.0 * line.length * scale, 10 * cam_data.clip_start)
    old_light = objects.members(volume_obj).get("LIGHT")
    if old_light is not None:
        objects._remove(old_light)
    cam = _replace(volume_obj, "CAMERA", volume_obj.name + "_camera", cam_data)
    cam.rotation_mode = "QUATERNION"
    frames = s.fly_frame_start + np.arange(len(flight))
    loc, quats = camera_keys(volume_obj.matrix_world, flight)
    _keys(cam, "location", frames, loc, "Object Transforms")
    _keys(cam, "rotation_quaternion", frames, quats, "Object Transforms")

    light_data = bpy.data.lights.new(volume_obj.name + "_light", "POINT")
    light_data.shadow_soft_size = 0.1 * float(flight.radii.min()) * scale
    light = _replace(volume_obj, "LIGHT", volume_obj.name + "_light", light_data)
    light.parent = cam
    light.matrix_parent_inverse.identity()
    light.matrix_basis = Matrix.Identity(4)
    # beside the lens as on an endoscope (a light at the lens itself shades the wall flat), 15 % of the way to
    # the wall above it
    _keys(light, "location", frames, np.c_[0 * flight.radii, 0.15 * flight.radii * scale, 0 * flight.radii],
          "Object Transforms")
    # the headlight follows the lumen's radius, so the wall nearby is lit alike in wide and narrow parts
    _keys(light_data, "energy", frames, s.fly_light * LIGHT_POWER * (flight.radii * scale) ** 2)

    lumen = build_lumen(volume_obj, scans.mask(volume_obj))
    s.preset = "LUMEN"  # the scan itself: the segmented range clear, the rest opaque (updates the material)

    scene.camera = cam
    scene.frame_start, scene.frame_end = int(frames[0]), int(frames[-1])
    scene.frame_set(int(frames[0]))
    engines.use(scene)  # Cycles on the CPU, or EEVEE where this Cycles renders no grids
    scene.view_settings.view_transform = "Standard"  # Filmic greys the wall's pink out
    staging.world_background(scene, (0.0, 0.0, 0.0))
    return {"line": line, "flight": flight, "path": path, "camera": cam, "light": light, "lumen": lumen}


def render_frames(scene, folder: str, count: int, resolution=(320, 320), samples: int = 16):
    """Renders ``count`` frames spread over the scene's range (first and last included) in Cycles on the CPU (or
    EEVEE where this Cycles renders no grids: engines.py) as
    PNGs ``frame_NNNN.png`` in ``folder``; returns their paths."""
    os.makedirs(folder, exist_ok=True)
    r = scene.render
    r.resolution_x, r.resolution_y = (int(v) for v in resolution)
    r.resolution_percentage = 100
    r.image_settings.file_format = "PNG"
    r.film_transparent = False
    engines.use(scene, samples)
    frames = np.unique(np.round(np.linspace(scene.frame_start, scene.frame_end, max(int(count), 1))).astype(int))
    paths = []
    for f in frames:
        scene.frame_set(int(f))
        r.filepath = os.path.join(folder, f"frame_{f:04d}.png")
        bpy.ops.render.render(write_still=True)
        paths.append(r.filepath)
    return paths


# ---- straightening ----

def straighten(context, volume_obj, import_samples, progress=None):
    """The volume resampled on the planes normal to its centerline (``volrig.straighten``), added as the Volume
    object ``<name>_straight`` beside the original (along +x); returns it. ``import_samples`` is the import
    operator's helper (the new object gets its own cache)."""
    s = volume_obj.volrig
    line = centerline(volume_obj, progress)
    radius = s.straighten_radius if s.straighten_radius > 0 else \
        1.5 * float(line.radii.max()) + 2.0 * max(s.spacing)
    straight, _ = volrig.straighten(scans.source(volume_obj), line, radius, fill=float(s.value_min))
    settings = {k: getattr(s, k) for k in ("segment_by", "low", "high", "labels", "largest", "preset",
                                           "density_scale", "sampling")}
    lo, hi = _box(volume_obj)
    obj = import_samples(context, straight, volume_obj.name + "_straight", s.unit_scale,
                         source=f"{volume_obj.name} straightened along its centerline")
    for k, v in settings.items():
        if k == "preset" and v == "LUMEN":
            v = "SOFT_TISSUE"
        setattr(obj.volrig, k, v)
    # beside the original: its box's +x side, a tenth of its width apart, the straight axis upright like its grid
    width = hi[0] - lo[0]
    slo, shi = _box(obj)
    shift = Vector((hi[0] + 0.1 * width - slo[0], (lo[1] + hi[1] - slo[1] - shi[1]) / 2, lo[2] - slo[2]))
    obj.matrix_world = Matrix.Translation(shift) @ obj.matrix_world
    return obj, line


def _box(volume_obj):
    lo, hi = staging.volume_box(volume_obj)
    return Vector(lo), Vector(hi)


def straightening_animation(context, volume_obj, save_rig, progress=None) -> tuple:
    """The thesis' §9.3 through the rig machinery: a chain armature of Bones equal-arc bones along the centerline
    (``volrig.straightening_rig``) replaces the volume's rig, its skeleton spheres (at the current thinness) are
    bound to it, and every frame of Frames is keyed from the curved rest (first frame) to the straight line (last);
    Bake then straightens the organ. Returns (the StraighteningRig, the armature object)."""
    s = volume_obj.volrig
    line = centerline(volume_obj, progress)
    sr = straightening_rig(line, bones=s.straighten_bones)
    mask = scans.mask(volume_obj)
    pts = scans.skeleton(volume_obj).at(scans.thinness(volume_obj))
    if len(pts) == 0:
        raise volrig.VolrigError(f"{volume_obj.name}: no skeleton points at thinness {s.thinness:g}: lower it")
    binding = volrig.bind(pts, sr.rig, mask, mode=s.bind_mode)
    save_rig(volume_obj, pts, None, sr.rig, binding)
    s.rig_found = f"straightening chain, {len(sr.rig)} bones"
    rig_obj = objects.build_armature(volume_obj, sr.rig)
    objects.build_spheres(volume_obj, rig_obj, pts, None, binding)
    objects.attach_volume(volume_obj, rig_obj)
    preview = objects.members(volume_obj).get("SKELETON")
    if preview is not None:
        preview.hide_set(True)
    n = max(int(s.straighten_frames), 2)
    frames = s.fly_frame_start + np.arange(n)
    fractions = np.linspace(0.0, 1.0, n)
    fractions = fractions * fractions * (3 - 2 * fractions)  # ease in and out
    basis = np.stack([sr.rig.basis_matrices(sr.matrices(f)) for f in fractions])  # (F, B, 4, 4)
    for b, name in enumerate(sr.rig.names):
        pb = rig_obj.pose.bones[name]
        pb.rotation_mode = "QUATERNION"
        q = np.array([tuple(Matrix(basis[k, b, :3, :3].tolist()).to_quaternion()) for k in range(n)])
        _keys(rig_obj, f'pose.bones["{name}"].rotation_quaternion', frames, _continuous(q), name)
    scene = context.scene
    scene.frame_start, scene.frame_end = int(frames[0]), int(frames[-1])
    scene.frame_set(int(frames[0]))
    materials.update_volume_material(volume_obj)
    return sr, rig_obj


# ---- headless: python -m volrig flythrough ----

def build_from_file(args: dict) -> dict:
    """The Blender side of ``volrig flythrough``: an empty scene, saved first as ``args["output"]`` (so the cache
    goes beside it), the scan imported and segmented, Fly Through, saved; frames rendered when asked."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 beside the output
    out = os.path.abspath(args["output"])
    os.makedirs(os.path.dirname(out), exist_ok=True)
    try:
        bpy.ops.wm.save_as_mainfile(filepath=out)
    except RuntimeError as e:
        raise OSError(f"{out}: cannot write ({e})") from None
    try:  # an operator's error report reaches Python as RuntimeError("Error: volrig: ...")
        bpy.ops.volrig.import_volume(filepath=os.path.abspath(args["file"]), unit="MM")
    except RuntimeError as e:
        raise volrig.VolrigError(str(e).split("volrig: ", 1)[-1].strip()) from None
    vol = bpy.context.active_object
    s = vol.volrig
    if args.get("labels"):
        s.segment_by, s.labels = "LABELS", " ".join(str(x) for x in args["labels"])
    else:
        s.segment_by = "RANGE"
        if args.get("lo") is not None:
            s.low, s.high = args["lo"], 1e9
        if args.get("hi") is not None:
            s.high = args["hi"]
    s.largest = bool(args.get("largest", True))
    if args.get("start") is not None or args.get("end") is not None:
        if args.get("start") is None or args.get("end") is None:
            raise volrig.VolrigError("--start and --end go together")
        s.fly_ends, s.fly_start, s.fly_end = "POINTS", args["start"], args["end"]
    s.frames_per_mm = args.get("frames_per_mm") or s.frames_per_mm
    if args.get("look_ahead") is not None:
        s.look_ahead = args["look_ahead"]
    made = fly_through(bpy.context, vol)
    bpy.ops.wm.save_mainfile()
    scene = bpy.context.scene
    made["renders"] = []
    if args.get("render"):
        made["renders"] = render_frames(scene, os.path.abspath(args["render"]), args.get("frames") or 3,
                                        args.get("resolution") or (320, 320), args.get("samples") or 16)
    return made


def command_line() -> None:
    """The Blender side of ``volrig flythrough``: ``build_from_file`` with the JSON after ``--`` (bake.exit_with)."""
    def work(args):
        made = build_from_file(args)
        scene = bpy.context.scene
        return (f"volrig: fly-through of {made['line'].length:.1f} mm in frames {scene.frame_start}-"
                f"{scene.frame_end} -> {bpy.data.filepath}" + "".join(f"\n  {p}" for p in made["renders"]))
    exit_with(work)


class _AlongCenterline(_OnVolume):
    """The operators that follow the volume's centerline: ``build(context, vol, progress)`` does the work, finding
    the centerline first (its progress on the first 80 % of the bar), and returns what to report."""

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            show = bar.steps({"centerline": (0, 80)})
            message = self.build(context, vol, lambda f: show("centerline", f))
        self.report({"INFO"}, f"volrig: {message}")
        return {"FINISHED"}


class VOLRIG_OT_fly_through(_AlongCenterline, bpy.types.Operator):
    """Fly a camera along the volume's centerline: a Bezier curve on it, a camera keyed along it looking down the
    averaged tangent, a headlight riding with it, the lumen's wall shown from inside, and the scene's frame range"""
    bl_idname = "volrig.fly_through"
    bl_label = "Fly Through"

    def build(self, context, vol, progress):
        made = fly_through(context, vol, progress=progress)
        scene = context.scene
        return (f"fly-through of {made['line'].length:.1f} units in {len(made['flight'])} frames "
                f"({scene.frame_start} .. {scene.frame_end}) by {made['camera'].name}")


class VOLRIG_OT_straighten(_AlongCenterline, bpy.types.Operator):
    """Resample the volume on the planes normal to its centerline (curved planar reformation) and add the straight
    volume as <name>_straight beside it"""
    bl_idname = "volrig.straighten"
    bl_label = "Straighten"

    def build(self, context, vol, progress):
        obj, line = straighten(context, vol, import_samples, progress=progress)
        x, y, z = obj.volrig.dims
        return f"{obj.name}: {x} x {y} x {z} voxels along {line.length:.1f} units of centerline"


class VOLRIG_OT_straightening_rig(_AlongCenterline, bpy.types.Operator):
    """Rig the volume with a chain of bones along its centerline and key it from curved to straight (Bake then
    straightens the organ); replaces the volume's rig"""
    bl_idname = "volrig.straightening_rig"
    bl_label = "Animate Straightening"

    def build(self, context, vol, progress):
        sr, rig_obj = straightening_animation(context, vol, _save_rig, progress=progress)
        scene = context.scene
        return (f"{rig_obj.name}: {len(sr.rig)} bones keyed straight over frames {scene.frame_start} .. "
                f"{scene.frame_end}; press Bake")


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


CLASSES = (VOLRIG_OT_fly_through, VOLRIG_OT_straighten, VOLRIG_OT_straightening_rig, VOLRIG_PT_centerline)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

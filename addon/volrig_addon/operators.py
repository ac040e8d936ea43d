"""Operators: thin over the volrig package, whose pipeline (``volrig.pipeline``) does every step. Each reports
user mistakes (volrig's own errors: bad files, empty segmentations, missing rigs; and OSError) in the UI instead
of raising, lets anything else (a bug) raise, is undoable, and never writes to the user's source file."""
import os
import threading
import uuid

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, IntVectorProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

import volrig
from volrig import pipeline
from volrig.collide import contact_runs
from volrig.volume import FORMATS, format_of

from . import bake as baking
from . import flythrough, looks, materials, mocap, objects, scans
from .properties import UNIT_FACTOR, UNIT_SCALES

#: What a user mistake or a bad file raises (volrig.Cancelled and volrig.FileFormatError are VolrigErrors); reported
#: in the UI, never as a traceback. Other exceptions are bugs and propagate.
USER_ERRORS = (volrig.VolrigError, OSError)


def _reported(method):
    """Wraps an operator's execute(self, context) or invoke(self, context, event): user errors become a report."""
    def run(self, context, *event):
        try:
            return method(self, context, *event)
        except volrig.Cancelled:
            self.report({"WARNING"}, "volrig: cancelled")
            return {"CANCELLED"}
        except USER_ERRORS as e:
            self.report({"ERROR"}, f"volrig: {e}")
            return {"CANCELLED"}

    if method.__code__.co_argcount == 3:  # Blender checks the argument count
        def invoke(self, context, event):
            return run(self, context, event)
        return invoke

    def execute(self, context):
        return run(self, context)
    return execute


def _active_volume(context):
    return objects.volume_of(context.active_object)


class _ProgressBar:
    """The window manager's progress bar (0..100) for a with-block; ``steps(spans)`` reports a pipeline's steps
    each on its part of the bar."""

    def __init__(self, context):
        self.wm = context.window_manager

    def __enter__(self):
        self.wm.progress_begin(0, 100)
        return self

    def __exit__(self, *exc):
        self.wm.progress_end()

    def steps(self, spans):
        """A pipeline StepProgress: step name -> its (start, end) span of the bar."""
        def show(step, f):
            start, end = spans[step]
            self.wm.progress_update(start + (end - start) * float(f))
            return True
        return show


def _rigged_volume_of(obj):
    """The volrig Volume object of obj (or a part of it) once it has a rig, else None."""
    vol = objects.volume_of(obj)
    return vol if vol is not None and "RIG" in objects.members(vol) else None


def _rigged_volume(context):
    return _rigged_volume_of(context.active_object)


class _OnVolume:
    """Undoable operators on the active object's volrig volume, offered in the context modes ``modes`` (None: any)
    and, when ``rigged``, once the volume has a rig."""
    bl_options = {"REGISTER", "UNDO"}
    modes = ("OBJECT",)
    rigged = False

    @classmethod
    def poll(cls, context):
        return cls.volume(context) is not None and (cls.modes is None or context.mode in cls.modes)

    @classmethod
    def volume(cls, context):
        return _rigged_volume(context) if cls.rigged else _active_volume(context)

    @_reported
    def execute(self, context):
        return self.run(context, self.volume(context))


class VOLRIG_OT_import_volume(bpy.types.Operator, ImportHelper):
    """Import a volume (NRRD, MetaImage, NIfTI, OpenVDB or raw) as a Volume object for rigging"""
    bl_idname = "volrig.import_volume"
    bl_label = "Import Volume"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default=";".join("*" + e for e in FORMATS), options={"HIDDEN"})
    unit: EnumProperty(name="Units", items=UNIT_SCALES, default="MM")
    custom_scale: FloatProperty(name="Scale", default=1.0, min=1e-9, precision=6,
                                description="Blender units per volume unit (Custom)")
    name: StringProperty(name="Name", default="", description="Object name (default: the file name)")
    grid: StringProperty(name="VDB grid", default="", description="VDB files: grid to read (default density)")
    raw_dims: IntVectorProperty(name="Raw size", size=3, default=(0, 0, 0), min=0,
                                description="Raw files: voxels along x, y, z")
    raw_dtype: EnumProperty(name="Raw type", items=[(t, t, "") for t in (
        "uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64")], default="uint8")
    raw_spacing: FloatVectorProperty(name="Raw spacing", size=3, default=(1.0, 1.0, 1.0), min=1e-9)
    raw_big_endian: bpy.props.BoolProperty(name="Big-endian", default=False)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "name")
        layout.prop(self, "unit")
        if self.unit == "CUSTOM":
            layout.prop(self, "custom_scale")
        layout.prop(self, "grid")
        box = layout.box()
        box.label(text="Raw files (.raw .bin .img)")
        box.prop(self, "raw_dims")
        box.prop(self, "raw_dtype")
        box.prop(self, "raw_spacing")
        box.prop(self, "raw_big_endian")

    @_reported
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"{path}: no such file")
        raw = format_of(path) == "raw" and min(self.raw_dims) > 0
        vol = pipeline.float_samples(pipeline.load_source(
            path, dims=tuple(self.raw_dims) if raw else None, dtype=self.raw_dtype, spacing=tuple(self.raw_spacing),
            big_endian=self.raw_big_endian, grid=self.grid))
        scale = self.custom_scale if self.unit == "CUSTOM" else UNIT_FACTOR[self.unit]
        base = self.name or os.path.basename(path).split(".")[0] or "volume"
        obj = import_samples(context, vol, base, scale, source=path)
        x, y, z = vol.dims
        self.report({"INFO"}, f"volrig: {obj.name}: {x} x {y} x {z} voxels, spacing {tuple(vol.spacing)}; "
                              f"cache {scans.cache_dir(obj)}")
        return {"FINISHED"}


def import_samples(context, vol: volrig.Volume, name: str, unit_scale: float, source: str = ""):
    """Write ``vol`` (float32 samples) into a new cache folder as source.vdb and make its Volume object."""
    key = uuid.uuid4().hex[:8]
    root = scans.cache_root()
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in name)
    rel = os.path.join(root, f"{safe}-{key}")
    folder = bpy.path.abspath(rel)
    os.makedirs(folder, exist_ok=True)
    scans.write_source(folder, vol, source)
    obj = objects.create_volume_object(context, name, os.path.join(rel, "source.vdb"), unit_scale,
                                       vol.grid_to_world())
    s = obj.volrig
    s.source, s.cache_dir = source, rel
    scans.remember_source(obj, vol)
    s.dims, s.spacing, s.origin = vol.dims, vol.spacing, vol.origin
    d = pipeline.import_defaults(vol, unit_scale)
    s.value_min, s.value_max, s.low, s.high = d.value_min, d.value_max, d.low, d.high
    s.preset, s.sampling, s.density_scale = "LABELS" if d.label_map else "SOFT_TISSUE", d.sampling, d.density_scale
    if d.label_map:
        s.segment_by, s.labels = "LABELS", d.labels
    scans.update_mask_count(obj)
    materials.update_volume_material(obj)
    _take_tissue_table(obj, vol, source)
    for o in context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


def _take_tissue_table(obj, vol: volrig.Volume, source: str) -> None:
    """A label map with its tissue table beside the file (``volrig.find_tissue_table``; integer values, at most
    256 of them): segmented as its body codes, per-tissue looks on (nearest sampling), and Automatic rigid tissue
    then binds its bone."""
    some = np.unique(vol.array[:: max(1, vol.array.shape[0] // 32)])
    if not source or len(some) > 256 or not np.array_equal(some, np.round(some)):
        return
    codes = np.unique(vol.array)
    table = volrig.find_tissue_table(source, codes)
    if not table:
        return
    s = obj.volrig
    body = volrig.tissues.body_codes(volrig.read_tissue_table(table), codes)
    s.segment_by, s.labels = "LABELS", pipeline.labels_text(body)
    s.tissue_table = table
    s.use_tissues = True
    scans.update_mask_count(obj)


class VOLRIG_OT_preview_mask(_OnVolume, bpy.types.Operator):
    """Show the segmentation mask over the scan as <name>_mask (updated each time it is pressed)"""
    bl_idname = "volrig.preview_mask"
    bl_label = "Preview Mask"

    def run(self, context, vol):
        mask = scans.mask(vol)
        count = int(np.count_nonzero(mask.array))
        objects.update_mask_preview(vol, mask)
        vol.volrig.mask_count = count
        self.report({"INFO"}, f"volrig: mask of {count:,} voxels shown as {vol.name}_mask")
        return {"FINISHED"}


class VOLRIG_OT_show_thickness(_OnVolume, bpy.types.Operator):
    """Show the segmented object coloured by its local thickness (each voxel: the diameter of the largest ball
    inside the object that contains it) as <name>_thickness"""
    bl_idname = "volrig.show_thickness"
    bl_label = "Show Thickness"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            mask = scans.mask(vol)
            show = bar.steps({"thickness": (0, 100)})
            obj, values = objects.update_thickness(vol, mask, progress=lambda f: show("thickness", f))
        if values.size == 0:
            self.report({"WARNING"}, "volrig: the mask is empty: no thickness to show")
            return {"FINISHED"}
        lo, med, hi = np.percentile(values, [5, 50, 95])
        self.report({"INFO"}, f"volrig: {obj.name}: thickness 5/50/95% {lo:.3g} / {med:.3g} / {hi:.3g} "
                              f"(volume units), blue thin to red thick")
        return {"FINISHED"}


class VOLRIG_OT_medial_surface(_OnVolume, bpy.types.Operator):
    """Show the medial surface of the segmented object's plates as a mesh coloured by thickness (<name>_medial),
    its rods as edges; Plate t sets which plates count"""
    bl_idname = "volrig.medial_surface"
    bl_label = "Medial Surface"

    def run(self, context, vol):
        t = vol.volrig.plane_t
        with _ProgressBar(context) as bar:
            mask = scans.mask(vol)
            show = bar.steps({"medial": (0, 100)})
            ms = volrig.medial_surface(mask, t=t, progress=lambda f: show("medial", f))
        if len(ms.faces) == 0 and not ms.rods:
            self.report({"WARNING"}, f"volrig: no plates or rods found at Plate t = {t:g} voxels (try a smaller t)")
            return {"FINISHED"}
        obj = objects.update_medial_surface(vol, ms)
        med = float(np.median(ms.thickness)) if len(ms.thickness) else 0.0
        self.report({"INFO"}, f"volrig: {obj.name}: {len(ms.faces):,} triangles, area {ms.area:.4g}, median "
                              f"thickness {med:.3g}, {len(ms.rods)} rods (volume units), blue thin to red thick")
        return {"FINISHED"}


class VOLRIG_OT_skeletonize(_OnVolume, bpy.types.Operator):
    """Segment the volume and compute its thinness skeleton once; the Thinness slider then re-thresholds it"""
    bl_idname = "volrig.skeletonize"
    bl_label = "Skeletonize"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            mask = scans.mask(vol)
            sk = scans.skeleton(vol, progress=bar.steps({"skeletonize": (0, 100)}))
        vol.volrig.mask_count = int(np.count_nonzero(mask.array))
        objects.update_skeleton_preview(vol)
        self.report({"INFO"}, f"volrig: {sk.object_count:,} object voxels; {vol.volrig.point_count:,} skeleton points "
                              f"at thinness {vol.volrig.thinness:g}")
        return {"FINISHED"}


#: The Rig button's progress bar: each pipeline step's share.
_RIG_STEPS = {"skeletonize": (0, 30), "skeleton-tree": (30, 55), "autorig": (55, 85), "bind": (85, 100)}


class VOLRIG_OT_rig(_OnVolume, bpy.types.Operator):
    """Build the skeleton-tree, the automatic armature and the binding from the skeleton at the current thinness:
    creates <name>_rig and <name>_spheres"""
    bl_idname = "volrig.rig"
    bl_label = "Rig"

    def run(self, context, vol):
        s = vol.volrig
        with _ProgressBar(context) as bar:
            progress = bar.steps(_RIG_STEPS)
            mask = scans.mask(vol)
            pts = scans.skeleton(vol, progress=progress).at(scans.thinness(vol))
            r = pipeline.rig_skeleton(pts, mask, alpha=s.alpha, bones=s.bones, roles=s.roles, bind_mode=s.bind_mode,
                                      progress=progress, kind=None if s.body_plan == "AUTO" else s.body_plan,
                                      up=objects.scene_up(vol) if s.use_scene_up else None,
                                      own_scale=not s.rig_kept_points, rigid=scans.rigid(vol))
        _save_rig(vol, r.points, r.tree, r.rig, r.binding)
        s.rig_found = pipeline.describe_rig(r.rig)
        rig_obj = objects.build_armature(vol, r.rig)
        objects.build_spheres(vol, rig_obj, r.points, r.tree, r.binding)
        objects.attach_volume(vol, rig_obj)
        preview = objects.members(vol).get("SKELETON")
        if preview is not None:
            preview.hide_set(True)
        looks.refresh(vol)
        self.report({"INFO"}, f"volrig: {s.rig_found}: {len(r.rig)} bones on {len(r.points):,} spheres")
        return {"FINISHED"}


def _save_rig(vol, pts, tree, rig, binding) -> None:
    """Each rig gets a new file (so undo returns to a rig whose file still exists); the objects name it."""
    name = f"rig-{uuid.uuid4().hex[:8]}.vrig"
    volrig.save_rig(os.path.join(scans.cache_dir(vol), name), pts, tree, rig, binding, source="source.vdb")
    vol.volrig.rig_file = name
    vol.volrig.rigid_voxels = 0 if binding.rigid is None else int(np.count_nonzero(binding.rigid))


class VOLRIG_OT_rebind(_OnVolume, bpy.types.Operator):
    """Bind the spheres again to the armature as it is now (after moving, adding or deleting bones in edit mode);
    replaces the vertex groups"""
    bl_idname = "volrig.rebind"
    bl_label = "Rebind"
    modes, rigged = None, True

    def run(self, context, vol):
        parts = objects.members(vol)
        if "SPHERES" not in parts:
            raise volrig.VolrigError(f"{vol.name} has no sphere mesh: press Rig")
        if context.mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")  # edit bones reach the armature on leaving edit mode
        saved = volrig.load_rig(scans.rig_path(vol))
        rig = objects.armature_rig(parts["RIG"])
        mask = scans.mask(vol)
        binding = volrig.bind(saved.points, rig, mask, mode=vol.volrig.bind_mode, rigid=scans.rigid(vol))
        objects.set_vertex_groups(parts["SPHERES"], binding)
        _save_rig(vol, saved.points, saved.tree, rig, binding)
        looks.refresh(vol)
        self.report({"INFO"}, f"volrig: {len(saved.points):,} spheres bound to {len(rig)} bones")
        return {"FINISHED"}


class FrameWork:
    """One frame's volume computed on a worker thread (``Baker.compute``: no Blender data touched); ``stop()``
    makes its progress callback return False, which stops the native computation at its next check (many per
    frame) with volrig.Cancelled."""

    def __init__(self, baker, frame: int, matrices):
        self.fraction = 0.0
        self._stop = threading.Event()
        self._error = None
        self._thread = threading.Thread(target=self._run, args=(baker, frame, matrices), name="volrig-frame",
                                        daemon=True)
        self._thread.start()

    def _progress(self, f) -> bool:
        self.fraction = float(f)
        return not self._stop.is_set()

    def _run(self, baker, frame, matrices):
        try:
            baker.compute(frame, matrices, progress=self._progress)
        except BaseException as e:  # handed to the modal operator on Blender's thread
            self._error = e

    def done(self) -> bool:
        return not self._thread.is_alive()

    def result(self) -> None:
        self._thread.join()
        if self._error is not None:
            raise self._error

    def stop(self) -> bool:
        """Stops the frame and waits for it; True when it was still computing."""
        running = not self.done()
        self._stop.set()
        self._thread.join()
        return running


class VOLRIG_OT_bake(_OnVolume, bpy.types.Operator):
    """Reconstruct each frame of the animated rig into a VDB sequence the Volume object plays (Esc cancels)"""
    bl_idname = "volrig.bake"
    bl_label = "Bake"
    modes = ("OBJECT", "POSE")

    force: bpy.props.BoolProperty(name="All frames", default=False,
                                  description="Bake every frame, also those whose pose did not change")

    _timer = None

    def run(self, context, vol):
        frames = baking.parse_frames(vol.volrig.bake_frames, context.scene)
        n = baking.bake(vol, context.scene, frames, vol.volrig.deform_mode, self.force, report=lambda m: None)
        self.report({"INFO"}, f"volrig: baked {n} of {len(frames)} frames (the others were up to date)")
        return {"FINISHED"}

    @_reported
    def invoke(self, context, event):
        vol = self.volume(context)
        self._frames = baking.parse_frames(vol.volrig.bake_frames, context.scene)
        self._baker = baking.Baker(vol, vol.volrig.deform_mode, frames=len(self._frames))
        self._next = 0
        self._written = 0
        self._rate = pipeline.BakeRate(len(self._frames))
        self._current = context.scene.frame_current
        self._work = None
        wm = context.window_manager
        wm.progress_begin(0, len(self._frames))
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        """Each frame: its pose taken on Blender's thread, its volume computed on a worker (FrameWork), so Esc is
        seen while a frame computes and stops it within a fraction of the frame."""
        if event.type == "ESC":
            inside = self._work is not None and self._work.stop()
            self._finish(context)
            self.report({"WARNING"}, f"volrig: bake cancelled after {self._next} of {len(self._frames)} frames"
                                     + (" (the frame in progress dropped)" if inside else ""))
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            if self._work is not None:
                if not self._work.done():
                    context.window_manager.progress_update(self._next + self._work.fraction)
                    return {"RUNNING_MODAL"}
                self._work.result()  # raises what the frame raised
                self._work = None
                self._written += 1
                return self._frame_done(context)
            frame = self._frames[self._next]
            matrices = self._baker.pose(context.scene, frame, force=self.force)
            if matrices is None:  # up to date
                return self._frame_done(context)
            self._work = FrameWork(self._baker, frame, matrices)
        except USER_ERRORS as e:
            self._finish(context)
            self.report({"ERROR"}, f"volrig: {e}")
            return {"CANCELLED"}
        return {"RUNNING_MODAL"}

    def _frame_done(self, context):
        self._next += 1
        self._rate.tick()
        context.window_manager.progress_update(self._next)
        if context.workspace is not None:  # the bar with frames per second in the status bar
            context.workspace.status_text_set(f"volrig bake: {self._rate.bar()}")
        if self._next < len(self._frames):
            return {"RUNNING_MODAL"}
        self._finish(context)
        self.report({"INFO"}, f"volrig: baked {self._written} of {len(self._frames)} frames, "
                              f"{self._rate.per_second:.2f} frames/s")
        return {"FINISHED"}

    def _finish(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        context.scene.frame_set(self._current)
        try:
            self._baker.finish()  # the last file written; the frames' memory freed
        except USER_ERRORS as e:
            self.report({"ERROR"}, f"volrig: {e}")
        if self._next:
            self._baker.play(context.scene)


#: The prefix of the timeline markers Find Contacts adds (and replaces on the next run).
CONTACT_MARKER = "contact: "


def _to_frame_of(a_obj, b_obj) -> np.ndarray:
    """B's armature space -> A's (both rigid and of one scale, else a clear error): the two volumes' worlds."""
    rel = np.array(a_obj.matrix_world.inverted() @ b_obj.matrix_world)
    r = rel[:3, :3]
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-4):
        raise volrig.VolrigError(f"{a_obj.name} and {b_obj.name} are scaled differently: contacts need both "
                                 "volumes at one scale (apply the scale or import both in the same units)")
    return rel


class VOLRIG_OT_find_contacts(_OnVolume, bpy.types.Operator):
    """Find the frames of the scene range where this rigged volume touches another selected one (or, alone,
    passes through itself): timeline markers at the first frame of each contact, named with the bones"""
    bl_idname = "volrig.find_contacts"
    bl_label = "Find Contacts"
    rigged = True
    modes = ("OBJECT", "POSE")

    min_distance: bpy.props.IntProperty(
        name="Bones apart", default=2, min=1, max=20,
        description="Self-contact: only bones at least this many bones apart in the rig (2: not parent and child); "
                    "bones touching at rest never count")

    def run(self, context, vol):
        scene = context.scene
        others = list({_rigged_volume_of(o) for o in context.selected_objects} - {vol, None})
        if len(others) > 1:
            raise volrig.VolrigError("select at most one other rigged volume (none: self-contact)")
        a = baking.RigState(vol)
        ca = volrig.Collider(a.points, a.binding, parents=a.parents)
        b = cb = None
        if others:
            b = baking.RigState(others[0])
            cb = volrig.Collider(b.points, b.binding, parents=b.parents)
        frames = list(range(scene.frame_start, scene.frame_end + 1))
        current, results = scene.frame_current, []
        mode, keep = vol.volrig.deform_mode, vol.volrig.keep_volume
        with _ProgressBar(context) as bar:
            try:
                for k, f in enumerate(frames):
                    scene.frame_set(f)
                    depsgraph = context.evaluated_depsgraph_get()
                    ma = a.bone_matrices(depsgraph)
                    if b is None:
                        results.append(volrig.self_collide(ca, ma, min_bone_distance=self.min_distance, mode=mode,
                                                           keep_volume=keep))
                    else:  # B's rest (its armature space) -> B posed -> A's armature space, as they stand now
                        to_a = _to_frame_of(a.rig_obj.evaluated_get(depsgraph), b.rig_obj.evaluated_get(depsgraph))
                        mb = to_a @ b.bone_matrices(depsgraph)
                        results.append(volrig.collide(ca, ma, cb, mb, mode=mode, keep_volume=keep))
                    bar.wm.progress_update(100.0 * (k + 1) / len(frames))
            finally:
                scene.frame_set(current)
        contacts = contact_runs(frames, results)
        for m in [m for m in scene.timeline_markers if m.name.startswith(CONTACT_MARKER)]:
            scene.timeline_markers.remove(m)
        for c in contacts:
            scene.timeline_markers.new(CONTACT_MARKER + c.name, frame=c.first)
        what = f"{vol.name} and {others[0].name}" if others else f"{vol.name} with itself"
        spans = "; ".join(f"{c.first}-{c.last} {c.name}" for c in contacts[:4])
        self.report({"INFO"}, f"volrig: {len(contacts)} contact(s) of {what} over frames {frames[0]}-{frames[-1]}"
                              + (f": {spans}" if spans else ""))
        return {"FINISHED"}


class VOLRIG_OT_walk_cycle(_OnVolume, bpy.types.Operator):
    """Keyframe a procedural walk on a humanoid rig (thighs, shins, feet, arms swing about its left-right axis)"""
    bl_idname = "volrig.walk_cycle"
    bl_label = "Add Walk Cycle"
    modes, rigged = ("OBJECT", "POSE"), True

    frame_start: bpy.props.IntProperty(name="Start", default=1)
    frames: bpy.props.IntProperty(name="Frames", default=24, min=1, max=100000)
    period: FloatProperty(name="Stride", default=24.0, min=1.0, description="Frames per stride")
    amplitude: FloatProperty(name="Amplitude", default=1.0, min=0.0, soft_max=2.0, description="Angle scale")

    def run(self, context, vol):
        from mathutils import Quaternion, Vector
        from volrig.walk import walk_cycle
        rig_obj = objects.members(vol)["RIG"]
        axis, angles = walk_cycle(objects.armature_rig(rig_obj), self.frames, self.period, self.amplitude)
        for name, values in angles.items():
            pb = rig_obj.pose.bones[name]
            pb.rotation_mode = "QUATERNION"
            local_axis = pb.bone.matrix_local.to_3x3().transposed() @ Vector(axis)
            for i, angle in enumerate(values):
                pb.rotation_quaternion = Quaternion(local_axis, float(angle))
                pb.keyframe_insert("rotation_quaternion", frame=self.frame_start + i, group=name)
        scene = context.scene
        scene.frame_start, scene.frame_end = self.frame_start, self.frame_start + self.frames - 1
        scene.frame_set(self.frame_start)
        self.report({"INFO"}, f"volrig: walk on {len(angles)} bones over {self.frames} frames")
        return {"FINISHED"}


class VOLRIG_OT_drive_with_bvh(_OnVolume, bpy.types.Operator, ImportHelper):
    """Drive the rig with a motion capture clip (.bvh): retarget it (volrig.animate) and key every pose bone, so
    Bake and render follow. Uses the bone map in the panel when it was made for this clip's joints"""
    bl_idname = "volrig.drive_with_bvh"
    bl_label = "Drive with BVH"
    modes, rigged = ("OBJECT", "POSE"), True

    filename_ext = ".bvh"
    filter_glob: StringProperty(default="*.bvh", options={"HIDDEN"})
    root_motion: EnumProperty(name="Root motion", items=[
        ("in_place", "In place", "The rig walks on the spot (feet still touch the floor)"),
        ("travel", "Travel", "The rig follows the clip's path over the floor, scaled"),
    ], default="in_place")
    up_axis: EnumProperty(name="Clip up axis", items=[("y", "Y", "Y-up clips (most BVH files)"),
                                                      ("z", "Z", "Z-up clips")], default="y")
    first: bpy.props.IntProperty(name="First BVH frame", default=1, min=1)
    last: bpy.props.IntProperty(name="Last BVH frame", default=0, min=0, description="0 = the clip's last frame")
    step: bpy.props.IntProperty(name="Step", default=1, min=1,
                                description="Key every STEP-th clip frame (e.g. 5 plays a 120 fps clip at 24 fps)")
    frame_start: bpy.props.IntProperty(name="Start frame", default=1, description="Scene frame of the first key")

    def run(self, context, vol):
        rig_obj = objects.members(vol)["RIG"]
        path = bpy.path.abspath(self.filepath)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"{path}: no such file")
        motion = volrig.read_bvh(path)
        frames = pipeline.clip_frames(motion.frame_count, f"{self.first}-{self.last or motion.frame_count}",
                                      self.step, anchor=self.first, what=os.path.basename(path))
        rig = objects.armature_rig(rig_obj)
        bone_map = mocap.stored_bone_map(vol, motion)
        if bone_map is None:
            bone_map = volrig.default_bone_map(motion, rig)
            mocap.store_bone_map(vol, motion, bone_map)  # shown (and editable) even if the retarget fails
        _, matrices = pipeline.mocap_poses(rig, motion, frames, bone_map, root_motion=self.root_motion,
                                           up_axis=self.up_axis)
        mocap.key_pose(rig_obj, rig, matrices, self.frame_start + np.arange(len(frames)))
        vol.volrig.bvh_file = path
        scene = context.scene
        scene.frame_start, scene.frame_end = self.frame_start, self.frame_start + len(frames) - 1
        fps = motion.fps / self.step
        scene.render.fps = max(1, round(fps))
        scene.render.fps_base = scene.render.fps / fps
        scene.frame_set(self.frame_start)
        self.report({"INFO"}, f"volrig: {len(frames)} frames of {os.path.basename(path)} keyed on "
                              f"{len(bone_map)} mapped bones of {len(rig)}, {fps:.4g} fps")
        return {"FINISHED"}


class VOLRIG_OT_reset_bone_map(_OnVolume, bpy.types.Operator):
    """Fill the bone map again from the names of the last clip's joints and the rig's bones"""
    bl_idname = "volrig.reset_bone_map"
    bl_label = "Map by Names"
    modes, rigged = None, True

    @classmethod
    def poll(cls, context):
        return super().poll(context) and bool(cls.volume(context).volrig.bvh_file)

    def run(self, context, vol):
        motion = volrig.read_bvh(bpy.path.abspath(vol.volrig.bvh_file))
        bone_map = volrig.default_bone_map(motion, objects.armature_rig(objects.members(vol)["RIG"]))
        mocap.store_bone_map(vol, motion, bone_map)
        self.report({"INFO"}, f"volrig: {len(bone_map)} of {len(motion.names)} joints mapped by name")
        return {"FINISHED"}


class VOLRIG_OT_thickness(_OnVolume, bpy.types.Operator):
    """Give every bone of the rig a keyframable Thickness (1 = as scanned): the bake thickens the volume around a
    bone by it"""
    bl_idname = "volrig.thickness"
    bl_label = "Thickness per Bone"
    modes, rigged = None, True

    def run(self, context, vol):
        for pb in objects.members(vol)["RIG"].pose.bones:
            objects.thickness_property(pb)
        self.report({"INFO"}, "volrig: select a bone in pose mode to set (and key) its thickness; Bake applies it")
        return {"FINISHED"}


class VOLRIG_OT_show_rest(_OnVolume, bpy.types.Operator):
    """Show the imported volume again (with its parts once rigged) instead of the baked sequence"""
    bl_idname = "volrig.show_rest"
    bl_label = "Show Source"
    modes = None

    def run(self, context, vol):
        objects.point_volume_at(vol, looks.shown_at_rest(vol))
        return {"FINISHED"}


def _centerline_progress(bar):
    """The centerline's progress on the first 80 % of the bar."""
    show = bar.steps({"centerline": (0, 80)})
    return lambda f: show("centerline", f)


class VOLRIG_OT_fly_through(_OnVolume, bpy.types.Operator):
    """Fly a camera along the volume's centerline: a Bezier curve on it, a camera keyed along it looking down the
    averaged tangent, a headlight riding with it, the lumen's wall shown from inside, and the scene's frame range"""
    bl_idname = "volrig.fly_through"
    bl_label = "Fly Through"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            made = flythrough.fly_through(context, vol, progress=_centerline_progress(bar))
        scene = context.scene
        self.report({"INFO"}, f"volrig: fly-through of {made['line'].length:.1f} units in {len(made['flight'])} "
                              f"frames ({scene.frame_start} .. {scene.frame_end}) by {made['camera'].name}")
        return {"FINISHED"}


class VOLRIG_OT_straighten(_OnVolume, bpy.types.Operator):
    """Resample the volume on the planes normal to its centerline (curved planar reformation) and add the straight
    volume as <name>_straight beside it"""
    bl_idname = "volrig.straighten"
    bl_label = "Straighten"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            obj, line = flythrough.straighten(context, vol, import_samples, progress=_centerline_progress(bar))
        x, y, z = obj.volrig.dims
        self.report({"INFO"}, f"volrig: {obj.name}: {x} x {y} x {z} voxels along {line.length:.1f} units of "
                              f"centerline")
        return {"FINISHED"}


class VOLRIG_OT_straightening_rig(_OnVolume, bpy.types.Operator):
    """Rig the volume with a chain of bones along its centerline and key it from curved to straight (Bake then
    straightens the organ); replaces the volume's rig"""
    bl_idname = "volrig.straightening_rig"
    bl_label = "Animate Straightening"

    def run(self, context, vol):
        with _ProgressBar(context) as bar:
            sr, rig_obj = flythrough.straightening_animation(context, vol, _save_rig,
                                                             progress=_centerline_progress(bar))
        scene = context.scene
        self.report({"INFO"}, f"volrig: {rig_obj.name}: {len(sr.rig)} bones keyed straight over frames "
                              f"{scene.frame_start} .. {scene.frame_end}; press Bake")
        return {"FINISHED"}


def menu_import(self, context):
    self.layout.operator(VOLRIG_OT_import_volume.bl_idname, text="Volume for rigging (volrig)")


CLASSES = (VOLRIG_OT_import_volume, VOLRIG_OT_preview_mask, VOLRIG_OT_show_thickness,
           VOLRIG_OT_medial_surface, VOLRIG_OT_skeletonize, VOLRIG_OT_rig, VOLRIG_OT_rebind,
           VOLRIG_OT_bake, VOLRIG_OT_find_contacts, VOLRIG_OT_walk_cycle, VOLRIG_OT_drive_with_bvh,
           VOLRIG_OT_reset_bone_map, VOLRIG_OT_thickness, VOLRIG_OT_show_rest, VOLRIG_OT_fly_through, VOLRIG_OT_straighten,
           VOLRIG_OT_straightening_rig)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)

"""Baking: each frame of the evaluated rig reconstructs the volume (volrig.Deformer) into
``<cache>/frames/<name>_<frame>.vdb`` (grids ``density``, ``bone`` and each part's ``density_<key>`` and
``mask_<key>``: looks.py), and the Volume object plays them. The object's *Explode* factor (animatable) takes each
frame's pose apart (``volrig.explode_matrices``).

The weights come from the sphere mesh's vertex groups as they are now (weight painting counts); the points and the
source from the cache. Bone matrices are rest-to-pose in armature space (= volume units): pose_bone.matrix @
bone.matrix_local^-1. A frame is re-baked only when its pose, weights or rig changed (``frames/poses.json``).
Every frame is independent, so a range can be split across machines once the .blend is saved.

The Bake operator (modal: each frame's volume computed on a worker thread, ``FrameWork``; Esc cancels), Show Source
and the Bake panel (which also holds Find Contacts: collide.py) are here too.
"""
import json
import os
import re
import sys
import threading

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty

import volrig
from volrig import pipeline
from volrig.deform import MODE_INFO, SAMPLING_INFO

from . import looks, objects, scans
from .ops_base import USER_ERRORS, _OnVolume, _reported, _labelled, _settings, _VolrigPanel
from .state import THICKNESS, RigState, parts_of, substitutes_of, tissues_of  # noqa: F401  (bake.THICKNESS, bake.RigState as before)


#: > 0 while a bake sets frames (the live preview skips those frame changes)
posing = 0


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

def _menu(info):
    """EnumProperty items from volrig's {name: (label, description)} (volrig.deform.MODE_INFO, SAMPLING_INFO)."""
    return [(name, label, description) for name, (label, description) in info.items()]


class BakeSettings:
    """How frames are deformed and sampled, and which were baked."""
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


def frames_dir(volume_obj) -> str:
    return os.path.join(scans.cache_dir(volume_obj), "frames")


def _stem(volume_obj) -> str:
    """The sequence's file stem: the object's name without what Blender would read as a frame number."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", volume_obj.name).rstrip("0123456789.") or "volume"


def frame_path(volume_obj, frame: int) -> str:
    """The VDB file of a scene frame; numbered by scene frame so the Volume object's sequence finds it."""
    return pipeline.frame_file(frames_dir(volume_obj), _stem(volume_obj), frame)


def parse_frames(text: str, scene=None):
    """'1-48', '5', '1-10,20-30' -> sorted frame list; empty text = the scene's frame range."""
    return pipeline.parse_frames(text, None if scene is None else (scene.frame_start, scene.frame_end))


class Baker(RigState):
    """Everything one bake of a volrig Volume object needs, prepared once (``volrig.pipeline.FolderBake``: the
    Deformer and the record of baked poses). ``frames``: how many frames the bake will draw, when known."""

    def __init__(self, volume_obj, mode: str = "linear", frames=None):
        super().__init__(volume_obj)
        self.folder = pipeline.FolderBake(scans.source(volume_obj), self.points, self.binding,
                                          frames_dir(volume_obj), _stem(volume_obj), mode=mode,
                                          sampling=volume_obj.volrig.sampling, track=True,
                                          setup=os.path.basename(self.path), parts=parts_of(volume_obj),
                                          rig=objects.armature_rig(self.rig_obj),
                                          tissues=tissues_of(volume_obj),
                                          substitutes=substitutes_of(volume_obj),
                                          keep_volume=volume_obj.volrig.keep_volume,
                                          lattice_tables=volume_obj.volrig.lattice_tables,
                                          frames=frames)  # (how many: whether the lattice tables pay)
        self._thickness = {}  # frame -> the thickness factors pose() read for it

    def bake_frame(self, scene, frame: int, progress=None, force: bool = False) -> bool:
        """Reconstruct scene frame ``frame`` into its VDB file (written while the next frame computes: ``finish``
        waits for it); False when the file was up to date."""
        matrices = self.pose(scene, frame, force)
        if matrices is None:
            return False
        self.compute(frame, matrices, progress)
        return True

    def pose(self, scene, frame: int, force: bool = False):
        """The (B, 4, 4) bone matrices of scene frame ``frame`` (Blender's side of a frame: the main thread only),
        or None when its file is up to date."""
        global posing
        posing += 1  # the live preview stays out of a bake's frame changes
        try:
            scene.frame_set(frame)
        finally:
            posing -= 1
        depsgraph = bpy.context.evaluated_depsgraph_get()
        matrices = self.bone_matrices(depsgraph)
        explode = self.volume_obj.volrig.explode  # (frame_set writes the animated value back to the object)
        if explode:  # the animated pose taken apart (volrig.explode_matrices)
            matrices = volrig.explode_matrices(self.rig, explode, matrices)
        self._thickness[frame] = self.thickness(depsgraph)
        if not force and self.folder.up_to_date(frame, matrices, self._thickness[frame]):
            return None
        return matrices

    def compute(self, frame: int, matrices, progress=None) -> None:
        """volrig's side of a frame: reconstructs the pose into its file; touches no Blender data, so it may run on
        a worker thread while Blender's stays responsive. ``progress(fraction)`` is called many times within the
        frame; returning False stops it there (``volrig.Cancelled``) and writes nothing for it."""
        self.folder.bake(frame, matrices, progress=progress, thickness=self._thickness.get(frame))

    def finish(self) -> None:
        """Waits for the last frame's file (bake_frame returns while it is written) and frees the frames' memory;
        a failed write raises here."""
        self.folder.finish()

    def play(self, scene) -> None:
        """Point the Volume object at the frame sequence over the scene's frame range."""
        s = self.volume_obj.volrig
        s.baked_start, s.baked_end = scene.frame_start, scene.frame_end
        first = frame_path(self.volume_obj, scene.frame_start)
        objects.point_volume_at(self.volume_obj, bpy.path.relpath(first) if bpy.data.filepath else first,
                                (scene.frame_start, scene.frame_end))


def bake(volume_obj, scene, frames, mode: str = "linear", force: bool = False, report=print) -> int:
    """Bake ``frames`` of ``volume_obj`` (blocking; the headless path); returns the number of frames written."""
    baker = Baker(volume_obj, mode, frames=len(frames))
    current = scene.frame_current
    written = 0
    rate = pipeline.BakeRate(len(frames))
    try:
        for frame in frames:
            if baker.bake_frame(scene, frame, force=force):
                written += 1
            rate.tick()
            report(f"volrig: {volume_obj.name} frame {frame} {rate.bar()}")
    finally:
        scene.frame_set(current)
        baker.finish()
    baker.play(scene)
    return written


def bake_saved_scene(frames_text: str = "", names=(), mode: str = "", force: bool = False, save: bool = True) -> int:
    """Headless entry (``python -m volrig bake scene.blend``): bake the named volrig Volume objects (all when
    ``names`` is empty) of the open .blend over ``frames_text`` (default: the scene range), then save the .blend so
    ``blender -b scene.blend -a`` renders the sequence."""
    scene = bpy.context.scene
    frames = parse_frames(frames_text, scene)
    targets = [o for o in bpy.data.objects if o.volrig.role == "VOLUME" and (not names or o.name in names)]
    missing = set(names) - {o.name for o in targets}
    if missing:
        raise volrig.VolrigError(f"no volrig volume named {', '.join(sorted(missing))} in {bpy.data.filepath}")
    if not targets:
        raise volrig.VolrigError(f"{bpy.data.filepath} holds no volrig volume")
    total = 0
    for obj in targets:
        total += bake(obj, scene, frames, mode or obj.volrig.deform_mode, force)
    if save and bpy.data.filepath:
        bpy.ops.wm.save_mainfile()
    return total


def exit_with(work) -> None:
    """The Blender side of a headless volrig command: runs ``work(args)`` with the JSON after ``--`` on Blender's
    command line and prints the line it returns, then exits Blender with 0, or 2 and a message for a user error (a
    bug gives a traceback and 1 through ``--python-exit-code``)."""
    args = json.loads(sys.argv[sys.argv.index("--") + 1])
    try:
        print(work(args))
        code = 0
    except (volrig.VolrigError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        code = 2
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def command_line() -> None:
    """The Blender side of ``python -m volrig bake``: bakes the open .blend as the JSON after ``--`` says."""
    def work(args):
        n = bake_saved_scene(args["frames"], args["objects"], args["mode"], args["force"], args["save"])
        return f"volrig: baked {n} frame(s) of {os.path.basename(bpy.data.filepath)}"
    exit_with(work)


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
        frames = parse_frames(vol.volrig.bake_frames, context.scene)
        n = bake(vol, context.scene, frames, vol.volrig.deform_mode, self.force, report=lambda m: None)
        self.report({"INFO"}, f"volrig: baked {n} of {len(frames)} frames (the others were up to date)")
        return {"FINISHED"}

    @_reported
    def invoke(self, context, event):
        vol = self.volume(context)
        self._frames = parse_frames(vol.volrig.bake_frames, context.scene)
        self._baker = Baker(vol, vol.volrig.deform_mode, frames=len(self._frames))
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


class VOLRIG_OT_show_rest(_OnVolume, bpy.types.Operator):
    """Show the imported volume again (with its parts once rigged) instead of the baked sequence"""
    bl_idname = "volrig.show_rest"
    bl_label = "Show Source"
    modes = None

    def run(self, context, vol):
        objects.point_volume_at(vol, looks.shown_at_rest(vol))
        return {"FINISHED"}


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


CLASSES = (VOLRIG_OT_bake, VOLRIG_OT_show_rest, VOLRIG_PT_bake)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

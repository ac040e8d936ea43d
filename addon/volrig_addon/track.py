"""Import Tracked Series: a time series' features tracked by their skeletons (``volrig.track``) become a volume
sequence coloured by track, one colour per track that it keeps while it lives, with the events (splits, merges,
creations, dissipations) as timeline markers.

Step k of the series plays at scene frame k + 1. Each step is written into the object's cache folder as
``tracks_<frame>.vdb``: a ``density`` grid holding each voxel's track colour number (1..31; track ids 31 apart
share a colour), rendered with the label look (a constant colour per number, only whole numbers opaque) through the
object's own palette. The tracking graph goes beside them as ``tracks.json`` (``volrig track``'s JSON).
"""
import colorsys
import json
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, IntProperty
from bpy_extras.io_utils import ImportHelper

import volrig
from volrig.files import atomic_output
from volrig.track import EVENT_KINDS
from volrig.volume import FORMATS

from . import materials, objects, scans
from .drawing import whole_labels_only
from .ops_base import _ProgressBar, _reported
from .volume import import_samples

#: Colours a series cycles through, one per track (track id t has colour number (t - 1) % COLOURS + 1).
COLOURS = 31


def track_palette(n: int = COLOURS) -> np.ndarray:
    """``n`` distinct colours (linear RGB), neighbours far apart in hue: the golden-angle walk around the hue circle,
    alternating two lightnesses, so tracks born one after the other differ at a glance."""
    hues = (np.arange(n) * 0.381966) % 1.0
    rgb = [colorsys.hls_to_rgb(h, 0.5 if k % 2 == 0 else 0.65, 0.85) for k, h in enumerate(hues)]
    srgb = np.array(rgb)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def colour_numbers(tr: "volrig.Tracking", step: int) -> np.ndarray:
    """float32 [z, y, x]: each feature voxel its track's colour number (1..COLOURS), 0 elsewhere."""
    ids = tr.track_volume(step)
    return np.where(ids > 0, (ids - 1) % COLOURS + 1, 0).astype(np.float32)


def marker_name(e: "volrig.Event") -> str:
    return f"{e.kind} {list(e.before)}->{list(e.after)}"


def add_markers(scene, tr: "volrig.Tracking") -> int:
    """A timeline marker for every event that is not a continuation, at the frame its new state shows (the later
    step's); volrig's earlier markers of a tracked series (named by kind) are replaced. Returns how many."""
    kinds = tuple(k for k in EVENT_KINDS if k != "continuation")
    for m in [m for m in scene.timeline_markers if m.name.split(" ")[0] in kinds]:
        scene.timeline_markers.remove(m)
    events = [e for e in tr.events if e.kind != "continuation"]
    for e in events:
        scene.timeline_markers.new(marker_name(e), frame=e.step + 2)
    return len(events)


def frame_timelines(context) -> None:
    """Fits the open timelines and dope sheets to the scene's range, so the events' markers show (no windows in
    background mode: nothing to do)."""
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            region = next((r for r in area.regions if r.type == "WINDOW"), None)
            if area.type == "DOPESHEET_EDITOR" and region is not None:
                with context.temp_override(window=window, area=area, region=region):
                    bpy.ops.action.view_all()


def write_sequence(folder: str, tr: "volrig.Tracking", progress=None) -> None:
    """Each step as ``folder/tracks_<frame>.vdb`` (frame = step + 1) and the graph as ``folder/tracks.json``."""
    for s in range(tr.steps):
        vol = volrig.Volume(colour_numbers(tr, s), tr.spacing, tr.origin)
        volrig.write_vdb(os.path.join(folder, f"tracks_{s + 1:04d}.vdb"), {"density": vol}, half=False)
        if progress:
            progress((s + 1) / tr.steps)
    with atomic_output(os.path.join(folder, "tracks.json")) as tmp, open(tmp, "w") as f:
        json.dump(tr.to_dict(), f, indent=1)


def series_object(context, tr: "volrig.Tracking", name: str, size: float, source: str):
    """The Volume object playing the tracked series, ``size`` Blender units along its longest side."""
    first = volrig.Volume(colour_numbers(tr, 0), tr.spacing, tr.origin)
    extent = max(d * s for d, s in zip(first.dims, first.spacing))
    obj = import_samples(context, first, name, size / extent, source=source)
    s = obj.volrig
    s.segment_by, s.labels, s.preset, s.sampling = "LABELS", f"1-{COLOURS}", "LABELS", "nearest"
    s.value_min, s.value_max = 0.0, float(COLOURS)
    obj["volrig_palette"] = [float(c) for c in track_palette().ravel()]
    whole_labels_only(materials.update_volume_material(obj))
    return obj


class VOLRIG_OT_import_tracks(bpy.types.Operator, ImportHelper):
    """Import a time series (pick any one of its files: every volume file of its folder is a step, in name
    order), track its features by their skeletons and play it coloured by track, the events as timeline markers"""
    bl_idname = "volrig.import_tracks"
    bl_label = "Import Tracked Series"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: bpy.props.StringProperty(default=";".join("*" + e for e in FORMATS if e.startswith(".")),
                                          options={"HIDDEN"})
    lo: FloatProperty(name="Low", default=0.5, description="A feature's voxels are at least this value")
    use_hi: BoolProperty(name="Upper limit", default=False)
    hi: FloatProperty(name="High", default=1.0, description="... and at most this value (with Upper limit)")
    thinness: FloatProperty(name="Thinness", default=1.0, min=0.0, max=4.08,
                            description="Skeleton thinness the features are matched by (<3,4,5> chamfer units, as "
                                        "the thesis' Table 9.1); 0 matches whole features")
    min_size: IntProperty(name="Smallest feature", default=20, min=1, description="Voxels")
    size: FloatProperty(name="Size", default=2.0, min=1e-6, description="The series' longest side in Blender units")
    markers: BoolProperty(name="Event markers", default=True,
                          description="Splits, merges, creations and dissipations as timeline markers")

    @_reported
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        folder = path if os.path.isdir(path) else os.path.dirname(path)
        if not os.path.isdir(folder):
            raise FileNotFoundError(f"{path}: no such file or folder")
        with _ProgressBar(context) as bar:
            tr = volrig.track(folder, lo=self.lo, hi=self.hi if self.use_hi else None, thinness=self.thinness,
                              min_size=self.min_size, progress=lambda f: bar.wm.progress_update(80 * f) or True)
            name = os.path.basename(os.path.normpath(folder)) or "series"
            obj = series_object(context, tr, name, self.size, folder)
            cache = scans.cache_dir(obj)
            write_sequence(cache, tr, lambda f: bar.wm.progress_update(80 + 20 * f))
        objects.point_volume_at(obj, os.path.join(obj.volrig.cache_dir, "tracks_0001.vdb"), (1, tr.steps))
        scene = context.scene
        scene.frame_start, scene.frame_end = 1, tr.steps
        n = add_markers(scene, tr) if self.markers else 0
        frame_timelines(context)
        self.report({"INFO"}, f"volrig: {obj.name}: {tr.steps} steps, {tr.track_count} tracks, {n} events marked")
        return {"FINISHED"}


def menu_import(self, context):
    self.layout.operator(VOLRIG_OT_import_tracks.bl_idname, text="Time series, tracked (volrig)")


def register():
    bpy.utils.register_class(VOLRIG_OT_import_tracks)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(VOLRIG_OT_import_tracks)

"""volrig for Blender: import a volume, skeletonize it, rig it automatically, animate the armature and bake the
deformed volume into a VDB sequence that Cycles renders (or EEVEE, where this Blender's Cycles renders no grids).

The add-on is a thin layer over the ``volrig`` Python package: it finds the package bundled beside it (the add-on
zip carries ``volrig/`` with its compiled module in ``lib/``) or, in a checkout, in ``../../python``.
"""
bl_info = {
    "name": "volrig",
    "author": "volrig authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D View > Sidebar > volrig",
    "description": "Skeletonize, rig, animate and render volumes (CT, MRI, label maps, VDB)",
    "warning": "Tested with Blender 3.4, 4.3 and 5.2",
    "doc_url": "",
    "category": "Animation",
}

import os
import sys

#: Blender versions the add-on supports: 3.4 up to (not including) 6.0.
SUPPORTED = ((3, 4, 0), (6, 0, 0))


def _find_volrig() -> None:
    here = os.path.dirname(os.path.abspath(__file__))
    for folder in (os.path.join(here, "lib"), os.path.normpath(os.path.join(here, "..", "..", "python"))):
        if os.path.isdir(os.path.join(folder, "volrig")):
            if folder not in sys.path:
                sys.path.insert(0, folder)
            return


_find_volrig()

if "bpy" in locals():  # reloading (F3 > Reload Scripts)
    import importlib
    # properties last: its VolrigObject joins the feature modules' settings classes.
    for _m in ("compat", "engines", "scans", "state", "materials", "objects", "looks", "tissue_looks", "ops_base",
               "staging", "volume", "medial", "skeleton", "markers", "rig", "mocap", "looks_ui", "bake",
               "flythrough", "collide", "drawing", "track", "preview", "mesh_rig", "properties"):
        if _m in locals():
            importlib.reload(locals()[_m])

import bpy  # noqa: E402

from . import compat, engines, materials, objects, properties, scans, staging  # noqa: E402,F401
from . import looks, ops_base, state, tissue_looks  # noqa: E402,F401
# One module per feature, each with its operators and panel; registered in this order, which is the sidebar's
# order of their panels (Volume, Segment, Skeleton, Rig, Motion capture, Look, Centerline, Bake, then Mesh).
from . import (bake, collide, drawing, flythrough, looks_ui, markers, medial, mesh_rig, mocap, preview,  # noqa: E402
               rig, skeleton, track, volume)

FEATURES = (volume, medial, skeleton, markers, rig, mocap, looks_ui, flythrough, bake, collide, drawing, track, preview,
            mesh_rig)

#: The volrig tab's top panels in the sidebar's order (the Mesh panel, mesh_rig.py, polls on meshes and comes last).
PANELS = (volume.VOLRIG_PT_volume, volume.VOLRIG_PT_segment, skeleton.VOLRIG_PT_skeleton, rig.VOLRIG_PT_rig,
          mocap.VOLRIG_PT_mocap, looks_ui.VOLRIG_PT_look, flythrough.VOLRIG_PT_centerline, bake.VOLRIG_PT_bake)


def register():
    if not (SUPPORTED[0] <= tuple(bpy.app.version) < SUPPORTED[1]):
        print(f"volrig: Blender {bpy.app.version_string} is outside the supported range 3.4 .. 5.x")
    properties.register()
    for feature in FEATURES:
        feature.register()
    bpy.app.handlers.load_post.append(scans.forget_all)
    if not bpy.app.background:  # the Look panel's word on Cycles and grids, probed once the UI is up
        bpy.app.timers.register(_probe_engines, first_interval=1.0)


def _probe_engines():
    if not engines.cycles_renders_grids():
        engines.tell()
    return None  # once


def unregister():
    for timer in (_probe_engines, engines._clear_status):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    if scans.forget_all in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(scans.forget_all)
    scans.forget_all()
    for feature in reversed(FEATURES):
        feature.unregister()
    properties.unregister()

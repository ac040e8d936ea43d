"""Per-part looks: the rig's parts (``volrig.bone_parts``: left arm, spine, head, ... or one per chain) listed on
the Volume object (``volrig.parts``), each visible or hidden, in its own colour and opacity, in Cycles.

Every baked frame, and the rest volume (``<rig file>_parts.vdb`` in the cache, written when the rig is bound),
holds per part ``density_<key>`` (the values on the part's voxels) and ``mask_<key>`` (1 on them); the rest volume
also ``density_outside`` (the voxels in no part). The material:

- value   = the sum of the visible parts' density_<part> and density_outside: the density of the volume whose
            hidden voxels are empty, so no shell of a hidden part is left (a hidden part's grid is not read at
            all: Cycles' volume lookups may pick one neighbour at random, so even density - density_<part>
            would leave speckles at the part's surface);
- opacity = the transfer function's, times (1 + sum_p mask_p (opacity_p visible_p - 1)) / (1 - sum_hidden mask_p):
            each part's opacity weighted by its mask, hidden parts' weight left out;
- colour  = the transfer function's, mixed towards a coloured part's colour by its mask: non-zero only within a
            voxel of the part's voxels, so the colour never reaches a neighbour beyond the shared voxel band.
Frames baked before the parts were found have no part grids: they render empty until baked again (the bake
re-bakes them: the parts are part of what a frame's file depends on).
"""
import os

import bpy

import volrig
from volrig import pipeline

from . import materials, objects, scans
from .materials import route  # noqa: F401  (looks.route as before)
from .state import (RigState, parts_of, substitutes_of, tissues_of, tissues_rest_file,  # noqa: F401
                    write_tissues_rest)

#: Colours offered to new parts (a part keeps its settings when the parts are found again).
PART_COLORS = [(0.9, 0.15, 0.1), (0.2, 0.55, 0.95), (0.95, 0.8, 0.2), (0.3, 0.8, 0.35), (0.7, 0.4, 0.9),
               (0.95, 0.5, 0.15), (0.3, 0.85, 0.8), (0.9, 0.4, 0.65)]


def rest_file(volume_obj) -> str:
    """The rest volume with its part grids: ``<rig file>_parts.vdb`` beside the rig file (one per rig, so undo
    never points at a file that is gone)."""
    return os.path.splitext(scans.rig_path(volume_obj))[0] + "_parts.vdb"


def shown_at_rest(volume_obj) -> str:
    """The file the Volume object shows when not playing a bake: the rest volume with parts (per-part looks on,
    with the tissue grids too when per-tissue looks are on), else the rest volume with tissues, else the source."""
    s = volume_obj.volrig
    if s.use_parts and s.rig_file and os.path.exists(rest_file(volume_obj)):
        return rest_file(volume_obj)
    if s.use_tissues and os.path.exists(tissues_rest_file(volume_obj)):
        return tissues_rest_file(volume_obj)
    return scans.source_path(volume_obj)


def write_rest(volume_obj) -> None:
    """The rest volume's looks files: with per-part looks on (and a rig), the parts' grids and the tissues' (if on);
    with per-tissue looks on, also the tissues' alone (shown once per-part looks are turned off)."""
    s = volume_obj.volrig
    if s.use_parts and "RIG" in objects.members(volume_obj):
        state = RigState(volume_obj)
        pipeline.write_rest_looks(rest_file(volume_obj), scans.source(volume_obj), state.points, state.binding,
                                  parts_of(volume_obj), scans.mask(volume_obj),
                                  tissues=tissues_of(volume_obj),
                                  substitutes=substitutes_of(volume_obj))
    if s.use_tissues:
        write_tissues_rest(volume_obj)


def tell(message: str) -> None:
    """A message in a popup where there is a window (a property's update cannot report), and on the console."""
    print(message)
    wm = bpy.context.window_manager
    if not bpy.app.background and wm is not None and wm.windows:
        wm.popup_menu(lambda menu, _c: menu.layout.label(text=message), title="volrig", icon="ERROR")


def substitute_changed(volume_obj) -> None:
    """A part's substitute file changed: the rest volume is written again (the bake follows: the substitutes are part
    of what a frame depends on); a file that cannot be read is reported (and again by the bake)."""
    if volume_obj.volrig.use_parts and "RIG" in objects.members(volume_obj):
        try:
            write_rest(volume_obj)
        except volrig.VolrigError as e:
            tell(f"volrig: {e}")
            return
        if not volume_obj.data.is_sequence:
            objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))


def parts_toggled(volume_obj) -> None:
    """Per-part looks turned on (the parts found, the rest volume with their grids written and shown) or off (the
    source shown again), unless a bake is playing; the material follows."""
    if volume_obj.volrig.use_parts and "RIG" in objects.members(volume_obj):
        refresh(volume_obj)
        return
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)


def refresh(volume_obj) -> int:
    """Finds the rig's parts (keeping the settings of parts already listed by name); with per-part looks on,
    writes the rest volume with their grids and shows it unless a bake is playing; returns the number of parts."""
    state = RigState(volume_obj)
    s = volume_obj.volrig
    kept = {p.name: (p.visible, p.colored, tuple(p.color), p.opacity) for p in s.parts}
    s.parts.clear()
    for k, part in enumerate(volrig.bone_parts(state.names, state.parents)):
        item = s.parts.add()
        item.name, item.key = part.name, part.key
        item.bones = ",".join(state.names[b] for b in part.bones)
        item.visible, item.colored, item.color, item.opacity = kept.get(
            part.name, (True, False, PART_COLORS[k % len(PART_COLORS)], 1.0))
    s.parts_index = min(s.parts_index, max(len(s.parts) - 1, 0))
    if s.use_parts:
        write_rest(volume_obj)
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)
    return len(s.parts)

"""Per-tissue looks for label maps: the scan's tissue classes (``volrig.tissue_classes`` of a table of codes and
names; the classes a baked frame's metadata names when a frame is imported; one class per label without either)
listed on the Volume object (``volrig.tissues``), each visible or hidden, in its own colour and opacity.

The rest volume (``tissues.vdb`` in the cache, or the parts' rest file when per-part looks are on too) and every
baked frame hold one label grid of class indices (``tissue``: the list's k-th class is k + 1); the material sums the
visible classes' opacity and colour over per-class indicators of it (``materials.tissue_sums``), so an interpolated
boundary mixes its two real neighbours (and, between classes of distant index, for a fraction of a voxel the classes
of opacity between theirs), and a hidden class adds nothing. Label maps bake with nearest sampling (turning the
looks on sets it; a bake with trilinear sampling and tissue looks is refused).
"""

import bpy
import numpy as np

import volrig

from . import looks, materials, objects, scans
from .state import tissues_of  # noqa: F401  (tissue_looks.tissues_of as before)
from .state import tissues_rest_file as rest_file  # noqa: F401
from .state import write_tissues_rest as write_rest  # noqa: F401


def classes(volume_obj):
    """The source's tissue classes from the object's table (all codes present), else those its imported file's
    metadata names (a frame baked with tissue looks), else one per label."""
    codes = np.unique(scans.source(volume_obj).array)
    table = bpy.path.abspath(volume_obj.volrig.tissue_table)
    if not volume_obj.volrig.tissue_table:
        baked = volrig.tissues.file_classes(bpy.path.abspath(volume_obj.volrig.source))
        if baked:
            return baked
        if len(codes) > 256 or np.any(codes != np.round(codes)):
            raise volrig.VolrigError(f"{volume_obj.name} is not a label map ({len(codes)} distinct values, "
                                     f"{'not all integers' if np.any(codes != np.round(codes)) else 'too many'}): "
                                     f"per-tissue looks need integer tissue codes")
        return volrig.label_classes(codes)
    return volrig.tissue_classes(volrig.read_tissue_table(table), present=codes)


def toggled(volume_obj) -> None:
    """Per-tissue looks turned on (the classes found, the rest file written and shown, nearest sampling) or off
    (the rest volume without them shown again); the material follows."""
    if volume_obj.volrig.use_tissues:
        volume_obj.volrig.sampling = "nearest"
        try:
            refresh(volume_obj)
            return
        except (volrig.VolrigError, OSError) as e:  # not a label map, a bad table: say so, turn the looks off
            looks.tell(f"volrig: per-tissue looks: {e}")
            volume_obj.volrig.use_tissues = False  # runs this again, with the looks off
            return
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, looks.shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)


def refresh(volume_obj) -> int:
    """Finds the tissue classes (keeping the looks of classes already listed by name), writes the rest volume with
    their grids and shows it unless a bake is playing; returns the number of classes."""
    s = volume_obj.volrig
    found = classes(volume_obj)
    kept = {t.name: (t.visible, tuple(t.color), t.opacity) for t in s.tissues}
    s.tissues.clear()
    for t in found:
        item = s.tissues.add()
        item.name, item.key, item.codes = t.name, t.key, ",".join(str(c) for c in t.codes)
        item.visible, item.color, item.opacity = kept.get(t.name, (t.visible, t.color, t.opacity))
    s.tissues_index = min(s.tissues_index, max(len(s.tissues) - 1, 0))
    looks.write_rest(volume_obj)
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, looks.shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)
    return len(s.tissues)

"""Thickness, medial surface and pore network of the segmented object: Show Thickness (local thickness, ``volrig``
thickness), Medial Surface (``volrig.medial_surface``) and Pore Network (``volrig.pore_network``: the segmentation
is the pore space); their buttons are on the Segment panel (volume.py)."""
import bpy
import numpy as np
from bpy.props import FloatProperty

import volrig

from . import objects, scans
from .ops_base import _OnVolume, _ProgressBar


# ---- What this feature stores: its part of Object.volrig (properties.VolrigObject joins the parts) ------------------

class MedialSettings:
    """Which plates get a medial surface."""
    plane_t: FloatProperty(name="Plate t", default=5.0, min=1.0, soft_max=30.0, precision=1,
                           description="Plane-like threshold of Medial Surface, in voxels: plates whose sides lie "
                                       "more than t apart around their rim get a medial surface (larger: only the "
                                       "larger plates; at least 5 against noise)")


def _on_mask(context, vol, compute):
    """``compute(mask, progress)`` on the volume's segmentation, with the window manager's progress bar."""
    with _ProgressBar(context) as bar:
        mask = scans.mask(vol)
        show = bar.steps({"compute": (0, 100)})
        return mask, compute(mask, lambda f: show("compute", f))


class VOLRIG_OT_show_thickness(_OnVolume, bpy.types.Operator):
    """Show the segmented object coloured by its local thickness (each voxel: the diameter of the largest ball
    inside the object that contains it) as <name>_thickness"""
    bl_idname = "volrig.show_thickness"
    bl_label = "Show Thickness"

    def run(self, context, vol):
        _, (obj, values) = _on_mask(context, vol, lambda mask, p: objects.update_thickness(vol, mask, progress=p))
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
        _, ms = _on_mask(context, vol, lambda mask, p: volrig.medial_surface(mask, t=t, progress=p))
        if len(ms.faces) == 0 and not ms.rods:
            self.report({"WARNING"}, f"volrig: no plates or rods found at Plate t = {t:g} voxels (try a smaller t)")
            return {"FINISHED"}
        obj = objects.update_medial_surface(vol, ms)
        med = float(np.median(ms.thickness)) if len(ms.thickness) else 0.0
        self.report({"INFO"}, f"volrig: {obj.name}: {len(ms.faces):,} triangles, area {ms.area:.4g}, median "
                              f"thickness {med:.3g}, {len(ms.rods)} rods (volume units), blue thin to red thick")
        return {"FINISHED"}


class VOLRIG_OT_pore_network(_OnVolume, bpy.types.Operator):
    """Show the network of the segmented pore space (a rock's pores: pores as spheres, throats as cylinders, coloured
    by their inscribed diameter) as <name>_pores; reports porosity, counts and the network's permeability"""
    bl_idname = "volrig.pore_network"
    bl_label = "Pore Network"

    def run(self, context, vol):
        mask, net = _on_mask(context, vol, lambda mask, p: volrig.pore_network(mask, progress=p))
        obj = objects.update_pore_network(vol, net, mask.origin, mask.spacing)
        k = ", ".join(f"{a} {v:.3g}" for a, v in zip("xyz", net.permeability))
        self.report({"INFO"}, f"volrig: {obj.name}: porosity {net.porosity:.4f}, {net.pore_count:,} pores, "
                              f"{net.throat_count:,} throats, mean coordination {net.coordination.mean():.2f}; "
                              f"permeability {k} (volume units²), blue narrow to red wide")
        return {"FINISHED"}


CLASSES = (VOLRIG_OT_show_thickness, VOLRIG_OT_medial_surface, VOLRIG_OT_pore_network)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

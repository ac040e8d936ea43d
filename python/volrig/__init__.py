"""volrig: rig and animate volumes (skeletonization after Gagvani's parameter-controlled thinness).

Pipeline: ``load`` -> ``segment`` -> ``skeletonize`` -> ``Skeleton.at(tp)`` -> ``skeleton_tree`` -> ``autorig``
-> ``bind`` (and ``reconstruct``) -> per frame ``deform`` (``Deformer``); ``save_rig`` / ``load_rig`` keep the result in one file.
``volrig.pipeline`` chains these steps as the command line, the Blender add-on and the demo use them.
Meshes come in through ``read_mesh`` -> ``voxelize`` (a mask, like ``segment``'s). Motion capture: ``read_bvh``
-> ``animate(rig, motion)`` gives per-frame bone matrices. Drawings come in through ``inflate`` (a mask, too)
and ``drawing_colours``. Time series: ``track`` follows features from step to step by their skeletons.
"""
from ._volrig import Cancelled, FileFormatError, VolrigError
from .mesh import read_mesh, read_tgf, subdivide, voxelize
from .segment import label_components, segment
from .skeleton import (MAX_THINNESS, Skeleton, SkeletonPoints, distance_transform, reconstruct,
                       reconstruction_loss, skeletonize)
from .volume import Volume, dicom_series, load, vdb_grids, vdb_metadata, write_vdb

read_volume = load  # the native core's name for it
from .tree import SkeletonTree, skeleton_tree
from .rig import MARKER_NAMES, Binding, Rig, autorig, bind, rest_pose, rigid_tissue, rotation_about
from .bones import BoneJoint, BonesFit, bone_segments, rig_to_bones
from .markers import ray_marker
from .rigfile import RiggedSkeleton, load_rig, save_rig
from .deform import BrickedFrame, Deformer, Frame, deform, deform_reference, inverse_warp
from .mocap import Motion, animate, default_bone_map, load_bone_map, read_bvh, save_bone_map
from .centerline import (Centerline, CenterlineTree, StraighteningRig, StraightenMap, centerline, centerline_tree,
                          straighten, straightening_rig)
from .medial import MedialSurface, local_thickness, medial_surface, plane_like, plane_measure
from .collide import ClipContacts, Collider, Collision, Contact, collide, collisions, self_collide
from .skin import MeshRig, pose_vertices, skin_weights
from .pipeline import rig_mesh
from .parts import Part, bone_parts, explode_matrices, part_grids
from .tissues import (TISSUE_CLASSES, Tissue, TissueClass, find_tissue_table, label_classes, read_tissue_table,
                      tissue_classes, tissue_grid)
from .track import Event, Tracking, track
from .pores import PoreNetwork, load_network, pore_network
from . import pipeline

__version__ = "0.1.0"
__license__ = "GPL-3.0-or-later"

__all__ = ["Volume", "load", "read_volume", "dicom_series", "write_vdb", "segment", "label_components", "skeletonize", "distance_transform", "Skeleton",
           "SkeletonPoints", "reconstruct", "reconstruction_loss", "MAX_THINNESS", "VolrigError",
           "FileFormatError", "Cancelled", "phantom", "SkeletonTree", "skeleton_tree", "Rig", "autorig", "bind", "rigid_tissue",
           "bone_segments", "rig_to_bones", "BoneJoint", "BonesFit",
           "MARKER_NAMES", "ray_marker",
           "Binding", "RiggedSkeleton", "save_rig", "load_rig", "read_mesh", "read_tgf", "voxelize", "Deformer", "Frame", "BrickedFrame", "deform",
           "deform_reference", "inverse_warp", "rest_pose", "rotation_about", "Motion", "read_bvh", "animate",
           "default_bone_map", "load_bone_map", "save_bone_map", "pipeline", "Centerline", "CenterlineTree",
           "StraightenMap", "centerline", "centerline_tree", "straighten", "StraighteningRig", "straightening_rig",
           "Collider", "Collision", "Contact", "ClipContacts", "collide", "self_collide", "collisions",
           "local_thickness", "plane_like", "plane_measure", "medial_surface", "MedialSurface", "subdivide", "MeshRig",
           "rig_mesh", "skin_weights", "pose_vertices", "inflate", "drawing_colours", "Part", "bone_parts", "TISSUE_CLASSES", "Tissue", "TissueClass", "read_tissue_table",
           "tissue_classes", "tissue_grid", "label_classes", "find_tissue_table",
           "part_grids", "explode_matrices", "vdb_grids", "vdb_metadata", "track", "Tracking", "Event", "PoreNetwork", "pore_network",
           "load_network"]


def __getattr__(name):
    if name in ("phantom", "drawing"):  # numpy/scipy-heavy modules, imported on first use
        import importlib
        return importlib.import_module("." + name, __name__)
    if name == "centerlines":  # volrig.centerline's old name (its module, not the function volrig.centerline)
        import importlib
        return importlib.import_module(".centerlines", __name__)
    if name in ("inflate", "drawing_colours"):  # scipy.ndimage, imported on first use
        from . import drawing
        return getattr(drawing, name)
    raise AttributeError(name)

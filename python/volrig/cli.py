"""Command line: ``python -m volrig {info,skeletonize,rig,animate,bake-mocap,bake,centerline,flythrough,contacts,thickness,medial,pores,inflate,track,demo}``. Run with -h for each command's options.

The parser and ``main`` live here; the commands themselves (``cmd_<name>``) and their helpers in volrig.cli_commands.
"""
from __future__ import annotations

import argparse
import os
import sys

from ._volrig import VolrigError
from .cli_commands import (
    StepBars,
    addon_folder,
    cmd_animate,
    cmd_bake,
    cmd_bake_mocap,
    cmd_centerline,
    cmd_contacts,
    cmd_demo,
    cmd_flythrough,
    cmd_inflate,
    cmd_info,
    cmd_medial,
    cmd_pores,
    cmd_rig,
    cmd_skeletonize,
    cmd_thickness,
    cmd_track,
)
from .deform import MODES, SAMPLINGS
from .pipeline import DEFAULT_THINNESS_VOXELS
from .rig import KINDS

# main, and the names volrig.cli has always offered (addon_folder: tests/python/test_cli.py) that now live in
# volrig.cli_commands. The parsers below bind each command by its name in this module (cmd_bake, ...), so replacing
# volrig.cli.cmd_<name> still takes effect (tests/python/test_flamenco_job.py).
__all__ = ["main", "addon_folder", "StepBars"]


def _add_load_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="volume file (.nrrd .nhdr .mha .mhd .nii .nii.gz .vti .vdb .tif .tiff .dcm, a "
                                "DICOMDIR, a folder of DICOM or TIFF files, or raw with --dims)")
    p.add_argument("--dims", type=int, nargs=3, metavar=("X", "Y", "Z"), help="raw files: size in voxels")
    p.add_argument("--dtype", help="raw files: element type (uint8, int16, float32, ...)")
    p.add_argument("--spacing", type=float, nargs=3, default=(1.0, 1.0, 1.0), metavar=("SX", "SY", "SZ"),
                   help="raw files: voxel size in world units")
    p.add_argument("--big-endian", action="store_true", help="raw files: big-endian samples")
    p.add_argument("--offset", type=int, default=0, help="raw files: header bytes to skip")
    p.add_argument("--grid", default="", help="VDB files: grid name (default: density, else the first)")
    p.add_argument("--crop", type=int, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
                   help="VDB files: read only this box of the grid (index coordinates, inclusive)")
    p.add_argument("--series", default="", help="DICOM: SeriesInstanceUID (default: the series with most slices)")
    p.add_argument("--tiff-spacing", type=float, nargs=3, metavar=("SX", "SY", "SZ"),
                   help="TIFF stacks: voxel size; 0 takes it from the file (x, y from its resolution, z = x)")


def _add_mocap_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", help="BVH frames FIRST-LAST (1-based, inclusive; also 1-10,20; default all)")
    p.add_argument("--map", help="bone map JSON {BVH joint: rig bone} (default: automatic from the names)")
    p.add_argument("--root", choices=["in_place", "travel"], default="in_place", help="root motion")
    p.add_argument("--up", choices=["y", "z"], default="y", help="the BVH's up axis (default y)")
    p.add_argument("--scale", type=float, help="rig units per BVH unit (default: from the leg lengths)")


def _add_segmentation_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--lo", type=float, help="segmentation: lowest object value (default: non-zero is object)")
    p.add_argument("--hi", type=float, help="segmentation: highest object value")
    p.add_argument("--labels", type=int, nargs="+", help="segmentation: object labels")
    p.add_argument("--largest", action="store_true", help="segmentation: keep the largest connected part")


def _add_skeleton_options(p: argparse.ArgumentParser, what: str) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--thinness", "-t", type=float,
                   help="thinness TP in distance-transform units: world units for euclidean (0 to 1.416 voxels' "
                        "size), grid steps for chamfer345 (0 to 4.077); default: half a voxel (the add-on's "
                        f"default, {DEFAULT_THINNESS_VOXELS} x the smallest spacing for euclidean)")
    g.add_argument("--count", "-n", type=int, help="keep the N highest-scoring points instead")
    p.add_argument("--metric", choices=["euclidean", "chamfer345"], default="euclidean")
    _add_segmentation_options(p)
    p.add_argument("--progress", action="store_true", help="show progress bars on stderr (always on a terminal)")
    p.add_argument("-o", "--output", required=True, help=what)


def _at_least_one(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _add_command(sub, name: str, help_text: str, run) -> argparse.ArgumentParser:
    """The parser of the command ``name``, which ``run(args)`` carries out."""
    p = sub.add_parser(name, help=help_text)
    p.set_defaults(run=run)
    return p


def _add_blender_options(p: argparse.ArgumentParser) -> None:
    """The commands that run in headless Blender (bake, flythrough): which Blender, and which add-on."""
    p.add_argument("--blender", help="the Blender executable (default: $BLENDER or blender on PATH)")
    p.add_argument("--addon", help="the volrig add-on: its zip or a folder holding volrig_addon (default: the "
                                   "volrig_addon Python finds, else the one installed in Blender)")


def _info_command(sub) -> None:
    p = _add_command(sub, "info", "print a volume file's grid, type and value range", cmd_info)
    _add_load_options(p)
    p.add_argument("--json", action="store_true", help="print JSON")


def _skeletonize_command(sub) -> None:
    p = _add_command(sub, "skeletonize", "skeleton points of a volume at a thinness", cmd_skeletonize)
    _add_load_options(p)
    _add_skeleton_options(p, "output .npz (ijk, centers, radii, dt, scores, ...)")


def _rig_command(sub) -> None:
    p = _add_command(sub, "rig", "skeleton, skeleton-tree, automatic rig and binding, saved as one .vrig file", cmd_rig)
    _add_load_options(p)
    _add_skeleton_options(p, "output .vrig (points, tree, rig, binding, source path)")
    p.add_argument("--voxel-size", type=float, help="meshes (.obj .ply .off .stl .mesh): voxel size, mesh units")
    p.add_argument("--voxelize", choices=("auto", "winding", "flood"), default="auto",
                   help="meshes: inside/outside test (default auto: the flood fill, and for a mesh that is not "
                        "closed also the generalized winding number's solid; see volrig.voxelize)")
    p.add_argument("--alpha", type=float, default=0.9, help="skeleton-tree connectivity parameter (0..1)")
    p.add_argument("--max-edge", type=float, help="longest tree edge in world units (default 4 voxel diagonals)")
    p.add_argument("--bones", type=int, help="bone count target (default 24; role rigs use 21)")
    p.add_argument("--no-roles", action="store_true", help="neutral chain names, no humanoid/quadruped guess")
    p.add_argument("--kind", choices=KINDS, help="force a body plan (default: the best-fitting template)")
    p.add_argument("--up", help="the world's up in the volume's frame: +z, -y, x ... or x,y,z (default: inferred)")
    p.add_argument("--rig-kept-points", action="store_true",
                   help="rig the kept skeleton points themselves, not autorig's own skeleton (thin, fragmented "
                        "objects such as bones without flesh; the rig then depends on --count / --thinness)")
    p.add_argument("--markers", metavar="JSON",
                   help='joints you marked, {"chin": [x, y, z], "wrist.L": [...], ...} in the volume\'s frame: they '
                        "choose the body plan and place those joints (names: volrig.MARKER_NAMES)")
    p.add_argument("--bind", choices=["rigid", "smooth"], default="smooth", help="binding mode")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rigid-labels", type=int, nargs="+", metavar="LABEL",
                   help="tissue that must not bend: these label values (a label map's bone codes, e.g. 84 92)")
    g.add_argument("--rigid-range", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="tissue that must not bend: values in this range (a CT's bone, e.g. 300 3000)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--bone-labels", type=int, nargs="+", metavar="LABEL",
                   help="bone whose articulations place the limb joints: these label values (e.g. 84 92; default: "
                        "the rigid tissue, when given)")
    g.add_argument("--bone-range", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="bone whose articulations place the limb joints: values in this range (a CT, e.g. 250 3000)")


def _bake_command(sub) -> None:
    p = _add_command(sub, "bake", "bake a saved .blend's volrig volumes in headless Blender (then render with blender "
                                  "-b scene.blend -a)", cmd_bake)
    p.add_argument("blend", help="the saved .blend file")
    p.add_argument("--frames", help="frames to bake, e.g. 1-48 or 1-10,20 (default: the scene's range); split a "
                                    "range across machines sharing the cache folder")
    p.add_argument("--object", action="append", help="bake only this volrig Volume object (repeatable)")
    p.add_argument("--mode", choices=MODES, help="override the deform mode")
    p.add_argument("--force", action="store_true", help="bake frames whose pose did not change, too")
    p.add_argument("--no-save", action="store_true", help="do not save the .blend after baking")
    _add_blender_options(p)


def _animate_command(sub) -> None:
    p = _add_command(sub, "animate", "per-frame bone matrices driving a rig with a BVH clip", cmd_animate)
    p.add_argument("rig", help="rig file (.vrig, from `volrig rig`)")
    p.add_argument("clip", help="motion capture (.bvh)")
    p.add_argument("-o", "--output", required=True,
                   help="output .npz: matrices (F, B, 4, 4) rest-to-pose in the rig's world, frames (0-based), "
                        "bone_names, frame_time, bone_map (JSON), ...")
    _add_mocap_options(p)
    p.add_argument("--save-map", help="also write the bone map used as JSON (to edit and pass back with --map)")


def _bake_mocap_command(sub) -> None:
    p = _add_command(sub, "bake-mocap", "bake a VDB sequence of a volume driven by a BVH clip (no Blender)",
                     cmd_bake_mocap)
    _add_load_options(p)
    p.add_argument("rig", help="rig file (.vrig, from `volrig rig` on the same volume, with its binding)")
    p.add_argument("clip", help="motion capture (.bvh)")
    p.add_argument("-o", "--output", required=True,
                   help="output folder: <name>_NNNN.vdb per frame (grids density and bone), written atomically")
    _add_mocap_options(p)
    p.add_argument("--step", type=_at_least_one, default=1,
                   help="bake every STEP-th BVH frame (1, 1+STEP, ...; files numbered 1, 2, ...), e.g. 5 for 120 fps "
                        "-> 24 fps")
    p.add_argument("--mode", choices=MODES, default="linear", help="deform mode")
    p.add_argument("--plain-blend", action="store_true",
                   help="smooth modes: blend without keeping the volume at bends or the limbs' contact plane")
    p.add_argument("--sampling", choices=SAMPLINGS, default="trilinear",
                   help="nearest for label maps")
    p.add_argument("--name", help="file name stem (default: the volume file's)")
    p.add_argument("--tissues", help="label maps: a table of tissue codes and names (TSV or CSV); each frame also "
                                     "holds the tissue grid, each voxel's tissue class (skin, muscle, bone, ...), for "
                                     "per-tissue looks; needs --sampling nearest")
    p.add_argument("--skip-existing", action="store_true", help="leave frames whose file exists (resume a farm job)")
    p.add_argument("--lattice-tables", action="store_true",
                   help="build the bones' lattice tables at the first frame (a bake of 16 frames or more): frames "
                        "about 5%% (smooth) to 20%% (rigid) faster for 1-3 bytes per source voxel more memory "
                        "(docs/deform.md, Bakes and the lattice tables)")
    p.add_argument("--progress", action="store_true", help="show a progress bar on stderr (always on a terminal)")


def _centerline_command(sub) -> None:
    p = _add_command(sub, "centerline", "centerline of a tubular object (--tree: every branch of a branching one) as "
                                        "CSV", cmd_centerline)
    _add_load_options(p)
    p.add_argument("--start", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="world start point (default: the object's end farthest from the other)")
    p.add_argument("--end", type=float, nargs=3, metavar=("X", "Y", "Z"), help="world end point (default: automatic)")
    p.add_argument("--tree", action="store_true", help="every branch from a root (airways, vessels)")
    p.add_argument("--root", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="--tree: world root point (default: the end of the thickest terminal branch)")
    p.add_argument("--step", type=float, help="arc length between samples (default: the smallest voxel spacing)")
    _add_segmentation_options(p)
    p.add_argument("-o", "--output", required=True,
                   help="output .csv: branch,parent,generation,index,x,y,z,radius,arc_length (world units)")


def _thickness_command(sub) -> None:
    p = _add_command(sub, "thickness", "local thickness of an object (each voxel: the diameter of the largest "
                                       "inscribed ball containing it) as a volume", cmd_thickness)
    _add_load_options(p)
    _add_segmentation_options(p)
    p.add_argument("--progress", action="store_true", help="show a progress bar on stderr (always on a terminal)")
    p.add_argument("-o", "--output", required=True, help="output .nrrd, .mha or .vdb (grid 'thickness'), world units")


def _medial_command(sub) -> None:
    p = _add_command(sub, "medial", "medial surface of the object's plates (a mesh with per-vertex thickness) and its "
                                    "rods, as a PLY", cmd_medial)
    _add_load_options(p)
    _add_segmentation_options(p)
    p.add_argument("--t", type=float, default=5.0,
                   help="plane-like threshold in voxels of the smallest spacing (default 5; larger: larger plates)")
    p.add_argument("--progress", action="store_true", help="show a progress bar on stderr (always on a terminal)")
    p.add_argument("-o", "--output", required=True,
                   help="output .ply: vertices with a 'thickness' property, triangles, rods as edges (world units)")


def _pores_command(sub) -> None:
    p = _add_command(sub, "pores", "pore network of a rock's pore space (pores, throats), its permeability and "
                                   "formation factor along x, y, z, as OpenPNM's .npz or CSV", cmd_pores)
    _add_load_options(p)
    p.add_argument("--shape", type=int, nargs=3, metavar=("N0", "N1", "N2"),
                   help="raw files: the array's shape in numpy's C order, slowest axis first (--dims X Y Z "
                        "reversed); element type uint8 unless --dtype")
    p.add_argument("--key", default="im", help=".npz files: the array's key (default im)")
    p.add_argument("--invert", action="store_true", help="zero is pore (default: non-zero is pore)")
    p.add_argument("--voxel", type=float, help="voxel size in metres (default: the file's spacing, else 1)")
    p.add_argument("--model", choices=("pyramids_and_cuboids", "cones_and_cylinders"), default="pyramids_and_cuboids",
                   help="conduit shapes for the flow (default pyramids_and_cuboids, as OpenPNM's SNOW example)")
    p.add_argument("--progress", action="store_true", help="show a progress bar on stderr (always on a terminal)")
    p.add_argument("-o", "--output", required=True,
                   help="output .npz (OpenPNM's keys) or .csv (<stem>_pores.csv and <stem>_throats.csv)")


def _contacts_command(sub) -> None:
    p = _add_command(sub, "contacts", "frames where two rigged volumes touch, or one passes through itself, over BVH "
                                      "clips", cmd_contacts)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="one or two rig files (.vrig, with their binding) then a clip (.bvh) for each; one clip "
                        "drives the first rig (the second holds its rest pose); one rig alone: self-contact")
    _add_mocap_options(p)
    p.add_argument("--step", type=_at_least_one, default=1, help="test every STEP-th frame of the clip")
    p.add_argument("--mode", choices=MODES, default="rigid", help="how the spheres move (as in the bake)")
    p.add_argument("--min-distance", type=_at_least_one, default=2,
                   help="self-contact: bones at least this many bones apart in the rig (default 2: not parent and "
                        "child)")


def _flythrough_command(sub) -> None:
    p = _add_command(sub, "flythrough", "a fly-through along a tubular object's centerline, built in headless Blender "
                                        "and saved as a .blend (optionally a few frames rendered)", cmd_flythrough)
    p.add_argument("file", help="volume file (.nrrd .nhdr .mha .mhd .nii .nii.gz .vdb), in mm")
    p.add_argument("--lo", type=float, help="segmentation: lowest lumen value (default: the add-on's guess)")
    p.add_argument("--hi", type=float, help="segmentation: highest lumen value")
    p.add_argument("--labels", type=int, nargs="+", help="segmentation: lumen labels")
    p.add_argument("--all-parts", action="store_true", help="keep every connected part (default: the largest)")
    p.add_argument("--start", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="world start point (default: the end of the thickest terminal branch)")
    p.add_argument("--end", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="world end point (default: the end farthest from the start)")
    p.add_argument("--frames-per-mm", type=float, default=1.0, help="the camera's speed (default 1)")
    p.add_argument("--look-ahead", type=float, help="mm of centerline the view direction averages (default 10)")
    p.add_argument("-o", "--output", required=True, help="output .blend (its cache folder goes beside it)")
    p.add_argument("--render", metavar="DIR", help="also render frames as DIR/frame_NNNN.png (Cycles, or EEVEE where "
                                                   "this Blender's Cycles renders no VDB grids)")
    p.add_argument("--frames", type=_at_least_one, help="--render: how many frames, spread over the flight "
                                                         "(default 3)")
    p.add_argument("--resolution", type=int, nargs=2, default=(320, 320), metavar=("W", "H"),
                   help="--render: image size (default 320 320)")
    p.add_argument("--samples", type=_at_least_one, default=16, help="--render: samples (default 16)")
    _add_blender_options(p)


def _inflate_command(sub) -> None:
    p = _add_command(sub, "inflate", "a front-view drawing (PNG with alpha or on a light background) inflated to a "
                                     "rounded solid, with its colours, as a VDB (grids density, color_r/g/b)",
                     cmd_inflate)
    p.add_argument("drawing", help="the drawing (.png)")
    p.add_argument("output", help="output .vdb")
    p.add_argument("--pixel-size", type=float, default=1.0, help="world units per pixel (default 1)")
    p.add_argument("--depth-scale", type=float, default=1.0, help="depth / round (default 1; < 1 flatter)")
    p.add_argument("--stroke-width", type=float, default=3.0,
                   help="widest inner line (pixels) separating parts (default 3)")
    p.add_argument("--gap", type=int, default=0, help="voxels between a part drawn in front and what is behind it")
    p.add_argument("--resolution", type=int, help="downscale the drawing to about this many pixels along its "
                                                  "longer side first")
    p.add_argument("--max-voxels", type=int, default=None,
                   help="refuse a solid whose box holds more voxels (default 2^28; the error names the resolution "
                        "that fits)")


def _track_command(sub) -> None:
    p = _add_command(sub, "track", "track the features of a time series by their skeletons (thesis 9.1): prints "
                                   "the events, writes the tracking graph as JSON", cmd_track)
    p.add_argument("steps", help="a folder of time steps (any volume format, .vti too; taken in name order)")
    p.add_argument("--lo", type=float, required=True, help="a feature's voxels are >= LO")
    p.add_argument("--hi", type=float, help="... and <= HI")
    p.add_argument("--thinness", type=float, default=1.0,
                   help="skeleton thinness (<3,4,5> chamfer units as in the thesis' Table 9.1; 0 = whole features)")
    p.add_argument("--min-size", type=_at_least_one, default=20, help="smallest feature in voxels (default 20)")
    p.add_argument("--tolerance", type=float, default=0.1,
                   help="a match overlaps by at least this share of the smaller feature (default 0.1)")
    p.add_argument("-o", "--output", help="the tracking graph (.json: features, edges, events)")
    p.add_argument("--vdb", metavar="DIR", help="also write DIR/track_NNNN.vdb: a `track` grid (each voxel its "
                                                "feature's track id) a step")


def _demo_command(sub) -> None:
    p = _add_command(sub, "demo", "phantom -> skeleton -> pictures and a report", cmd_demo)
    p.add_argument("-o", "--output", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--scale", type=float, default=0.5, help="phantom scale (1.0 = 290 x 169 x 940)")
    p.add_argument("--thinness", type=float, default=0.3, help="thinness for the pictured skeleton")


def main(argv=None) -> int:
    # the wheel's console script is `volrig`; in a checkout it runs as `python -m volrig`
    prog = "volrig" if os.path.basename(sys.argv[0]) == "volrig" else "python -m volrig"
    parser = argparse.ArgumentParser(prog=prog, description="volrig: rig and animate volumes")
    sub = parser.add_subparsers(dest="command", required=True)
    _info_command(sub)
    _skeletonize_command(sub)
    _rig_command(sub)
    _bake_command(sub)
    _animate_command(sub)
    _bake_mocap_command(sub)
    _centerline_command(sub)
    _thickness_command(sub)
    _medial_command(sub)
    _pores_command(sub)
    _contacts_command(sub)
    _flythrough_command(sub)
    _inflate_command(sub)
    _track_command(sub)
    _demo_command(sub)

    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (VolrigError, OSError) as e:  # user mistakes and bad files; anything else is a bug: a traceback
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""Command line: ``python -m volrig {info,skeletonize,rig,animate,bake-mocap,bake,demo}``. Run with -h for each command's options."""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def _add_load_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="volume file (.nrrd .nhdr .mha .mhd .nii .nii.gz .vdb, or raw with --dims)")
    p.add_argument("--dims", type=int, nargs=3, metavar=("X", "Y", "Z"), help="raw files: size in voxels")
    p.add_argument("--dtype", help="raw files: element type (uint8, int16, float32, ...)")
    p.add_argument("--spacing", type=float, nargs=3, default=(1.0, 1.0, 1.0), metavar=("SX", "SY", "SZ"),
                   help="raw files: voxel size in world units")
    p.add_argument("--big-endian", action="store_true", help="raw files: big-endian samples")
    p.add_argument("--offset", type=int, default=0, help="raw files: header bytes to skip")
    p.add_argument("--grid", default="", help="VDB files: grid name (default: density, else the first)")


def _load(args):
    from .volume import load
    if args.dims:
        if not args.dtype:
            raise ValueError("--dims needs --dtype")
        return load(args.file, dims=args.dims, dtype=args.dtype, spacing=args.spacing,
                    byte_order="big" if args.big_endian else "little", offset=args.offset)
    return load(args.file, grid=args.grid)


def cmd_info(args) -> int:
    v = _load(args)
    a = v.array
    finite = a[np.isfinite(a)] if a.dtype.kind == "f" else a
    info = {
        "file": args.file, "dims_xyz": list(v.dims), "dtype": str(a.dtype), "spacing": list(v.spacing),
        "origin": list(v.origin), "min": float(finite.min()) if finite.size else None,
        "max": float(finite.max()) if finite.size else None, "nonzero": int(np.count_nonzero(a)),
        "voxels": int(a.size),
    }
    if a.dtype.kind in "iu" and a.size and int(a.max()) - int(a.min()) <= 255:
        values, counts = np.unique(a, return_counts=True)
        info["values"] = {int(k): int(c) for k, c in zip(values, counts)}
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        x, y, z = v.dims
        print(f"{args.file}\n  {x} x {y} x {z} {a.dtype}, spacing {v.spacing}, origin {v.origin}\n"
              f"  values {info['min']} .. {info['max']}, {info['nonzero']:,} non-zero of {a.size:,} voxels")
        if "values" in info and len(info["values"]) <= 40:
            print("  labels: " + ", ".join(f"{k}: {c:,}" for k, c in info["values"].items()))
    return 0


def cmd_skeletonize(args) -> int:
    from .files import atomic_output
    t = time.perf_counter()
    args.voxel_size = None
    mask, sk, pts = _mask_and_skeleton(args)
    elapsed = time.perf_counter() - t
    out = args.output
    if not out.endswith(".npz"):
        raise ValueError(f"{out}: the output must be a .npz file")
    with atomic_output(out, suffix=".npz") as tmp:
        np.savez_compressed(tmp, ijk=pts.ijk, centers=pts.centers, radii=pts.radii, dt=pts.dt, scores=pts.scores,
                            metric=pts.metric, thinness=np.nan if pts.thinness is None else pts.thinness,
                            spacing=np.asarray(pts.spacing), origin=np.asarray(pts.origin),
                            shape=np.asarray(mask.array.shape), source=args.file)
    print(f"{len(pts):,} skeleton points of {sk.object_count:,} object voxels "
          f"({100.0 * len(pts) / sk.object_count:.2f}%), {pts.metric}, "
          + (f"thinness {pts.thinness}" if pts.thinness is not None else f"top {args.count}")
          + f"; loaded and skeletonized in {elapsed:.2f} s -> {out}")
    return 0


def _mask_and_skeleton(args):
    """The mask (segmented volume, or voxelized mesh) and its skeleton points, as the options say."""
    from .segment import segment
    from .skeleton import skeletonize
    from .mesh import MESH_EXTENSIONS, read_mesh, voxelize
    if args.file.lower().endswith(MESH_EXTENSIONS):
        if not args.voxel_size:
            raise ValueError(f"{args.file}: meshes need --voxel-size")
        mask = voxelize(*read_mesh(args.file), args.voxel_size)
    else:
        mask = segment(_load(args), lo=args.lo, hi=args.hi, labels=args.labels, largest_component=args.largest)
    if not mask.array.any():
        raise ValueError(f"{args.file}: the segmentation is empty (check --lo/--hi/--labels)")
    sk = skeletonize(mask, args.metric, progress=_progress_bar("skeletonize") if args.progress else None)
    pts = sk.top(args.count) if args.count is not None else sk.at(args.thinness)
    return mask, sk, pts


def cmd_rig(args) -> int:
    from .rig import autorig, bind
    from .rigfile import save_rig
    from .tree import skeleton_tree
    if not args.output.endswith(".vrig"):
        raise ValueError(f"{args.output}: the output must be a .vrig file")
    t = time.perf_counter()
    mask, sk, pts = _mask_and_skeleton(args)
    show = args.progress
    tree = skeleton_tree(pts, mask, alpha=args.alpha, max_edge=args.max_edge,
                         progress=_progress_bar("skeleton-tree") if show else None)
    rig = autorig(pts, tree, mask, bones=args.bones, roles=not args.no_roles,
                  progress=_progress_bar("autorig") if show else None)
    binding = bind(pts, rig, mask, mode=args.bind, progress=_progress_bar("bind") if show else None)
    save_rig(args.output, pts, tree, rig, binding, source=args.file)
    print(f"{len(pts):,} skeleton points, tree of {tree.component_count} part(s), {rig.kind} rig of {len(rig)} bones "
          f"({', '.join(rig.names[:8])}{', ...' if len(rig) > 8 else ''}), {args.bind} binding; "
          f"{time.perf_counter() - t:.1f} s -> {args.output}")
    return 0


def _frame_range(text: str, count: int):
    """'A-B' (1-based, inclusive) or 'N' -> 0-based frame indices of a clip of `count` frames."""
    parts = text.split("-")
    try:
        if len(parts) == 1:
            first = last = int(parts[0])
        elif len(parts) == 2:
            first, last = int(parts[0]), int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise ValueError(f"--frames {text!r}: expected FIRST-LAST or N (1-based frame numbers)") from None
    if not 1 <= first <= last <= count:
        raise ValueError(f"--frames {text}: the clip has frames 1-{count}")
    return np.arange(first - 1, last)


def _mocap_matrices(args):
    """What ``animate`` and ``bake-mocap`` share: the rig file, the clip, the BVH frames (0-based), the bone map and
    the (F, B, 4, 4) rest-to-pose matrices of those frames."""
    from .mocap import animate, default_bone_map, load_bone_map, read_bvh
    from .rigfile import load_rig
    saved = load_rig(args.rig)
    if saved.rig is None:
        raise ValueError(f"{args.rig}: the file holds no rig")
    motion = read_bvh(args.clip)
    frames = _frame_range(args.frames, motion.frame_count) if args.frames else np.arange(motion.frame_count)
    bone_map = load_bone_map(args.map) if args.map else default_bone_map(motion, saved.rig)
    matrices = animate(saved.rig, motion, frames=frames, bone_map=bone_map, root_motion=args.root,
                       up_axis=args.up, scale=args.scale)
    return saved, motion, frames, bone_map, matrices


def _add_mocap_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", help="BVH frames FIRST-LAST, 1-based and inclusive (default all)")
    p.add_argument("--map", help="bone map JSON {BVH joint: rig bone} (default: automatic from the names)")
    p.add_argument("--root", choices=["in_place", "travel"], default="in_place", help="root motion")
    p.add_argument("--up", choices=["y", "z"], default="y", help="the BVH's up axis (default y)")
    p.add_argument("--scale", type=float, help="rig units per BVH unit (default: from the leg lengths)")


def cmd_animate(args) -> int:
    from .files import atomic_output
    from .mocap import save_bone_map
    if not args.output.endswith(".npz"):
        raise ValueError(f"{args.output}: the output must be a .npz file")
    t = time.perf_counter()
    saved, motion, frames, bone_map, matrices = _mocap_matrices(args)
    with atomic_output(args.output, suffix=".npz") as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, matrices=matrices, frames=frames, bone_names=np.array(saved.rig.names, np.str_),
                                frame_time=np.array(motion.frame_time), root_motion=np.array(args.root),
                                up_axis=np.array(args.up), bone_map=np.array(json.dumps(bone_map, sort_keys=True)),
                                rig=np.array(args.rig), clip=np.array(args.clip))
    if args.save_map:
        save_bone_map(args.save_map, bone_map)
    print(f"{len(frames)} frames (BVH {frames[0] + 1}-{frames[-1] + 1} of {motion.frame_count}, "
          f"{motion.fps:.4g} fps) x {len(saved.rig)} bones, {len(bone_map)} mapped, {args.root}; "
          f"{time.perf_counter() - t:.2f} s -> {args.output}")
    return 0


def mocap_frame_path(folder: str, stem: str, bvh_frame: int, step: int) -> str:
    """``<folder>/<stem>_NNNN.vdb`` of 0-based BVH frame ``bvh_frame`` baked every ``step`` frames: numbered from 1
    over the whole clip (BVH frames 1, 1 + step, ... are files 1, 2, ...), so split ranges fit one sequence."""
    import os
    return os.path.join(folder, f"{stem}_{bvh_frame // step + 1:04d}.vdb")


def cmd_bake_mocap(args) -> int:
    import os
    from .deform import Deformer
    if args.step < 1:
        raise ValueError(f"--step must be at least 1, got {args.step}")
    t = time.perf_counter()
    source = _load(args)
    saved, motion, frames, bone_map, matrices = _mocap_matrices(args)
    if saved.binding is None:
        raise ValueError(f"{args.rig}: the file holds no binding (make it with `volrig rig`)")
    keep = frames % args.step == 0  # BVH frames 1, 1 + step, ...: the same on every machine of a farm
    frames, matrices = frames[keep], matrices[keep]
    if not len(frames):
        raise ValueError(f"--frames {args.frames}: no frame of the range falls on the --step {args.step} grid "
                         f"(BVH frames 1, {1 + args.step}, ...)")
    stem = args.name or os.path.basename(args.file).split(".")[0] or "volume"
    os.makedirs(args.output, exist_ok=True)
    deformer = Deformer(source, saved.points, saved.binding)
    written = 0
    for k, (f, m) in enumerate(zip(frames, matrices)):
        path = mocap_frame_path(args.output, stem, int(f), args.step)
        if args.skip_existing and os.path.exists(path):
            sys.stderr.write(f"bake-mocap: {k + 1}/{len(frames)} BVH frame {f + 1}: {path} exists, skipped\n")
            continue
        started = time.perf_counter()
        frame = deformer.frame(m, mode=args.mode, sampling=args.sampling)
        frame.save(path, half=True)
        written += 1
        sys.stderr.write(f"bake-mocap: {k + 1}/{len(frames)} BVH frame {f + 1}: {frame.stats['covered']:,} voxels, "
                         f"{time.perf_counter() - started:.2f} s -> {path}\n")
        sys.stderr.flush()
        del frame  # its memory goes back to the Deformer for the next frame
    print(f"{written} of {len(frames)} frames (BVH {frames[0] + 1}-{frames[-1] + 1} step {args.step} of "
          f"{motion.frame_count}, {motion.fps / args.step:.4g} fps) x {len(saved.rig)} bones, {len(bone_map)} mapped, "
          f"{args.root}, {args.mode}; {time.perf_counter() - t:.1f} s -> {args.output}")
    return 0


def _add_skeleton_options(p: argparse.ArgumentParser, what: str) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--thinness", "-t", type=float, help="thinness TP (DT units; Euclidean 0..1.416, chamfer 0..4.077)")
    g.add_argument("--count", "-n", type=int, help="keep the N highest-scoring points instead")
    p.add_argument("--metric", choices=["euclidean", "chamfer345"], default="euclidean")
    p.add_argument("--lo", type=float, help="segmentation: lowest object value")
    p.add_argument("--hi", type=float, help="segmentation: highest object value")
    p.add_argument("--labels", type=int, nargs="+", help="segmentation: object labels")
    p.add_argument("--largest", action="store_true", help="segmentation: keep the largest connected part")
    p.add_argument("--progress", action="store_true", help="show progress on stderr")
    p.add_argument("-o", "--output", required=True, help=what)


def _progress_bar(label: str):
    def show(f: float) -> bool:
        sys.stderr.write(f"\r{label}: {100 * f:5.1f}%")
        if f >= 1.0:
            sys.stderr.write("\n")
        sys.stderr.flush()
        return True
    return show


#: Runs inside Blender for ``bake``: enables the add-on (from the checkout, else as installed), bakes, exits with
#: 0, or 2 and a message for a user error (Python errors exit 1 through --python-exit-code).
_BAKE_IN_BLENDER = """
import json, os, sys
args = json.loads(sys.argv[sys.argv.index("--") + 1])
sys.path[:0] = args["paths"]
import addon_utils
addon_utils.enable("volrig_addon", default_set=False)
from volrig_addon import bake
try:
    n = bake.bake_saved_scene(args["frames"], args["objects"], args["mode"], args["force"], args["save"])
    print(f"volrig: baked {n} frame(s) of {os.path.basename(args['blend'])}")
    code = 0
except (ValueError, OSError, RuntimeError) as e:
    print(f"error: {e}", file=sys.stderr)
    code = 2
sys.stdout.flush(); sys.stderr.flush()
os._exit(code)
"""


def cmd_bake(args) -> int:
    import os
    import shutil
    import subprocess
    blender = args.blender or os.environ.get("BLENDER") or shutil.which("blender")
    if not blender:
        raise FileNotFoundError("blender not found: install it (apt-get install blender) or pass --blender PATH")
    if not os.path.isfile(args.blend):
        raise FileNotFoundError(f"{args.blend}: no such file")
    here = os.path.dirname(os.path.abspath(__file__))
    checkout_addon = os.path.normpath(os.path.join(here, "..", "..", "addon"))
    paths = [os.path.dirname(here)] + ([checkout_addon] if os.path.isdir(checkout_addon) else [])
    payload = json.dumps({"paths": paths, "frames": args.frames or "", "objects": args.object or [],
                          "mode": args.mode or "", "force": args.force, "save": not args.no_save,
                          "blend": args.blend})
    cmd = [blender, "-b", "--factory-startup", os.path.abspath(args.blend), "--python-exit-code", "1",
           "--python-expr", _BAKE_IN_BLENDER, "--", payload]
    return subprocess.run(cmd).returncode


def cmd_demo(args) -> int:
    from .demo import run_demo
    run_demo(args.output, scale=args.scale, thinness=args.thinness)
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m volrig", description="volrig: rig and animate volumes")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("info", help="print a volume file's grid, type and value range")
    _add_load_options(p)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=cmd_info)

    p = sub.add_parser("skeletonize", help="skeleton points of a volume at a thinness")
    _add_load_options(p)
    _add_skeleton_options(p, "output .npz (ijk, centers, radii, dt, scores, ...)")
    p.set_defaults(run=cmd_skeletonize)

    p = sub.add_parser("rig", help="skeleton, skeleton-tree, automatic rig and binding, saved as one .vrig file")
    _add_load_options(p)
    _add_skeleton_options(p, "output .vrig (points, tree, rig, binding, source path)")
    p.add_argument("--voxel-size", type=float, help="meshes (.obj .ply .off .stl .mesh): voxel size, mesh units")
    p.add_argument("--alpha", type=float, default=0.9, help="skeleton-tree connectivity parameter (0..1)")
    p.add_argument("--max-edge", type=float, help="longest tree edge in world units (default 4 voxel diagonals)")
    p.add_argument("--bones", type=int, help="bone count target (default 24; role rigs use 21)")
    p.add_argument("--no-roles", action="store_true", help="neutral chain names, no humanoid/quadruped guess")
    p.add_argument("--bind", choices=["rigid", "smooth"], default="smooth", help="binding mode")
    p.set_defaults(run=cmd_rig)

    p = sub.add_parser("bake", help="bake a saved .blend's volrig volumes in headless Blender (then render with "
                                    "blender -b scene.blend -a)")
    p.add_argument("blend", help="the saved .blend file")
    p.add_argument("--frames", help="frames to bake, e.g. 1-48 or 1-10,20 (default: the scene's range); split a "
                                    "range across machines sharing the cache folder")
    p.add_argument("--object", action="append", help="bake only this volrig Volume object (repeatable)")
    p.add_argument("--mode", choices=["rigid", "linear", "dual_quaternion"], help="override the deform mode")
    p.add_argument("--force", action="store_true", help="bake frames whose pose did not change, too")
    p.add_argument("--no-save", action="store_true", help="do not save the .blend after baking")
    p.add_argument("--blender", help="the Blender executable (default: $BLENDER or blender on PATH)")
    p.set_defaults(run=cmd_bake)

    p = sub.add_parser("animate", help="per-frame bone matrices driving a rig with a BVH clip")
    p.add_argument("rig", help="rig file (.vrig, from `volrig rig`)")
    p.add_argument("clip", help="motion capture (.bvh)")
    p.add_argument("-o", "--output", required=True,
                   help="output .npz: matrices (F, B, 4, 4) rest-to-pose in the rig's world, frames (0-based), "
                        "bone_names, frame_time, bone_map (JSON), ...")
    _add_mocap_options(p)
    p.add_argument("--save-map", help="also write the bone map used as JSON (to edit and pass back with --map)")
    p.set_defaults(run=cmd_animate)

    p = sub.add_parser("bake-mocap", help="bake a VDB sequence of a volume driven by a BVH clip (no Blender)")
    _add_load_options(p)
    p.add_argument("rig", help="rig file (.vrig, from `volrig rig` on the same volume, with its binding)")
    p.add_argument("clip", help="motion capture (.bvh)")
    p.add_argument("-o", "--output", required=True,
                   help="output folder: <name>_NNNN.vdb per frame (grids density and bone), written atomically")
    _add_mocap_options(p)
    p.add_argument("--step", type=int, default=1,
                   help="bake every STEP-th BVH frame (1, 1+STEP, ...; files numbered 1, 2, ...), e.g. 5 for 120 fps "
                        "-> 24 fps")
    p.add_argument("--mode", choices=["rigid", "linear", "dual_quaternion"], default="linear", help="deform mode")
    p.add_argument("--sampling", choices=["trilinear", "nearest"], default="trilinear",
                   help="nearest for label maps")
    p.add_argument("--name", help="file name stem (default: the volume file's)")
    p.add_argument("--skip-existing", action="store_true", help="leave frames whose file exists (resume a farm job)")
    p.set_defaults(run=cmd_bake_mocap)

    p = sub.add_parser("demo", help="phantom -> skeleton -> pictures and a report")
    p.add_argument("-o", "--output", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--scale", type=float, default=0.5, help="phantom scale (1.0 = 290 x 169 x 940)")
    p.add_argument("--thinness", type=float, default=0.3, help="thinness for the pictured skeleton")
    p.set_defaults(run=cmd_demo)

    args = parser.parse_args(argv)
    from . import Cancelled, VolrigError
    try:
        return args.run(args)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (VolrigError, ValueError, Cancelled) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

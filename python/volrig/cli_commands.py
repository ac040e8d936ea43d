"""The commands of ``python -m volrig`` (volrig.cli): what each does once its options are parsed.

volrig.cli holds the argument parser and ``main``; it binds each command to its ``cmd_<name>(args) -> int`` here
(0 for success; a ``VolrigError`` or ``OSError`` raised here is a user's mistake, which ``main`` prints and turns into
exit code 2). The helpers the commands share sit beside them: loading with the load options, the mask and skeleton
of the skeleton options, the BVH frames of the mocap options, the progress bars, and headless Blender for ``bake``
and ``flythrough``.
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

from ._volrig import VolrigError
from .pipeline import DEFAULT_THINNESS_VOXELS


def _hints(args) -> dict:
    """The load options as ``pipeline.load_source``'s keywords."""
    return dict(dims=args.dims, dtype=args.dtype, spacing=args.spacing, big_endian=args.big_endian,
                offset=args.offset, grid=args.grid, series=getattr(args, "series", ""),
                tiff_spacing=getattr(args, "tiff_spacing", None),
                crop=None if getattr(args, "crop", None) is None else (args.crop[:3], args.crop[3:]))


def _load(args):
    from .pipeline import load_source
    return load_source(args.file, **_hints(args))


def _dicom_listing(path: str):
    """The DICOM series under ``path`` (a folder, DICOMDIR or DICOM file), or None for other files."""
    from .volume import dicom_series, format_of
    try:
        kind = format_of(path)
    except VolrigError:
        return None
    if kind not in ("folder", "dicom"):
        return None
    try:
        return dicom_series(path)
    except VolrigError:
        return None  # a folder of TIFF files


def _print_series(series) -> None:
    print(f"  {len(series)} DICOM series (the largest is read unless --series names another):")
    for s in series:
        x, y, z = s["dims"]
        print(f"    {s['uid']}  {s['modality'] or '?'}  {s['description']!r}  {z} slices of {x} x {y}")


def _check_output(path: str, ending: str, *, any_case: bool = False, what: str = "") -> None:
    """A VolrigError unless the output ``path`` ends in ``ending`` (``any_case``: in either case); ``what`` the
    message's name for it (default: a <ending> file)."""
    if not (path.lower() if any_case else path).endswith(ending):
        raise VolrigError(f"{path}: the output must be {what or f'a {ending} file'}")


def cmd_info(args) -> int:
    series = _dicom_listing(args.file) if args.dims is None else None
    v = _load(args)
    a = v.array
    finite = a[np.isfinite(a)] if a.dtype.kind == "f" else a
    info = {
        "file": args.file, "dims_xyz": list(v.dims), "dtype": str(a.dtype), "spacing": list(v.spacing),
        "origin": list(v.origin), "min": float(finite.min()) if finite.size else None,
        "max": float(finite.max()) if finite.size else None, "nonzero": int(np.count_nonzero(a)),
        "voxels": int(a.size), "direction": np.asarray(v.direction).tolist(),
    }
    if series:
        info["series"] = [{k: s[k] for k in ("uid", "description", "modality", "dims")} | {"slices": len(s["files"])}
                          for s in series]
    if a.dtype.kind in "iu" and a.size and int(a.max()) - int(a.min()) <= 255:
        values, counts = np.unique(a, return_counts=True)
        info["values"] = {int(k): int(c) for k, c in zip(values, counts)}
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        x, y, z = v.dims
        print(f"{args.file}\n  {x} x {y} x {z} {a.dtype}, spacing {v.spacing}, origin {v.origin}\n"
              f"  values {info['min']} .. {info['max']}, {info['nonzero']:,} non-zero of {a.size:,} voxels")
        if not v.axis_aligned:
            print("  direction (LPS, columns x y z): " + np.array2string(np.asarray(v.direction), precision=4))
        if "values" in info and len(info["values"]) <= 40:
            print("  labels: " + ", ".join(f"{k}: {c:,}" for k, c in info["values"].items()))
        if series:
            _print_series(series)
    return 0


def cmd_skeletonize(args) -> int:
    from .files import atomic_output
    t = time.perf_counter()
    args.voxel_size = None
    mask, sk, pts = _mask_and_skeleton(args)
    elapsed = time.perf_counter() - t
    out = args.output
    _check_output(out, ".npz")
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
    from .pipeline import Segmentation, load_mask, skeleton_of, skeleton_points, thinness_from_voxels
    seg = Segmentation(lo=args.lo, hi=args.hi, labels=args.labels, largest=args.largest)
    mask = load_mask(args.file, seg, voxel_size=args.voxel_size,
                     voxelize_method=getattr(args, "voxelize", "auto"), **_hints(args))
    bars = StepBars() if _show_progress(args) else None
    sk = skeleton_of(mask, args.metric, progress=bars)
    if bars is not None:
        bars.close()
    thinness = args.thinness
    if thinness is None and args.count is None:  # the add-on's and rig_mesh's default: half a voxel
        thinness = thinness_from_voxels(DEFAULT_THINNESS_VOXELS, sk.metric, mask.spacing)
    return mask, sk, skeleton_points(sk, thinness=thinness, count=args.count)


def _rigid(args):
    """The rigid tissue of ``--rigid-labels`` / ``--rigid-range`` (``volrig.rigid_tissue`` of the volume), or None."""
    from .rig import rigid_tissue
    if args.rigid_labels is None and args.rigid_range is None:
        return None
    if args.voxel_size is not None:
        raise VolrigError("--rigid-labels / --rigid-range: a mesh has no tissue values")
    source = _load(args)
    out = rigid_tissue(source, labels=args.rigid_labels, value_range=args.rigid_range)
    if not out.array.any():
        raise VolrigError("rigid tissue: no voxel has the given " + ("labels" if args.rigid_labels else "values"))
    return out


def _bone(args, rigid):
    """The bone tissue whose articulations place the limb joints: ``--bone-labels`` / ``--bone-range`` of the volume,
    else the rigid tissue (``--rigid-labels`` / ``--rigid-range``), else None (the rig from the outer shape)."""
    from .rig import rigid_tissue
    if args.bone_labels is None and args.bone_range is None:
        return rigid
    if args.voxel_size is not None:
        raise VolrigError("--bone-labels / --bone-range: a mesh has no tissue values")
    out = rigid_tissue(_load(args), labels=args.bone_labels, value_range=args.bone_range)
    if not out.array.any():
        raise VolrigError("bone: no voxel has the given " + ("labels" if args.bone_labels else "values"))
    return out


def _bone_summary(rig) -> str:
    """'; bones moved hip.L 12 mm, knee.L 8 mm, ... (kept: wrist.R)' for the rig's bone joints, or ''."""
    if rig.bone_joints is None:
        return ""
    moved = [f"{j.name} {j.shift:.0f}" for j in rig.bone_joints if j.moved]
    kept = [j.name for j in rig.bone_joints if not j.moved]
    return (f"; from the bones: {', '.join(moved) or 'no joint'} moved (world units)"
            + (f", kept {', '.join(kept)}" if kept else ""))


def _read_markers(path: str) -> dict:
    """--markers: a JSON object {name: [x, y, z]} (volrig.MARKER_NAMES; the volume's world frame)."""
    import json
    try:
        with open(path) as f:
            data = json.load(f)
    except ValueError as e:
        raise VolrigError(f"{path}: not JSON ({e})") from None
    if not isinstance(data, dict) or not all(isinstance(v, list) and len(v) == 3 for v in data.values()):
        raise VolrigError(f'{path}: markers must be a JSON object of name -> [x, y, z], e.g. {{"chin": [0, 10, 170]}}')
    return data


def cmd_rig(args) -> int:
    from .pipeline import describe_rig, parse_up, rig_skeleton
    from .rigfile import save_rig
    _check_output(args.output, ".vrig")
    t = time.perf_counter()
    mask, sk, pts = _mask_and_skeleton(args)
    rigid = _rigid(args)
    r = rig_skeleton(pts, mask, alpha=args.alpha, max_edge=args.max_edge, bones=args.bones, roles=not args.no_roles,
                     bind_mode=args.bind, progress=StepBars() if _show_progress(args) else None, source=args.file,
                     kind=args.kind, up=parse_up(args.up) if args.up else None, own_scale=not args.rig_kept_points,
                     rigid=rigid, bone=_bone(args, rigid),
                     markers=_read_markers(args.markers) if args.markers else None)
    save_rig(args.output, r.points, r.tree, r.rig, r.binding, source=r.source)
    rig = r.rig
    print(f"{len(pts):,} skeleton points, tree of {r.tree.component_count} part(s), {describe_rig(rig)}: {len(rig)} "
          f"bones ({', '.join(rig.names[:8])}{', ...' if len(rig) > 8 else ''}), {args.bind} binding; "
          f"{time.perf_counter() - t:.1f} s -> {args.output}{_bone_summary(rig)}")
    return 0


def _mocap_matrices(args, step: int = 1, binding: bool = False):
    """What ``animate`` and ``bake-mocap`` share: the rig file, the clip, the BVH frames (0-based; every ``step``-th
    from the clip's first), the bone map and the (F, B, 4, 4) rest-to-pose matrices of those frames."""
    from .mocap import load_bone_map, read_bvh
    from .pipeline import clip_frames, load_rigged, mocap_poses
    saved = load_rigged(args.rig, binding=binding)
    motion = read_bvh(args.clip)
    frames = clip_frames(motion.frame_count, args.frames or "", step, what=os.path.basename(args.clip))
    bone_map, matrices = mocap_poses(saved.rig, motion, frames, load_bone_map(args.map) if args.map else None,
                                     root_motion=args.root, up_axis=args.up, scale=args.scale)
    return saved, motion, frames, bone_map, matrices


def cmd_animate(args) -> int:
    from .files import atomic_output
    from .mocap import save_bone_map
    _check_output(args.output, ".npz")
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


def _tissues(path: str, source):
    """The tissue classes of a label map (``volrig.tissue_classes`` of the table at ``path``, the codes present)."""
    from .tissues import codes_present, read_tissue_table, tissue_classes
    tissues = tissue_classes(read_tissue_table(path), present=codes_present(source.array))
    if not tissues:
        raise VolrigError(f"{path}: none of its tissue codes is in the volume")
    sys.stderr.write("tissues: " + ", ".join(f"{t.name} ({len(t.codes)})" for t in tissues) + "\n")
    return tissues


def cmd_bake_mocap(args) -> int:
    from .pipeline import BakeRate, FolderBake, frame_file, sequence_number
    t = time.perf_counter()
    if args.tissues and args.sampling != "nearest":
        raise VolrigError("--tissues needs the label map's own codes: add --sampling nearest")
    source = _load(args)
    saved, motion, frames, bone_map, matrices = _mocap_matrices(args, args.step, binding=True)
    stem = args.name or os.path.basename(args.file).split(".")[0] or "volume"
    tissues = _tissues(args.tissues, source) if args.tissues else ()
    todo = [(f, m) for f, m in zip(frames, matrices)
            if not (args.skip_existing and os.path.exists(frame_file(args.output, stem, sequence_number(f, args.step))))]
    bake = FolderBake(source, saved.points, saved.binding, args.output, stem, mode=args.mode, sampling=args.sampling,
                      tissues=tissues, keep_volume=not args.plain_blend,
                      lattice_tables=args.lattice_tables, frames=len(todo))
    rate = BakeRate(len(todo))
    tqdm = _tqdm() if _show_progress(args) else None
    bar = tqdm(total=len(todo), desc="bake-mocap", unit="frame", file=sys.stderr) if tqdm else None

    def say(line: str) -> None:
        if bar is not None:
            bar.write(line, file=sys.stderr)
        else:
            sys.stderr.write(line + "\n")
            sys.stderr.flush()

    try:
        for k, (f, m) in enumerate(zip(frames, matrices)):
            path = bake.path(sequence_number(f, args.step))
            head = f"bake-mocap: {k + 1}/{len(frames)} BVH frame {f + 1}: "
            if args.skip_existing and os.path.exists(path):
                say(head + f"{path} exists, skipped")
                continue
            started = time.perf_counter()
            stats = bake.bake(sequence_number(f, args.step), m)
            rate.tick()
            say(head + f"{stats['covered']:,} voxels, {time.perf_counter() - started:.2f} s -> {path}"
                + ("" if bar is not None else f"  {rate.bar()}"))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        bake.finish()
    written = rate.done
    print(f"{written} of {len(frames)} frames (BVH {frames[0] + 1}-{frames[-1] + 1} step {args.step} of "
          f"{motion.frame_count}, {motion.fps / args.step:.4g} fps) x {len(saved.rig)} bones, {len(bone_map)} mapped, "
          f"{args.root}, {args.mode}; {time.perf_counter() - t:.1f} s -> {args.output}")
    return 0


def _tqdm():
    """tqdm (Debian's python3-tqdm, which scripts/setup installs), or None: the bars are then plain lines."""
    try:
        from tqdm import tqdm
        return tqdm
    except ImportError:
        return None


class StepBars:
    """A pipeline StepProgress (``progress(step, fraction) -> bool``) on stderr: one tqdm bar per step
    (skeletonize, skeleton-tree, autorig, bind), in percent; without tqdm one line per step, rewritten in place."""

    def __init__(self, file=None):
        self.file = file or sys.stderr
        self.tqdm = _tqdm()
        self.step, self.bar = None, None
        self.finished = None  # the step last seen at 100% (steps may report their end twice)

    def __call__(self, step: str, f: float) -> bool:
        f = min(max(float(f), 0.0), 1.0)
        if step == self.finished:
            return True
        self.finished = None
        if step != self.step:
            self.close()
            self.step = step
            if self.tqdm is not None:
                self.bar = self.tqdm(total=100, desc=step, unit="%", file=self.file, leave=True,
                                     bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}")
        if self.bar is not None:
            self.bar.n = round(100 * f, 1)
            self.bar.refresh()
        else:
            self.file.write(f"\r{step}: {100 * f:5.1f}%")
            self.file.flush()
        if f >= 1.0:
            self.close()
            self.finished = step
        return True

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.step is not None:
            self.file.write("\n")
            self.file.flush()
        self.step, self.bar = None, None


def _show_progress(args) -> bool:
    """--progress, or stderr is a terminal."""
    return bool(getattr(args, "progress", False)) or sys.stderr.isatty()


#: Runs inside Blender for ``bake`` and ``flythrough``: puts the folders found for volrig and the add-on first on
#: sys.path, enables the add-on (``volrig_addon``, else the Blender 4.2+ extension ``bl_ext.<repo>.volrig``) and hands
#: over to its headless entry (``<add-on>.<module>.command_line``: bake, flythrough), which does the work and exits
#: 0, or 2 with a message for a user error.
_BOOTSTRAP = """
import os, sys
sys.path[:0] = {paths!r}
import addon_utils
addon_utils.enable("volrig_addon", default_set=False)
try:
    from volrig_addon import {module}
except ImportError as e:
    # Blender 4.2+: the volrig extension (bl_ext.<repository>.volrig), when installed
    import importlib
    ext = sorted(m.__name__ for m in addon_utils.modules()
                 if m.__name__.startswith("bl_ext.") and m.__name__.rsplit(".", 1)[-1] == "volrig")
    if not ext:
        print("error: the volrig add-on is not installed in this Blender (" + str(e) + "): install the add-on zip "
              "or the extension, or pass --addon", file=sys.stderr)
        sys.stderr.flush()
        os._exit(2)
    addon_utils.enable(ext[0], default_set=False)
    {module} = importlib.import_module(ext[0] + ".{module}")
{module}.command_line()
"""


def addon_folder(addon: str = "", unpack_to: str = "") -> str:
    """The folder holding the ``volrig_addon`` package for Blender's sys.path: ``addon`` (that folder, the package
    folder itself, or the add-on zip, unpacked into ``unpack_to``), else where Python finds an installed
    ``volrig_addon`` (on PYTHONPATH or in site-packages); "" when neither, leaving it to Blender's installed
    add-ons."""
    import importlib.util
    if addon:
        if addon.lower().endswith(".zip") and os.path.isfile(addon):
            import zipfile
            with zipfile.ZipFile(addon) as z:
                z.extractall(unpack_to)
            addon = unpack_to
        if os.path.isfile(os.path.join(addon, "__init__.py")) and os.path.basename(os.path.normpath(addon)) == \
                "volrig_addon":
            return os.path.dirname(os.path.abspath(addon))
        if not os.path.isfile(os.path.join(addon, "volrig_addon", "__init__.py")):
            raise FileNotFoundError(f"{addon}: neither the add-on zip nor a folder holding volrig_addon")
        return os.path.abspath(addon)
    spec = importlib.util.find_spec("volrig_addon")
    return os.path.dirname(os.path.dirname(spec.origin)) if spec is not None and spec.origin else ""


def _run_blender(args, module: str, payload: dict, blend: str = "") -> int:
    """Runs Blender headless on ``blend`` (or an empty scene) with the add-on's ``module``.command_line and the
    JSON ``payload``; returns Blender's exit code."""
    import shutil
    import subprocess
    import tempfile
    blender = args.blender or os.environ.get("BLENDER") or shutil.which("blender")
    if not blender:
        raise FileNotFoundError("blender not found: install it (apt-get install blender) or pass --blender PATH")
    with tempfile.TemporaryDirectory(prefix="volrig_addon_") as unpacked:
        found = addon_folder(args.addon or "", unpacked)
        package_parent = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # this volrig, for the add-on
        paths = [package_parent] + ([found] if found else [])
        cmd = [blender, "-b", "--factory-startup"] + ([os.path.abspath(blend)] if blend else []) + \
            ["--python-exit-code", "1", "--python-expr", _BOOTSTRAP.format(paths=paths, module=module), "--",
             json.dumps(payload)]
        return subprocess.run(cmd).returncode


def cmd_bake(args) -> int:
    if not os.path.isfile(args.blend):
        raise FileNotFoundError(f"{args.blend}: no such file")
    return _run_blender(args, "bake", {"frames": args.frames or "", "objects": args.object or [],
                                       "mode": args.mode or "", "force": args.force, "save": not args.no_save},
                        args.blend)


def cmd_flythrough(args) -> int:
    _check_output(args.output, ".blend")
    if not os.path.isfile(args.file):
        raise FileNotFoundError(f"{args.file}: no such file")
    if (args.start is None) != (args.end is None):
        raise VolrigError("--start and --end go together (or leave both out: automatic ends)")
    if not args.frames_per_mm > 0:
        raise VolrigError(f"--frames-per-mm must be positive, got {args.frames_per_mm}")
    if args.frames is not None and not args.render:
        raise VolrigError("--frames needs --render DIR")
    return _run_blender(args, "flythrough", {
        "file": os.path.abspath(args.file), "lo": args.lo, "hi": args.hi, "labels": args.labels,
        "largest": not args.all_parts, "start": args.start, "end": args.end, "frames_per_mm": args.frames_per_mm,
        "look_ahead": args.look_ahead, "output": os.path.abspath(args.output),
        "render": os.path.abspath(args.render) if args.render else "", "frames": args.frames or 3,
        "resolution": args.resolution, "samples": args.samples})


def cmd_centerline(args) -> int:
    from .centerline import centerline, centerline_tree
    from .files import atomic_output
    from .pipeline import Segmentation
    _check_output(args.output, ".csv")
    if args.tree and (args.start or args.end):
        raise VolrigError("--tree takes --root, not --start / --end")
    seg = Segmentation(lo=args.lo, hi=args.hi, labels=args.labels, largest=args.largest)  # default: non-zero
    t = time.perf_counter()
    mask = seg.mask(_load(args), name=args.file)
    loaded = time.perf_counter() - t
    t = time.perf_counter()
    if args.tree:
        tree = centerline_tree(mask, root=args.root, step=args.step)
        lines = list(zip(range(len(tree)), tree.parents, tree.generations, tree.branches))
    else:
        lines = [(0, -1, 0, centerline(mask, start=args.start, end=args.end, step=args.step))]
    elapsed = time.perf_counter() - t
    with atomic_output(args.output, suffix=".csv") as tmp, open(tmp, "w") as f:
        f.write("branch,parent,generation,index,x,y,z,radius,arc_length\n")
        for b, parent, gen, line in lines:
            for k, (p, r) in enumerate(zip(line.points, line.radii)):
                f.write(f"{b},{parent},{gen},{k},{p[0]:.6g},{p[1]:.6g},{p[2]:.6g},{r:.6g},{k * line.step:.6g}\n")
    total = sum(line.length for *_, line in lines)
    print(f"{len(lines)} branch(es), {sum(len(line) for *_, line in lines):,} points, length {total:.1f}; "
          f"loaded in {loaded:.2f} s, centerline{' tree' if args.tree else ''} in {elapsed:.2f} s -> {args.output}")
    return 0


def _timed_on_mask(args, step: str, compute, **options):
    """(the segmented mask, ``compute(mask, **options, progress=...)``, its seconds): thickness and medial, with a
    progress bar for ``step`` when --progress or on a terminal."""
    from .pipeline import Segmentation
    seg = Segmentation(lo=args.lo, hi=args.hi, labels=args.labels, largest=args.largest)
    mask = seg.mask(_load(args), name=args.file)
    t = time.perf_counter()
    bars = StepBars() if _show_progress(args) else None
    result = compute(mask, **options, progress=(lambda f: bars(step, f)) if bars else None)
    if bars is not None:
        bars.close()
    return mask, result, time.perf_counter() - t


def cmd_thickness(args) -> int:
    from .medial import local_thickness
    from .volume import format_of
    if format_of(args.output) not in ("nrrd", "metaimage", "vdb"):
        raise VolrigError(f"{args.output}: the output must be .nrrd, .mha or .vdb")
    mask, thick, elapsed = _timed_on_mask(args, "local thickness", local_thickness)
    thick.save(args.output, grid="thickness")
    values = thick.array[mask.array != 0]
    if values.size:
        q = np.percentile(values, [5, 50, 95])
        summary = f"thickness 5/50/95%: {q[0]:.3g} / {q[1]:.3g} / {q[2]:.3g}, max {values.max():.3g}"
    else:
        summary = "empty mask"
    print(f"{values.size:,} object voxels; {summary} (world units); local thickness in {elapsed:.2f} s "
          f"-> {args.output}")
    return 0


def cmd_medial(args) -> int:
    from .medial import medial_surface
    _check_output(args.output, ".ply", any_case=True, what=".ply")
    _, ms, elapsed = _timed_on_mask(args, "medial surface", medial_surface, t=args.t)
    ms.save_ply(args.output)
    med = f"median thickness {np.median(ms.thickness):.3g}, " if len(ms.thickness) else ""
    print(f"{len(ms.faces):,} triangles, area {ms.area:.4g}, {med}{len(ms.rods):,} rods (world units); medial "
          f"surface in {elapsed:.2f} s -> {args.output}")
    return 0


def _contact_poses(saved, clip_path, args, frames=None):
    """(F, B, 4, 4) poses of a rig driven by a clip (or the rest pose held for `frames`, or one frame)."""
    from .mocap import load_bone_map, read_bvh
    from .pipeline import clip_frames, mocap_poses
    if clip_path is None:
        return np.repeat(np.eye(4)[None, None], 1 if frames is None else len(frames), axis=0).repeat(
            len(saved.rig), axis=1), frames if frames is not None else [0]
    motion = read_bvh(clip_path)
    if frames is None:
        frames = clip_frames(motion.frame_count, args.frames or "", args.step, what=os.path.basename(clip_path))
    _, matrices = mocap_poses(saved.rig, motion, frames, load_bone_map(args.map) if args.map else None,
                              root_motion=args.root, up_axis=args.up, scale=args.scale)
    return matrices, frames


def cmd_contacts(args) -> int:
    from .collide import Collider, collisions
    from .pipeline import load_rigged
    rigs = [f for f in args.files if f.endswith(".vrig")]
    clips = [f for f in args.files if f.endswith(".bvh")]
    other = [f for f in args.files if f not in rigs and f not in clips]
    if other or not 1 <= len(rigs) <= 2 or len(clips) > len(rigs):
        raise VolrigError("give one or two rig files (.vrig) and at most one clip (.bvh) per rig, e.g. "
                          "`volrig contacts a.vrig b.vrig walk.bvh ball.bvh`" + (f"; not understood: {other}" if other else ""))
    t = time.perf_counter()
    saved = [load_rigged(r, binding=True) for r in rigs]
    colliders = [Collider(s.points, s.binding, s.rig) for s in saved]
    poses_a, frames = _contact_poses(saved[0], clips[0] if clips else None, args)
    options = dict(mode=args.mode)
    if len(rigs) == 2:
        clip_b = clips[1] if len(clips) == 2 else None
        poses_b, _ = _contact_poses(saved[1], clip_b, args, frames)
        if len(poses_b) != len(poses_a):
            raise VolrigError(f"the clips give {len(poses_a)} and {len(poses_b)} frames: use --frames within both")
        found = collisions(colliders[0], poses_a, colliders[1], poses_b, frames=[f + 1 for f in frames],
                           **options)
    else:
        found = collisions(colliders[0], poses_a, frames=[f + 1 for f in frames], min_bone_distance=args.min_distance,
                           **options)
    elapsed = time.perf_counter() - t
    what = f"{rigs[0]} and {rigs[1]}" if len(rigs) == 2 else f"{rigs[0]} against itself"
    for c in found.contacts:
        span = f"frame {c.first}" if c.first == c.last else f"frames {c.first}-{c.last}"
        print(f"{span}: {', '.join(f'{x}/{y}' for x, y in c.bone_pairs)} (most {c.voxels:,} voxels, frame "
              f"{c.peak_frame})")
    print(f"{len(found.hit_frames)} of {len(frames)} frames in contact ({what}, {args.mode}); "
          f"{elapsed:.2f} s with loading")
    return 0


def cmd_inflate(args) -> int:
    from .drawing import MAX_VOXELS, write_drawing_vdb
    _check_output(args.output, ".vdb", any_case=True)
    t = time.perf_counter()
    mask = write_drawing_vdb(args.output, args.drawing, pixel_size=args.pixel_size, depth_scale=args.depth_scale,
                             stroke_width=args.stroke_width, gap=args.gap, resolution=args.resolution,
                             max_voxels=args.max_voxels or MAX_VOXELS)
    x, y, z = mask.dims
    print(f"{args.drawing}: {int(mask.array.sum()):,} voxels in {x} x {y} x {z} (spacing {mask.spacing[0]:g}; up +z, "
          f"depth +y) with its colours, in {time.perf_counter() - t:.2f} s -> {args.output}")
    return 0


def cmd_track(args) -> int:
    from .files import atomic_output
    from .track import track
    from .volume import write_vdb
    if args.output:
        _check_output(args.output, ".json")
    t = time.perf_counter()
    tr = track(args.steps, lo=args.lo, hi=args.hi, thinness=args.thinness, min_size=args.min_size,
               tolerance=args.tolerance)
    counts = ", ".join(f"{n} {k}" for k, n in tr.event_counts().items() if n)
    print(f"{args.steps}: {tr.steps} steps, {sum(len(v) for v in tr.volumes)} features, {tr.track_count} tracks; "
          f"events: {counts or 'none'} ({time.perf_counter() - t:.2f} s)")
    for e in tr.events:
        if e.kind != "continuation":
            print(f"  step {e.step} -> {e.step + 1}: {e.kind} {list(e.before)} -> {list(e.after)}")
    if args.output:
        with atomic_output(args.output) as tmp, open(tmp, "w") as f:
            json.dump(tr.to_dict(), f, indent=1)
        print(f"-> {args.output}")
    if args.vdb:
        os.makedirs(args.vdb, exist_ok=True)
        for s in range(tr.steps):
            write_vdb(os.path.join(args.vdb, f"track_{s:04d}.vdb"), {"track": tr.track_volume(s)},
                      spacing=tr.spacing, origin=tr.origin)
        print(f"-> {args.vdb}/track_0000.vdb .. track_{tr.steps - 1:04d}.vdb")
    return 0


def cmd_demo(args) -> int:
    from .demo import run_demo
    run_demo(args.output, scale=args.scale, thinness=args.thinness)
    return 0



def _pore_mask(args):
    """The pore mask and its voxel size of ``volrig pores``: an .npz's array (--key), else any volume volrig reads
    (raw with --shape as numpy's C-order shape, or --dims X Y Z), non-zero = pore (--invert: zero = pore)."""
    from .volume import Volume
    if args.file.lower().endswith(".npz"):
        with np.load(args.file) as z:
            if args.key not in z.files:
                raise VolrigError(f"{args.file}: no array {args.key!r} (it holds {', '.join(z.files)}); pass --key")
            arr = z[args.key]
        spacing = None
    else:
        if args.shape is not None:
            if args.dims is not None:
                raise VolrigError("pass --shape (numpy's order, slowest axis first) or --dims X Y Z, not both")
            args.dims = list(reversed(args.shape))
            args.dtype = args.dtype or "uint8"
        v = _load(args)
        arr, spacing = v.array, v.spacing
    mask = (arr == 0) if args.invert else (arr != 0)
    voxel = args.voxel if args.voxel is not None else (spacing if spacing is not None else 1.0)
    return Volume(mask, tuple(np.broadcast_to(np.asarray(voxel, float), (3,))), (0.0, 0.0, 0.0)), voxel


def cmd_pores(args) -> int:
    from .pores import AXES, pore_network
    if not args.output.lower().endswith((".npz", ".csv")):
        raise VolrigError(f"{args.output}: the output must be .npz or .csv")
    mask, voxel = _pore_mask(args)
    t = time.perf_counter()
    bars = StepBars() if _show_progress(args) else None
    net = pore_network(mask, voxel=voxel, model=args.model,
                       progress=(lambda f: bars("pore network", f)) if bars else None)
    if bars is not None:
        bars.close()
    elapsed = time.perf_counter() - t
    written = net.save(args.output)
    print(f"porosity {net.porosity:.4f}; {net.pore_count:,} pores, {net.throat_count:,} throats, mean coordination "
          f"{net.coordination.mean() if net.pore_count else 0:.2f}; network in {elapsed:.2f} s")
    for a in range(3):
        k = net.permeability[a]
        perm = f"{k:.4g} m² ({net.permeability_md[a]:.4g} mD)" if k > 0 else "0 (no path joins the two faces)"
        print(f"  {AXES[a]}: permeability {perm}, formation factor {net.formation_factor[a]:.4g}")
    print("-> " + ", ".join(str(p) for p in written))
    return 0

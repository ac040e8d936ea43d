#!/usr/bin/env python3
"""Benchmark: bake throughput (issue 17), every figure with its reference measured in the same run.

On the humanoid phantom at --scale with its automatic rig (smooth binding, `pipeline.rig_skeleton`, as
bench_bake), prints:
  * frames: the rigid frame of the walking stride (bench_deform.walking_pose) with the bones' lattice tables
    built (the reference), the dual-quaternion and linear frames with them, and the rigid, dual-quaternion and
    linear frames without them (the bones' powers from the balls meeting each preimage: what a bake draws, and a
    Deformer for its first Deformer.LATTICE_AFTER frames after a rig change), best of --repeat each, run alternately; whether
    each smooth frame equals the brute-force scatter (volrig.deform_reference) voxel for voxel (skipped with
    --no-reference);
  * rig changes: what the first frame after one builds (the best of --repeat fresh Deformers' first frames less
    the best frame): the k-d trees (lattice_after=-1) and the lattice tables (lattice_after=0), rigid and smooth;
    and after a local repaint (every other point of one bone bound to it alone, `Binding.reassign`, then
    `Deformer.rebind`: only the fields whose spheres changed are rebuilt, with their tables);
  * a whole bake: --bake-frames frames of CMU 131_01 through pipeline.FolderBake (each VDB written on its own
    thread while the next frame computes) in --bake-mode, against the sum of its own deformation times, and the
    frames per second;
  * whether a bake's lattice tables pay: --pay-frames frames of CMU 131_01 as a bake draws them (8³ bricks, half
    floats) by a Deformer with the tables (lattice_after=0) and one without (-1), frame by frame alternately, in
    each of the three modes: the mean frame time with the tables over that without, and the tables' memory per
    source voxel (a bake builds none unless asked, `FolderBake(..., lattice_tables=True)`);
  * memory: the peak resident size of a child process baking --memory-frames frames as a bake does by default
    (without the bones' lattice tables), less that of the same child stopping before the bake (source, rig and
    matrices loaded), per source voxel; and the same bake with the tables from its first frame (lattice_after=0:
    a long bake asked for them, `FolderBake(..., lattice_tables=True)`).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_throughput.py [--scale 1] [--repeat 3] [--bake-frames 240]
Targets (issue 17, scale 1, 2 cores): smooth frames within 1.5x of rigid and equal to the brute force; a rig
change <= 0.5 s; bake <= 1.3x the sum of its deformation times; peak memory <= 3 bytes per source voxel above the source.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
PYTHON_DIR = os.path.join(HERE, "..", "python")
sys.path.insert(0, PYTHON_DIR)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root

import volrig  # noqa: E402
from volrig import phantom, pipeline  # noqa: E402
from volrig.deform import MODES  # noqa: E402
from bench_bake import timed_folder_bake  # noqa: E402  (this folder is on sys.path when run as a script)
from bench_deform import walking_pose  # noqa: E402
from volrig_support import data_root  # noqa: E402

CLIP = str(data_root() / "bvh" / "131_01.bvh")
SMOOTH = ("dual_quaternion", "linear")

# A child process's peak resident size (VmHWM): the source and rig loaded, the matrices read, then (with "bake") a
# FolderBake over them. Prints {"peak_bytes": ...}.
MEMORY_CHILD = r"""
import json, sys, tempfile
import numpy as np
sys.path.insert(0, sys.argv[1])
import volrig
from volrig import pipeline
source = volrig.Volume(np.load(sys.argv[2]), json.loads(sys.argv[3]))
rigged = volrig.load_rig(sys.argv[4])
matrices = np.load(sys.argv[5])
if sys.argv[7] == "bake":
    with tempfile.TemporaryDirectory() as folder:
        bake = pipeline.FolderBake(source, rigged.points, rigged.binding, folder, "m", mode=sys.argv[6],
                                   lattice_after=json.loads(sys.argv[8]))
        for k, m in enumerate(matrices, start=1):
            bake.bake(k, m)
        bake.finish()
# VmHWM, not getrusage's ru_maxrss: that one keeps the parent's size from before the exec.
with open("/proc/self/status") as f:
    hwm = next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
print(json.dumps({"peak_bytes": hwm * 1024}))
"""


# The two ways a Deformer's bones take their powers: from lattice tables built once per rig (what frames reach after
# Deformer.lattice_after frames without a rig change; 0: at once) or from the balls meeting each preimage (-1: never).
TABLES = {"tables": 0, "balls": -1}
PREFIX = {"tables": "", "balls": "balls_"}  # of their figures' keys


def frames(vol, rigged, repeat: int, reference: bool) -> dict:
    """Frames with and without lattice tables, smooth against rigid; the per-rig builds; the brute-force check."""
    M = walking_pose(rigged.rig)
    out = {}
    deformers, first = {}, {}
    for tables, after in TABLES.items():
        for name, mode in (("rigid", "rigid"), ("smooth", "linear")):
            key = (tables, name)
            first[key] = float("inf")
            for _ in range(repeat):  # fresh Deformers: the best first frame (the build moves with the machine's drift)
                deformers[key] = None  # the previous one's tables go first
                deformers[key] = volrig.Deformer(vol, rigged.points, rigged.binding, lattice_after=after)
                t = time.perf_counter()
                deformers[key].frame(M, mode=mode)
                first[key] = min(first[key], time.perf_counter() - t)
    best = {(t, m): float("inf") for t in TABLES for m in ("rigid",) + SMOOTH}
    kept = {}
    for k in range(repeat):  # alternately, so that the machine's drift hits every mode alike
        for tables, mode in best:
            d = deformers[(tables, "rigid" if mode == "rigid" else "smooth")]
            t = time.perf_counter()
            f = d.frame(M, mode=mode)
            best[(tables, mode)] = min(best[(tables, mode)], time.perf_counter() - t)
            if k == repeat - 1 and mode != "rigid":  # (only then: a frame kept alive holds its memory, and the next
                kept[(tables, mode)] = f             # frame of its Deformer would fault in fresh pages)
            del f
    reference_frame = best[("tables", "rigid")]
    for (tables, mode), v in best.items():
        out[f"{PREFIX[tables]}{mode}_frame_s"] = v
        out[f"{PREFIX[tables]}{mode}_ratio"] = v / reference_frame
    for (tables, mode), f in kept.items():
        out[f"{PREFIX[tables]}{mode}_exact_sub_blocks"] = f.stats["exact_sub_blocks"]
    for tables in TABLES:
        for name, mode in (("rigid", "rigid"), ("smooth", "linear")):
            out[f"{PREFIX[tables]}{name}_build_s"] = first[(tables, name)] - best[(tables, mode)]
            out[f"{PREFIX[tables]}{name}_tables_mb"] = deformers[(tables, name)].memory_bytes / 1e6
    if reference:
        for (tables, mode), f in list(kept.items()):
            t = time.perf_counter()
            ref = volrig.deform_reference(vol, rigged.points, rigged.binding, M, mode=mode, like=f)
            out[f"{PREFIX[tables]}{mode}_brute_force_s"] = time.perf_counter() - t
            out[f"{PREFIX[tables]}{mode}_equals_brute_force"] = bool(
                np.array_equal(ref.bone.array, f.bone.array) and np.array_equal(ref.values.array, f.values.array))
            del f, ref
    kept.clear()  # their memory back to the Deformers before the repaint's frame
    for key in [k for k in deformers if k[0] == "balls"]:
        deformers.pop(key)
    out.update(repaint(deformers[("tables", "smooth")], rigged.binding, M, best[("tables", "linear")]))
    return out


def repaint(d, binding, M, best_frame: float) -> dict:
    """A local weight change: every other point of the bone with the median number of points bound to it alone;
    the rebuild after the rebind is the next frame less the best linear frame."""
    counts = np.bincount(binding.bone, minlength=len(binding.bone_names))
    b = int(np.argsort(counts)[len(counts) // 2])
    d.rebind(binding.reassign(binding.points_of(b)[::2], b))
    t = time.perf_counter()
    d.frame(M, mode="linear")
    return {"repaint_bone": binding.bone_names[b], "repaint_points": int((counts[b] + 1) // 2),
            "repaint_build_s": time.perf_counter() - t - best_frame, "repaint_kept_fields": d.reused_fields}


def bake(vol, rigged, matrices, mode: str) -> dict:
    """A FolderBake of the matrices, told how many (as `volrig bake-mocap` does), against the sum of its own
    deformation times (the per-rig build left out)."""
    with tempfile.TemporaryDirectory() as folder:
        fb, times = timed_folder_bake(vol, rigged, folder, mode, matrices[0], len(matrices))
        rate = pipeline.BakeRate(len(matrices))
        for k, m in enumerate(matrices, start=1):
            fb.bake(k, m)
            rate.tick()
            sys.stderr.write(f"\r  bake {rate.bar()}   ")
        fb.finish()
        wall = time.perf_counter() - rate.start
        sys.stderr.write("\n")
    total = sum(times)
    return {"bake_frames": len(matrices), "bake_deform_sum_s": total, "bake_wall_s": wall,
            "bake_ratio": wall / total, "bake_frames_per_s": len(matrices) / wall}


def tables_pay(vol, rigged, matrices) -> dict:
    """Bake-like frames (bricks, half floats) with and without the bones' lattice tables, alternately: the mean
    frame with them over that without, per mode; their memory per source voxel."""
    out = {"pay_frames": len(matrices)}
    for mode in MODES:
        ds = {t: volrig.Deformer(vol, rigged.points, rigged.binding, lattice_after=a) for t, a in TABLES.items()}
        for d in ds.values():  # the per-rig builds (and the tables) out of the way
            d.frame(matrices[0], mode=mode, bricks=True, half=True)
        total = dict.fromkeys(ds, 0.0)
        for m in matrices:
            for t, d in ds.items():
                start = time.perf_counter()
                f = d.frame(m, mode=mode, bricks=True, half=True)
                total[t] += time.perf_counter() - start
                del f
        out[f"pay_{mode}_tables_s"] = total["tables"] / len(matrices)
        out[f"pay_{mode}_balls_s"] = total["balls"] / len(matrices)
        out[f"pay_{mode}_ratio"] = total["tables"] / total["balls"]
        out[f"pay_{mode}_tables_bytes_per_voxel"] = ds["tables"].memory_bytes / vol.array.size
        del ds
    return out


def memory(vol, rigged, matrices, mode: str) -> dict:
    """Peak resident size of a baking child above the same child without the bake, per source voxel."""
    with tempfile.TemporaryDirectory() as tmp:
        paths = [os.path.join(tmp, n) for n in ("source.npy", "rig.npz", "matrices.npy")]
        np.save(paths[0], vol.array)
        volrig.save_rig(paths[1], rigged.points, rigged.tree, rigged.rig, rigged.binding)
        np.save(paths[2], np.asarray(matrices))
        peak = {}
        for what, after in (("load", None), ("bake", -1), ("tables", 0)):
            r = subprocess.run([sys.executable, "-c", MEMORY_CHILD, os.path.abspath(PYTHON_DIR), paths[0],
                                json.dumps(list(vol.spacing)), paths[1], paths[2], mode,
                                "load" if what == "load" else "bake", json.dumps(after)],
                               check=True, capture_output=True, text=True)
            peak[what] = json.loads(r.stdout.strip().splitlines()[-1])["peak_bytes"]
    voxels = vol.array.size
    out = {"memory_frames": len(matrices), "source_bytes_per_voxel": vol.array.itemsize,
           "peak_loaded_mb": peak["load"] / 1e6}
    for what, prefix in (("bake", ""), ("tables", "tables_")):
        out[f"{prefix}peak_bake_mb"] = peak[what] / 1e6
        out[f"{prefix}bake_bytes_per_source_voxel"] = (peak[what] - peak["load"]) / voxels
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--points", type=int, default=40000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-reference", action="store_true", help="skip the (slow) brute-force scatters")
    ap.add_argument("--bake-frames", type=int, default=240, help="BVH frames 1..N of CMU 131_01 (0: no bake)")
    ap.add_argument("--bake-mode", default="linear", choices=MODES)
    ap.add_argument("--pay-frames", type=int, default=24,
                    help="bake-like frames each mode draws with and without the lattice tables (0: skip)")
    ap.add_argument("--memory-frames", type=int, default=12, help="frames the memory child bakes (0: skip)")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    ph = phantom.humanoid(args.scale)
    vol = ph.volume
    mask = volrig.segment(vol)
    rigged = pipeline.rig_skeleton(volrig.skeletonize(mask).top(args.points), mask, up=(0, 0, 1))
    print(f"phantom scale {args.scale}: grid {vol.dims} ({vol.array.size:,} voxels), {len(rigged.points):,} "
          f"spheres, {len(rigged.rig)} bones, smooth binding")
    fig = frames(vol, rigged, args.repeat, not args.no_reference)
    n_clip = max(args.bake_frames, args.memory_frames, args.pay_frames)
    if n_clip and os.path.exists(CLIP):
        clip = volrig.read_bvh(CLIP)
        picked = pipeline.clip_frames(clip.frame_count, f"1-{min(n_clip, clip.frame_count)}", 1)
        _, matrices = pipeline.mocap_poses(rigged.rig, clip, picked)
        if args.bake_frames:
            fig.update(bake(vol, rigged, matrices[:args.bake_frames], args.bake_mode))
        if args.pay_frames:
            fig.update(tables_pay(vol, rigged, matrices[:args.pay_frames]))
        if args.memory_frames:
            fig.update(memory(vol, rigged, matrices[:args.memory_frames], args.bake_mode))
    elif n_clip:
        print(f"bake and memory skipped: {CLIP} is absent")

    rows = [("rigid frame with lattice tables, walking stride (reference)", f"{fig['rigid_frame_s']:.3f} s", "")]
    for tables, what in (("tables", "with lattice tables"), ("balls", "without (balls)")):
        prefix = PREFIX[tables]
        for mode in (("rigid",) if tables == "balls" else ()) + SMOOTH:
            rows.append((f"{mode.replace('_', '-')} frame {what}", f"{fig[prefix + mode + '_frame_s']:.3f} s",
                         f"{fig[prefix + mode + '_ratio']:.2f}x the reference" + (" (<= 1.5x)" if mode != "rigid" else "")))
            if prefix + mode + "_equals_brute_force" in fig:
                rows.append((f"  equal to the brute-force scatter ({fig[prefix + mode + '_brute_force_s']:.0f} s)",
                             str(fig[prefix + mode + "_equals_brute_force"]), "(must be True)"))
    for name in ("rigid", "smooth"):
        rows += [(f"rig change, {name}: k-d trees (frames without tables)", f"{fig['balls_' + name + '_build_s']:.2f} s",
                  f"{fig['balls_' + name + '_tables_mb']:.0f} MB (<= 0.5 s)"),
                 (f"  lattice tables, {name} (after {volrig.Deformer.LATTICE_AFTER} frames without a change)",
                  f"{fig[name + '_build_s']:.2f} s", f"{fig[name + '_tables_mb']:.0f} MB")]
    rows += [(f"  tables after repainting {fig['repaint_points']} points of {fig['repaint_bone']}",
              f"{fig['repaint_build_s']:.2f} s", f"{fig['repaint_kept_fields']} fields kept")]
    if "bake_wall_s" in fig:
        rows += [(f"sum of deformation times, {fig['bake_frames']} frames {args.bake_mode} (reference)",
                  f"{fig['bake_deform_sum_s']:.1f} s", ""),
                 ("whole bake, VDBs written", f"{fig['bake_wall_s']:.1f} s",
                  f"{fig['bake_ratio']:.2f}x (<= 1.3x), {fig['bake_frames_per_s']:.2f} frames/s")]
    if "pay_frames" in fig:
        for mode in MODES:
            rows.append((f"{fig['pay_frames']} bake frames {mode.replace('_', '-')}, with tables / without",
                         f"{fig[f'pay_{mode}_ratio']:.2f}x",
                         f"{fig[f'pay_{mode}_tables_s']:.3f} s / {fig[f'pay_{mode}_balls_s']:.3f} s; tables "
                         f"{fig[f'pay_{mode}_tables_bytes_per_voxel']:.1f} B/source voxel"))
    if "bake_bytes_per_source_voxel" in fig:
        rows += [(f"peak memory of a child baking {fig['memory_frames']} frames", f"{fig['peak_bake_mb']:.0f} MB",
                  f"the same child loaded only (reference): {fig['peak_loaded_mb']:.0f} MB"),
                 ("  per source voxel above the source", f"{fig['bake_bytes_per_source_voxel']:.1f} B",
                  f"source {fig['source_bytes_per_voxel']} B/voxel (<= 3 B above it)"),
                 ("  the same bake with lattice tables (lattice_tables=True)",
                  f"{fig['tables_bake_bytes_per_source_voxel']:.1f} B", f"{fig['tables_peak_bake_mb']:.0f} MB")]
    for name, value, note in rows:
        print(f"  {name:<62} {value:>10}   {note}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(fig, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Benchmark: per-frame sampled reconstruction (issue: the deformation engine).

Measures, in one run on this machine, on the humanoid phantom with --points skeleton points, its automatic rig
and a rigid binding, posed in a walking stride:
  * volrig.Deformer: the per-rig build (first frame) and the rigid frame (best of --repeat);
  * the reference: a plain trilinear inverse warp through one matrix onto the frame's output grid (one gather per
    output voxel, volrig.inverse_warp), and the ratio of the rigid frame to it;
  * the thesis' literal brute-force scatter (every moved sphere over its bounding box with a proximity buffer,
    sampling the source at every write, multithreaded over z slabs; volrig.deform_reference), once, and the
    speed-up over it (and that both agree voxel for voxel);
  * writing the frame's VDB (density as half floats + bone labels), best of --repeat;
  * the smooth modes (dual quaternion, linear) on a smooth binding, and the nearest-centre proximity, for the record.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_deform.py [--scale 1.0] [--points 40000] [--repeat 3]
Targets (scale 1: 290 x 169 x 940, ~40,000 spheres, ~20 bones, 2 cores): rigid frame <= 1.0 s and within 3x of the
inverse warp; >= 100x faster than the brute-force scatter; VDB write <= 0.5 s.
"""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402
from bench_rig import best_of  # noqa: E402  (this folder is on sys.path when run as a script)


def walking_pose(rig):
    """A stride: one thigh forward and one back, knees and elbows bent, arms swinging against the legs."""
    swing = [1, 0, 0]
    wanted = {"thigh.L": 25, "thigh.R": -20, "shin.L": -30, "shin.R": -10, "foot.L": 10,
              "upper_arm.L": -20, "upper_arm.R": 20, "forearm.L": 30, "forearm.R": 25, "spine": 5, "head": -8}
    return rig.pose({name: (swing, deg) for name, deg in wanted.items() if name in rig.names})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--points", type=int, default=40000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-reference", action="store_true", help="skip the (slow) brute-force scatter")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    ph = phantom.humanoid(args.scale)
    vol = ph.volume
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(args.points)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    rigid = volrig.bind(pts, rig, mask)
    M = walking_pose(rig)
    print(f"phantom scale {args.scale}: grid {vol.dims}, {int(mask.array.sum()):,} object voxels, {len(pts):,} spheres, "
          f"{len(rig)} bones ({rig.kind})")

    fig = {}
    t0 = time.perf_counter()
    d = volrig.Deformer(vol, pts, rigid, lattice_after=0)  # (frames with the bones' lattice tables: a bake's)
    d.frame(M)
    fig["build_and_first_frame_s"] = time.perf_counter() - t0
    fig["per_rig_memory_mb"] = d.memory_bytes / 1e6
    fig["rigid_frame_s"], frame = best_of(args.repeat, lambda: d.frame(M))
    fig["output_voxels"] = int(np.prod(frame.bone.dims))
    fig["covered_voxels"] = frame.stats["covered"]
    fig["exact_queries"] = frame.stats["exact_queries"]
    fig["decided_by"] = {k: frame.stats["by_" + k] for k in ("block", "cube", "sphere", "search")}
    fig["inverse_warp_s"], _ = best_of(args.repeat, lambda: volrig.inverse_warp(vol, M[0], like=frame))
    fig["ratio_to_warp"] = fig["rigid_frame_s"] / fig["inverse_warp_s"]
    fig["inverse_warp_source_grid_s"], _ = best_of(args.repeat, lambda: volrig.inverse_warp(vol, M[0]))
    fig["ratio_to_source_grid_warp"] = fig["rigid_frame_s"] / fig["inverse_warp_source_grid_s"]
    rest = volrig.rest_pose(len(rig))
    fig["rest_frame_s"], _ = best_of(args.repeat, lambda: d.frame(rest))
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "frame.vdb")
        fig["vdb_write_s"], _ = best_of(args.repeat, lambda: frame.save(path))
        fig["vdb_mb"] = os.path.getsize(path) / 1e6
    fig["nearest_proximity_frame_s"], _ = best_of(1, lambda: d.frame(M, proximity="nearest"))
    smooth = volrig.bind(pts, rig, mask, mode="smooth")
    ds = volrig.Deformer(vol, pts, smooth, lattice_after=0)
    ds.frame(M, mode="dual_quaternion")
    fig["dual_quaternion_frame_s"], f_dq = best_of(1, lambda: ds.frame(M, mode="dual_quaternion"))
    fig["linear_frame_s"], _ = best_of(1, lambda: ds.frame(M, mode="linear"))
    fig["blended_spheres"] = f_dq.stats["blended_spheres"]
    if not args.no_reference:
        fig["brute_force_s"], ref = best_of(1, lambda: volrig.deform_reference(vol, pts, rigid, M, like=frame))
        fig["speedup_over_brute_force"] = fig["brute_force_s"] / fig["rigid_frame_s"]
        fig["brute_force_agrees"] = bool(np.array_equal(ref.bone.array, frame.bone.array)
                                         and np.array_equal(ref.values.array, frame.values.array))

    print(f"output grid {frame.bone.dims} ({fig['output_voxels']:,} voxels), {fig['covered_voxels']:,} covered, "
          f"{fig['exact_queries']:,} exact queries; per-rig data {fig['per_rig_memory_mb']:.0f} MB")
    print("covered voxels decided by " + ", ".join(f"{k} {v / max(1, fig['covered_voxels']):.1%}"
                                                   for k, v in fig["decided_by"].items()))
    rows = [("Deformer build + first frame", fig["build_and_first_frame_s"], ""),
            ("rigid frame (power proximity)", fig["rigid_frame_s"], "<= 1.0 s"),
            ("inverse warp onto the same grid (reference)", fig["inverse_warp_s"], ""),
            ("  ratio rigid frame / inverse warp", fig["ratio_to_warp"], "<= 3x"),
            ("inverse warp of the source grid", fig["inverse_warp_source_grid_s"], ""),
            ("  ratio rigid frame / it", fig["ratio_to_source_grid_warp"], ""),
            ("rest-pose frame (most bone overlap)", fig["rest_frame_s"], ""),
            ("write the frame's VDB (half density + bone)", fig["vdb_write_s"], "<= 0.5 s"),
            ("rigid frame, nearest-centre proximity", fig["nearest_proximity_frame_s"], ""),
            ("dual-quaternion frame (smooth binding)", fig["dual_quaternion_frame_s"], ""),
            ("linear-blend frame (smooth binding)", fig["linear_frame_s"], "")]
    if "brute_force_s" in fig:
        rows += [("brute-force scatter (the thesis, 2 threads)", fig["brute_force_s"], ""),
                 ("  speed-up over it", fig["speedup_over_brute_force"], ">= 100x")]
    for name, value, target in rows:
        unit = "x" if "ratio" in name or "speed-up" in name else " s"
        if name.startswith("  ratio rigid frame / it"):
            name = "  ratio rigid frame / source-grid warp"
        print(f"  {name:<46} {value:9.3f}{unit}   {target}")
    if "brute_force_agrees" in fig:
        print(f"  brute force and deform agree voxel for voxel: {fig['brute_force_agrees']}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(fig, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

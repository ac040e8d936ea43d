#!/usr/bin/env python3
"""Benchmark: a whole mocap bake (issue 17), the way `volrig bake-mocap` runs it: FolderBake writes each frame's VDB
on its own thread while the next frame computes. Prints the bake's wall time against the sum of its frames'
deformation times measured in the same run (the target: at most 1.3x), and frames per second.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_bake.py [--scale 1.0] [--frames 48] [--mode rigid]
Needs ../shared/data/bvh/131_01.bvh (skips with a message without it).
"""
import argparse
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig import phantom, pipeline  # noqa: E402
from volrig.deform import MODES  # noqa: E402
from volrig_support import data_root  # noqa: E402


def timed_folder_bake(vol, rigged, folder: str, mode: str, first, frames=None):
    """A FolderBake of `frames` frames (when known, as `volrig bake-mocap` tells it) whose deformer's frames are
    timed: (bake, times). Its per-rig build (the first frame, `first`, baked as frame 0) is left out of `times`."""
    bake = pipeline.FolderBake(vol, rigged.points, rigged.binding, folder, "phantom", mode=mode, frames=frames)
    times = []
    frame = bake.deformer.frame

    def timed(*a, **k):
        t = time.perf_counter()
        f = frame(*a, **k)
        times.append(time.perf_counter() - t)
        return f

    bake.deformer.frame = timed
    bake.bake(0, first)
    bake.finish()
    times.clear()
    return bake, times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--points", type=int, default=40000)
    ap.add_argument("--frames", type=int, default=48, help="BVH frames 1..N of CMU 131_01")
    ap.add_argument("--mode", default="rigid", choices=MODES)
    args = ap.parse_args()
    clip_path = str(data_root() / "bvh" / "131_01.bvh")
    if not os.path.exists(clip_path):
        print(f"skipped: {clip_path} is absent")
        return 0
    ph = phantom.humanoid(args.scale)
    mask = volrig.segment(ph.volume)
    rigged = pipeline.rig_skeleton(volrig.skeletonize(mask).top(args.points), mask, up=(0, 0, 1))
    clip = volrig.read_bvh(clip_path)
    frames = pipeline.clip_frames(clip.frame_count, f"1-{args.frames}", 1)
    _, matrices = pipeline.mocap_poses(rigged.rig, clip, frames)
    with tempfile.TemporaryDirectory() as folder:
        bake, deform_times = timed_folder_bake(ph.volume, rigged, folder, args.mode, matrices[0], len(matrices))
        start = time.perf_counter()
        for k, m in enumerate(matrices, start=1):
            bake.bake(k, m)
        bake.finish()
        wall = time.perf_counter() - start
    total = sum(deform_times)
    print(f"phantom scale {args.scale}, {len(rigged.points):,} spheres, {len(rigged.rig)} bones, {args.mode}, "
          f"{len(matrices)} frames of CMU 131_01")
    print(f"  sum of deformation times   {total:8.2f} s  ({total / len(matrices):.3f} s a frame)")
    print(f"  whole bake (VDBs written)  {wall:8.2f} s  ({len(matrices) / wall:.2f} frames/s)")
    print(f"  ratio bake / deformation   {wall / total:8.2f}x  (target <= 1.3x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Benchmark: smooth frames on a real scan (issue 17's frame target off the phantom). The Visible Human's tissue
labels (AustinMan, 4, 2 or 1 mm): skeleton, automatic rig, smooth binding, the walking stride of bench_deform; the
rigid, linear and dual-quaternion frames (best of --repeat, alternately), their ratios to the rigid frame (target:
at most 1.5x), and whether each equals the brute-force scatter voxel for voxel (--no-reference skips it).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_subject_frames.py [--mm 2] [--points 30000] [--repeat 3]
Needs ../shared/data/visible-human/austinman_<mm>mm_labels.nii.gz (skips with a message without it).
"""
import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects
sys.path.insert(0, HERE)

import volrig  # noqa: E402
from volrig import pipeline  # noqa: E402
from volrig_support import data_root  # noqa: E402
from bench_deform import walking_pose  # noqa: E402

MODES = ("rigid", "linear", "dual_quaternion")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mm", type=int, default=2, choices=(1, 2, 4))
    ap.add_argument("--points", type=int, default=30000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-reference", action="store_true")
    a = ap.parse_args()
    path = str(data_root() / "visible-human" / f"austinman_{a.mm}mm_labels.nii.gz")
    if not os.path.exists(path):
        print(f"skipped: {path} is absent")
        return 0
    labels = volrig.load(path)
    source = labels.like(np.asarray(labels.array).astype(np.uint8))
    mask = labels.like(np.asarray(labels.array) > 0)
    rigged = pipeline.rig_skeleton(volrig.skeletonize(mask).top(a.points), mask, up=(0, 0, 1))
    M = walking_pose(rigged.rig)
    # one Deformer per mode family: rigid frames and smooth ones use different per-rig tables (a Deformer switching
    # between the two rebuilds them)
    deformers = {"rigid": volrig.Deformer(source, rigged.points, rigged.binding, lattice_after=0),  # (with tables)
                 "smooth": volrig.Deformer(source, rigged.points, rigged.binding, lattice_after=0)}
    print(f"Visible Human {a.mm} mm: grid {tuple(source.array.shape[::-1])}, {len(rigged.points):,} points, "
          f"{len(rigged.rig.names)} bones, smooth binding")
    best, kept = {m: float("inf") for m in MODES}, {}
    def d(m):
        return deformers["rigid" if m == "rigid" else "smooth"]
    for m in MODES:
        d(m).frame(M, mode=m)  # the per-rig builds, left out
    for _ in range(a.repeat):
        for m in MODES:
            t = time.perf_counter()
            f = d(m).frame(M, mode=m)
            best[m] = min(best[m], time.perf_counter() - t)
            kept[m] = f
            del f
    for m in MODES:
        ratio = "" if m == "rigid" else f"{best[m] / best['rigid']:.2f}x rigid (<= 1.5x)"
        print(f"  {m + ' frame':<40} {best[m]:8.3f} s   {ratio}")
        if a.no_reference:
            continue
        t = time.perf_counter()
        ref = volrig.deform_reference(source, rigged.points, rigged.binding, M, mode=m, like=kept[m])
        same = np.array_equal(kept[m].bone.array, ref.bone.array) and np.array_equal(kept[m].values.array, ref.values.array)
        print(f"    equal to the brute-force scatter ({time.perf_counter() - t:.0f} s) {same!s:>12}   (must be True)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Benchmark: the live preview's coarse frames (issue 21) against full-resolution frames.

The humanoid phantom at --scale with its automatic rig (smooth binding, ``pipeline.rig_skeleton``), posed with the
left elbow bent 90 degrees; ``volrig.deform.coarse_level`` at factors 2 and 4 (every 2nd / 4th voxel per axis).
For each level: the time to build the coarse level and its Deformer's first frame (k-d trees: the preview's
Deformer never builds the bones' lattice tables, as in the add-on), then best and
median of --repeat frames of new poses (the preview's cost while scrubbing), their ratio to the full-resolution
frame measured in the same run, and how well the coarse frame's object matches the full frame's (Dice of the
masks, the full frame sampled on the coarse voxels).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_preview.py [--scale 1] [--repeat 5]
Target (issue 21, 2 cores): the phantom at scale 1 at a quarter resolution per axis within 50 ms a frame.
"""
import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
from volrig import phantom, pipeline  # noqa: E402
from volrig.deform import coarse_level  # noqa: E402
from bench_centerline import timed  # noqa: E402


def poses(rig, count):
    """Rest-to-pose matrices bending the left forearm by 60..120 degrees (a new pose each call)."""
    b = rig.index("forearm.L")
    below = [b] + [c for c in range(len(rig.bones)) if rig.parents[c] == b]
    d = rig.tails()[b] - rig.heads()[b]
    axis = np.cross(d, [0.0, 0.0, 1.0])
    for k in range(count):
        M = volrig.rest_pose(len(rig.bones))
        R = volrig.rotation_about(axis, 60 + 60 * k / max(count - 1, 1), rig.heads()[b])
        for c in below:
            M[c] = R
        yield M


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    ph = phantom.humanoid(args.scale)
    vol = ph.volume
    mask = volrig.segment(vol, lo=1)
    sk = volrig.skeletonize(mask)
    r = pipeline.rig_skeleton(sk.at(pipeline.thinness_from_voxels(0.5, sk.metric, mask.spacing)), mask,
                              up=(0.0, 0.0, 1.0))
    print(f"phantom scale {args.scale}: grid {vol.dims} ({vol.array.size:,} voxels), {len(r.points):,} points, "
          f"{len(r.rig.bones)} bones")
    M = next(poses(r.rig, 1))
    full = volrig.Deformer(vol, r.points, r.binding, lattice_after=0)  # (a bake's frames: with the lattice tables)
    full.frame(M, mode="linear")
    it = iter(poses(r.rig, 10 ** 6))
    fbest, fmed, fframe = timed(args.repeat, lambda: full.frame(next(it), mode="linear"))
    print(f"{'level':>10s} {'build s':>8s} {'best ms':>8s} {'median ms':>10s} {'/ full':>7s} {'Dice':>6s}")
    print(f"{'full':>10s} {'':8s} {1000 * fbest:8.1f} {1000 * fmed:10.1f} {1.0:7.3f}")
    for f in (2, 4):
        t = time.perf_counter()
        d = volrig.Deformer(*coarse_level(vol, r.points, r.binding, f), lattice_after=-1)  # (as the add-on's preview)
        d.frame(M, mode="linear")
        build = time.perf_counter() - t
        it = iter(poses(r.rig, 10 ** 6))
        best, med, frame = timed(args.repeat, lambda: d.frame(next(it), mode="linear"))
        it = iter(poses(r.rig, 10 ** 6))
        for _ in range(args.repeat):  # the same pose at full resolution, for the comparison
            ref = full.frame(next(it), mode="linear")
        print(f"{f'1/{f}':>10s} {build:8.2f} {1000 * best:8.1f} {1000 * med:10.1f} {best / fbest:7.3f} "
              f"{dice(frame, ref, f):6.3f}")


def dice(coarse, full, f) -> float:
    """Dice of the coarse frame's mask and the full frame's mask sampled at the coarse voxel centres."""
    c = coarse.mask
    fo = np.array(full.offset)
    co = np.array(coarse.offset) * f  # coarse offsets are in coarse voxels
    a = np.asarray(c.array)
    zz, yy, xx = np.nonzero(np.ones_like(a))
    fz, fy, fx = co[2] + zz * f - fo[2], co[1] + yy * f - fo[1], co[0] + xx * f - fo[0]
    fa = np.asarray(full.mask.array)
    ok = (fz >= 0) & (fz < fa.shape[0]) & (fy >= 0) & (fy < fa.shape[1]) & (fx >= 0) & (fx < fa.shape[2])
    b = np.zeros(a.size, bool)
    b[ok] = fa[fz[ok], fy[ok], fx[ok]]
    a = a.reshape(-1)
    return 2 * np.count_nonzero(a & b) / max(np.count_nonzero(a) + np.count_nonzero(b), 1)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Benchmark: centerlines, centerline trees and straightening (issue 20).

Measures, best and median of --repeat runs each (wall time, including cropping the mask and its distance
transform, which every call does):
  * volrig.centerline on a synthetic helix tube (3 turns, helix radius 30, tube radius 6 voxels, about 620 voxels
    long), ends found automatically, and between two given points;
  * volrig.straighten of that tube (radius 10);
  * on the airway tree (../shared/data/airway/Patient1_bronchialTree.nii.gz, 497 x 331 x 512, 0.55 x 0.55 x 0.70
    mm; skipped when absent): volrig.centerline between the object's two farthest ends and volrig.centerline_tree
    from the automatic root.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_centerline.py [--repeat 5]
Targets (issue 20, 2 cores): a centerline <= 1 s, the airway tree <= 2 s.
"""
import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig_support import data_root  # noqa: E402

AIRWAY = str(data_root() / "airway" / "Patient1_bronchialTree.nii.gz")


def timed(repeat, f):
    """Best and median wall time of `repeat` calls of f, and the last result."""
    times, out = [], None
    for _ in range(repeat):
        out = None
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times)), out


def helix_tube(turns=3.0, helix_radius=30.0, pitch=40.0, radius=6.0):
    """A bool Volume: the voxels within `radius` of a helix (unit voxels), and the helix's arc length."""
    from scipy.spatial import cKDTree
    t = np.linspace(0, 2 * np.pi * turns, 200000)
    c = np.stack([helix_radius * np.cos(t), helix_radius * np.sin(t), pitch * t / (2 * np.pi)], 1)
    lo = c.min(0) - radius - 3
    dims = np.ceil(c.max(0) + radius + 3 - lo).astype(int) + 1
    z, y, x = np.meshgrid(*[lo[a] + np.arange(dims[a]) for a in (2, 1, 0)], indexing="ij")
    q = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    d = cKDTree(c).query(q, distance_upper_bound=radius + 1)[0]
    return volrig.Volume((d <= radius).reshape(z.shape), (1.0, 1.0, 1.0), tuple(lo)), c


def row(what, best, median, extra=""):
    print(f"  {what:<58} best {best:6.3f} s  median {median:6.3f} s  {extra}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"volrig centerline benchmark, {os.cpu_count()} cores, best / median of {args.repeat}")

    mask, axis = helix_tube()
    x, y, z = mask.dims
    print(f"helix tube: {x} x {y} x {z} voxels, {int(mask.array.sum()):,} object voxels, "
          f"axis {np.linalg.norm(np.diff(axis, axis=0), axis=1).sum():.1f} long")
    b, m, cl = timed(args.repeat, lambda: volrig.centerline(mask))
    row("centerline, automatic ends", b, m, f"{len(cl)} points, length {cl.length:.1f}")
    b, m, cl2 = timed(args.repeat, lambda: volrig.centerline(mask, start=axis[5000], end=axis[-5000]))
    row("centerline, given ends", b, m, f"{len(cl2)} points, length {cl2.length:.1f}")
    vol = volrig.Volume(mask.array.astype(np.float32), mask.spacing, mask.origin)
    b, m, (straight, _) = timed(args.repeat, lambda: volrig.straighten(vol, cl, 10.0))
    row("straighten, radius 10", b, m, "-> %d x %d x %d" % straight.dims)

    if not os.path.exists(AIRWAY):
        print(f"airway tree skipped: {AIRWAY} is absent")
        return 0
    v = volrig.load(AIRWAY)
    air = volrig.Volume(v.array != 0, v.spacing, v.origin)
    x, y, z = air.dims
    print(f"airway tree: {x} x {y} x {z} voxels, spacing {tuple(round(s, 3) for s in air.spacing)}, "
          f"{int(air.array.sum()):,} object voxels")
    b, m, cl = timed(args.repeat, lambda: volrig.centerline(air))
    row("centerline, the two farthest ends", b, m, f"{len(cl)} points, length {cl.length:.1f} mm")
    b, m, tr = timed(args.repeat, lambda: volrig.centerline_tree(air))
    row("centerline_tree, automatic root", b, m,
        f"{len(tr)} branches, generations 0-{tr.generations.max()}, {len(tr.branch_points)} branch points")
    return 0


if __name__ == "__main__":
    sys.exit(main())

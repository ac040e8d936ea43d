#!/usr/bin/env python3
"""Benchmark: rig and skin a mesh through its volume (issue 23), stage by stage.

The shared cow (../shared/data/meshes/cow.off, 2,903 vertices) midpoint-subdivided (volrig.subdivide: the surface
unchanged) to 44,162 and 176,258 vertices, rigged by volrig.rig_mesh at the default 160 voxels along its longest
side. Best and median of --repeat runs of each stage: voxelize (the reference: the first step any mesh rig needs,
measured in the same run), skeletonize, skeleton-tree + autorig + bind (pipeline.rig_skeleton), skin_weights; the
total and its ratio to voxelize.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_skin.py [--repeat 3] [--levels 2 3]
Target (issue 23, 2 cores): rig and skin a 50,000-vertex mesh within 3 s.
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig.pipeline import rig_skeleton, skeleton_of, skeleton_points, thinness_from_voxels  # noqa: E402
from volrig.skin import mesh_voxel_size, skin_weights  # noqa: E402
from volrig_support import data_root  # noqa: E402
from bench_centerline import timed  # noqa: E402

DATA = str(data_root() / "meshes" / "cow.off")


def stages(v, f, repeat):
    size = mesh_voxel_size(v)
    rows = []
    best, med, mask = timed(repeat, lambda: volrig.voxelize(v, f, size))
    rows.append(("voxelize", best, med))
    best, med, sk = timed(repeat, lambda: skeleton_of(mask))
    rows.append(("skeletonize", best, med))
    pts = skeleton_points(sk, thinness=thinness_from_voxels(0.5, sk.metric, mask.spacing))
    best, med, r = timed(repeat, lambda: rig_skeleton(pts, mask, up=(0.0, 1.0, 0.0)))
    rows.append(("skeleton-tree + autorig + bind", best, med))
    best, med, _ = timed(repeat, lambda: skin_weights(mask, r.rig, v))
    rows.append(("skin_weights", best, med))
    return rows, mask, r.rig


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--levels", type=int, nargs="+", default=[2, 3], help="subdivision levels of the cow")
    args = ap.parse_args()
    if not os.path.exists(DATA):
        sys.exit(f"the shared cow is not available: {DATA}")
    v0, f0 = volrig.read_mesh(DATA)
    for level in args.levels:
        v, f = v0, f0
        for _ in range(level):
            v, f = volrig.subdivide(v, f)
        rows, mask, rig = stages(v, f, args.repeat)
        total_best = sum(r[1] for r in rows)
        print(f"\ncow subdivided {level}x: {len(v):,} vertices, {len(f):,} triangles; grid {mask.dims}, "
              f"{int(mask.array.sum()):,} object voxels; {rig.kind}, {len(rig.bones)} bones")
        print(f"{'stage':34s} {'best s':>8s} {'median s':>9s} {'/ voxelize':>11s}")
        for name, best, med in rows:
            print(f"{name:34s} {best:8.2f} {med:9.2f} {best / rows[0][1]:10.2f}x")
        print(f"{'total (rig_mesh)':34s} {total_best:8.2f} {'':9s} {total_best / rows[0][1]:10.2f}x")


if __name__ == "__main__":
    main()

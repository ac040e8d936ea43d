#!/usr/bin/env python3
"""Benchmark: skeleton-tree + autorig + bind on the humanoid phantom (issue: skeleton-tree, autorig, binding).

Measures, in one run on this machine, best of --repeat runs each:
  * volrig.skeleton_tree, volrig.autorig and volrig.bind (rigid and smooth) on the phantom's skeleton of --points
    points (the highest-scoring ones);
  * the reference: a plain Euclidean minimum spanning tree of the same points with scipy (cKDTree 26 nearest
    neighbours + csgraph.minimum_spanning_tree; no containment test), and the ratio of volrig's tree to it.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_rig.py [--scale 1.0] [--points 40000] [--repeat 3]
Target (scale 1, ~40,000 points, 2 cores): tree + autorig + bind <= 2 s.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402


def best_of(repeat, f):
    """Best wall time of `repeat` calls of f, and the last result. The previous result is released before the
    clock starts, so a run does not pay for freeing the one before it."""
    times, out = [], None
    for _ in range(repeat):
        out = None
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--points", type=int, default=40000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    ph = phantom.humanoid(args.scale)
    mask = volrig.segment(ph.volume)
    sk = volrig.skeletonize(mask)
    pts = sk.top(args.points)
    print(f"phantom scale {args.scale}: grid {mask.array.shape[::-1]}, {sk.object_count:,} object voxels, "
          f"{len(pts):,} skeleton points (TP {sk.tp_for_count(len(pts)):.3f})")

    t_tree, tree = best_of(args.repeat, lambda: volrig.skeleton_tree(pts, mask))
    t_rig, rig = best_of(args.repeat, lambda: volrig.autorig(pts, tree, mask))
    t_bind, binding = best_of(args.repeat, lambda: volrig.bind(pts, rig, mask))
    t_smooth, _ = best_of(args.repeat, lambda: volrig.bind(pts, rig, mask, mode="smooth"))
    total = t_tree + t_rig + t_bind

    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree
    from scipy.spatial import cKDTree

    def reference():
        d, j = cKDTree(pts.centers).query(pts.centers, k=27)
        n = len(pts)
        g = csr_matrix((d[:, 1:].ravel(), (np.repeat(np.arange(n), 26), j[:, 1:].ravel())), shape=(n, n))
        return minimum_spanning_tree(g)

    t_ref, _ = best_of(args.repeat, reference)
    figures = dict(scale=args.scale, points=len(pts), tree_s=t_tree, autorig_s=t_rig, bind_rigid_s=t_bind,
                   bind_smooth_s=t_smooth, total_s=total, scipy_mst_s=t_ref, tree_over_scipy=t_tree / t_ref,
                   rig_kind=rig.kind, bones=len(rig), tree_components=tree.component_count,
                   unreachable=int(binding.unreachable.sum()))
    print(f"skeleton_tree      {t_tree:7.3f} s  ({tree.component_count} components; scipy plain EMST "
          f"{t_ref:.3f} s: volrig's contained tree takes {t_tree / t_ref:.2f}x as long)")
    print(f"autorig            {t_rig:7.3f} s  ({rig.kind}, {len(rig)} bones)")
    print(f"bind rigid         {t_bind:7.3f} s  (smooth {t_smooth:.3f} s)")
    print(f"tree+autorig+bind  {total:7.3f} s  (target <= 2 s at scale 1 with ~40,000 points): "
          f"{'PASS' if total <= 2.0 else 'FAIL'}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(figures, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

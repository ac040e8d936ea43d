"""voxelize's inside/outside tests on open character meshes: the generalized winding number ("winding") against
the exterior flood fill ("flood"), timed in the same run, with the connected components of each mask.

    PYTHONPATH=python /usr/bin/python3 benchmarks/bench_voxelize_winding.py [--voxels 160] [--repeat 3] [mesh ...]

Meshes are paths, or names under ../shared/data/characters (default: rignet/9477_ori.obj, rignet/smith_ori.obj).
"""
import argparse
import os
import sys
import time

import numpy as np
from scipy import ndimage

import volrig
from volrig.skin import mesh_voxel_size

HERE = os.path.dirname(os.path.abspath(__file__))
CHARACTERS = os.path.join(HERE, "..", "..", "shared", "data", "characters")
DEFAULT = ["rignet/9477_ori.obj", "rignet/smith_ori.obj"]


def best_time(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def components(mask):
    labels, n = ndimage.label(mask.array)
    sizes = np.bincount(labels.ravel())[1:] if n else np.zeros(0, int)
    return n, int(sizes.max()) if n else 0, int(sizes.sum())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("meshes", nargs="*", default=DEFAULT)
    ap.add_argument("--voxels", type=int, default=160)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    print("| mesh | triangles | boundary edges | grid (voxels) | flood: time, components, largest / all | "
          "winding: time, components, largest / all | winding / flood time |")
    print("|---|---|---|---|---|---|---|")
    for name in a.meshes:
        path = name if os.path.exists(name) else os.path.join(CHARACTERS, name)
        if not os.path.exists(path):
            print(f"{name}: not found", file=sys.stderr)
            continue
        v, f = volrig.read_mesh(path)
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        _, uses = np.unique(e, axis=0, return_counts=True)
        h = mesh_voxel_size(v, a.voxels)
        tf, mf = best_time(lambda: volrig.voxelize(v, f, h, method="flood"), a.repeat)
        tw, mw = best_time(lambda: volrig.voxelize(v, f, h, method="winding"), a.repeat)
        cf, cw = components(mf), components(mw)
        print(f"| {os.path.basename(path)} | {len(f):,} | {int((uses != 2).sum()):,} | "
              f"{np.prod(mw.array.shape):,} | {tf:.2f} s, {cf[0]}, {cf[1]:,} / {cf[2]:,} | "
              f"{tw:.2f} s, {cw[0]}, {cw[1]:,} / {cw[2]:,} | {tw / tf:.1f} |")


if __name__ == "__main__":
    main()

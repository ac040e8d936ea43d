"""voxelize's inside/outside tests on open character meshes: the generalized winding number ("winding") against
the exterior flood fill ("flood"), timed in the same run, with the connected components of each mask.

    PYTHONPATH=python /usr/bin/python3 benchmarks/bench_voxelize_winding.py [--voxels 160] [--repeat 3] [mesh ...]

Meshes are paths, or names under ../shared/data/characters (default: six open ones, 338 to 64,618 triangles).
"auto" on these open meshes is the union of the flood's and the winding number's masks.
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
DEFAULT = ["rignet/9477_ori.obj", "rignet/smith_ori.obj", "rignet/8210_ori.obj",
           "axl/b3234635-0797-53cd-8e88-d8717986ad74.obj", "axl/15b2fcc8-3115-50e7-b201-d73f4e71b4f1.obj",
           "shapes/beast.obj"]


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
    print("| mesh | triangles | open edges | grid (voxels) | flood: time, components, largest / all | "
          "winding: time, components, largest / all | auto: components, largest / all | time winding / flood | "
          "auto / flood |")
    print("|---|---|---|---|---|---|---|---|---|")
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
        ta, ma = best_time(lambda: volrig.voxelize(v, f, h, method="auto"), a.repeat)
        cf, cw, ca = components(mf), components(mw), components(ma)
        print(f"| {os.path.basename(path)[:16]} | {len(f):,} | {int((uses != 2).sum()):,} | "
              f"{np.prod(mw.array.shape):,} | {tf:.2f} s, {cf[0]}, {cf[1]:,} / {cf[2]:,} | "
              f"{tw:.2f} s, {cw[0]}, {cw[1]:,} / {cw[2]:,} | {ca[0]}, {ca[1]:,} / {ca[2]:,} | {tw / tf:.1f} | "
              f"{ta / tf:.1f} |", flush=True)


if __name__ == "__main__":
    main()

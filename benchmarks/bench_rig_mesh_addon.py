"""Benchmark: the add-on's Rig Mesh on a 50,000-vertex mesh, inside Blender (issue 23).

The shared knight (../shared/data/meshes/decimated-knight.off, 502 vertices) subdivided by Blender (9 cuts per edge:
about 50,000 vertices), rigged through the operator's own function (``mesh_rig.rig_mesh_object``): the whole Rig Mesh,
the part writing the vertex groups, and the thickness keys, each timed; best of --repeat runs.

Run:  blender -b --factory-startup --python benchmarks/bench_rig_mesh_addon.py -- [--repeat 2] [--cuts 9]
"""
import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "tests", "support")]

import bmesh  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402

import volrig  # noqa: E402
import volrig_addon  # noqa: E402
from volrig_addon import mesh_rig, objects  # noqa: E402
from volrig_support import data_root  # noqa: E402


def knight(cuts: int):
    v, f = volrig.read_mesh(str(data_root() / "meshes" / "decimated-knight.off"))
    v = np.asarray(v, float)
    obj = mesh_rig.new_mesh_object(bpy.context, "knight", np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1), f)
    me = obj.data
    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    return obj


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--cuts", type=int, default=9)
    args = ap.parse_args(argv)
    volrig_addon.register()
    best = {}
    for _ in range(args.repeat):
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        obj = knight(args.cuts)
        t0 = time.perf_counter()
        arm, mr, groups = mesh_rig.rig_mesh_object(bpy.context, obj, up=objects.scene_up(obj), thickness_keys=False)
        total = time.perf_counter() - t0
        t1 = time.perf_counter()
        mesh_rig.add_thickness_keys(obj, arm, mr.rig, mr.weights)
        keys = time.perf_counter() - t1
        run = {"vertices": len(obj.data.vertices), "bones": len(mr.rig), "rig_mesh_s": total, "vertex_groups_s": groups,
               "thickness_keys_s": keys, "found": obj["volrig_rig_found"]}
        best = run if not best or run["rig_mesh_s"] < best["rig_mesh_s"] else best
        print(json.dumps(run), flush=True)
    print("best", json.dumps(best), flush=True)
    sys.stdout.flush()
    os._exit(0)


main()

#!/usr/bin/env python3
"""Where rig_mesh's time goes on the shared characters (issue 53's speed criterion): each step of
``pipeline.mesh_skeleton`` and ``pipeline.rig_skeleton`` timed on its own, per character: voxelize at 160 voxels
(its flood and winding-number parts timed apart too with --parts), skeletonize, the finer voxelization and its
skeletonization when the parts come out thinner than 2 voxels, skeleton-tree, autorig, bind. The steps are those of
``PlanSubject.rig`` (the compiled-in plan weights, no markers); the rig's joints go to --save (an .npz per
character name) so that two builds can be compared joint for joint (--compare).

Run:  PYTHONPATH=python:tests/support /usr/bin/python3 benchmarks/profile_rig_steps.py [--parts] [--save DIR]
          [--compare DIR] [names ...]
      /usr/bin/python3 benchmarks/profile_rig_steps.py --builds BEFORE AFTER [--rounds 1] [--cpu] [names ...]
--builds: two copies of the package (directories holding volrig/ with its compiled module, as for interleaved.py),
timed in the same minutes: each character in one fresh process per build, the builds alternating (which goes first
alternates too), best of --rounds; prints both tables and the ratios, and whether the joints and masks agree.
--cpu: CPU seconds of the process (all threads) instead of wall-clock seconds, which other jobs on the machine
stretch; the speed criterion is in wall-clock seconds.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# --builds runs each build's package in a child process: VOLRIG_PACKAGE says which
sys.path.insert(0, os.environ.get("VOLRIG_PACKAGE") or os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))

import volrig  # noqa: E402
from volrig import pipeline as P  # noqa: E402
from volrig.skin import mesh_voxel_size  # noqa: E402
from volrig_support import characters as C  # noqa: E402

STEPS = ("voxelize", "skeletonize", "voxelize2", "skeletonize2", "tree", "autorig", "bind")
#: --cpu: the process's CPU seconds (all its threads) instead of wall-clock seconds; steadier on a shared machine
CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCK["wall"]


def timed(t, key, fn):
    s = clock()
    out = fn()
    t[key] = t.get(key, 0.0) + clock() - s
    return out


def profile(sub, parts=False):
    """(seconds per step, rig, extra) for one character, the steps of PlanSubject.rig."""
    v, f = sub.mesh
    t = {}
    voxels, size = P.MESH_VOXELS, mesh_voxel_size(v, P.MESH_VOXELS)
    extra = {}
    for attempt in range(2):
        sfx = "2" if attempt else ""
        mask = timed(t, "voxelize" + sfx, lambda: volrig.voxelize(v, f, size, method="auto"))
        sk = timed(t, "skeletonize" + sfx, lambda: P.skeleton_of(mask))
        pts = P.skeleton_points(sk, thinness=P.thinness_from_voxels(P.DEFAULT_THINNESS_VOXELS, sk.metric,
                                                                    mask.spacing))
        extra["shape" + sfx] = mask.array.shape
        if parts:
            timed(t, "flood" + sfx, lambda: volrig.voxelize(v, f, size, method="flood"))
            timed(t, "winding" + sfx, lambda: volrig.voxelize(v, f, size, method="winding"))
        finer = None if attempt else P._finer_voxels(pts, size, voxels, P.MIN_RADIUS_VOXELS,
                                                     int(np.count_nonzero(mask.array)))
        if finer is None:
            break
        voxels, size = finer, mesh_voxel_size(v, finer)
    tree = timed(t, "tree", lambda: P.skeleton_tree(pts, mask))
    rig, _ = timed(t, "autorig", lambda: P.autorig_fit(pts, tree, mask, up=sub.up))
    timed(t, "bind", lambda: P.bind(pts, rig, mask, mode="smooth"))
    extra["mask"] = mask
    return t, rig, extra


def stem(name):
    return name.split("/")[-1].rsplit(".", 1)[0]


def child(name, out):
    """One character in this process (--child): its step times as JSON, its joints and mask to `out` (.npz)."""
    assert os.path.dirname(os.path.dirname(os.path.abspath(volrig.__file__))) == os.environ["VOLRIG_PACKAGE"]
    sub = C.characters([stem(name)])[0]
    t, rig, extra = profile(sub)
    mask = np.asarray(extra["mask"].array)
    np.savez(out, joints=rig.joints, mask=np.packbits(mask), shape=mask.shape)
    print(json.dumps(t))


def run_build(package, name, out):
    env = dict(os.environ, VOLRIG_PACKAGE=os.path.abspath(package))
    cpu = ["--cpu"] if clock is CLOCK["cpu"] else []
    r = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", out, *cpu, name], env=env, check=True,
                       capture_output=True, text=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def builds(before, after, names, rounds):
    """The two builds interleaved, character by character (--builds)."""
    subjects = [s.name for s in C.characters(names or None)]
    tables = {before: [], after: []}
    same = 0
    with tempfile.TemporaryDirectory() as tmp:
        for i, name in enumerate(subjects):
            best = {}
            order = (before, after) if i % 2 == 0 else (after, before)
            for r in range(rounds):
                for b in (order if r % 2 == 0 else order[::-1]):
                    t = run_build(b, name, os.path.join(tmp, f"{'ab'[b == after]}.npz"))
                    t["total"] = sum(t.get(k, 0.0) for k in STEPS)
                    if b not in best or t["total"] < best[b]["total"]:
                        best[b] = t
            a, z = (np.load(os.path.join(tmp, f"{c}.npz")) for c in "ab")
            agree = (a["joints"].shape == z["joints"].shape and np.array_equal(a["joints"], z["joints"])
                     and np.array_equal(a["mask"], z["mask"]) and tuple(a["shape"]) == tuple(z["shape"]))
            same += agree
            for b in (before, after):
                tables[b].append([best[b].get(k, 0.0) for k in STEPS + ("total",)])
            print(f"{name[:28]:28s} before {best[before]['total']:6.2f} s, after {best[after]['total']:6.2f} s, "
                  f"voxelize {best[before]['voxelize'] + best[before].get('voxelize2', 0):6.2f} -> "
                  f"{best[after]['voxelize'] + best[after].get('voxelize2', 0):6.2f} s, "
                  f"{'joints and mask identical' if agree else 'JOINTS OR MASK DIFFER'}", flush=True)
    print(f"\n{'seconds':10s} " + " ".join(f"{c:>12s}" for c in STEPS + ("total",)))
    for label, b in (("before", before), ("after", after)):
        r = np.array(tables[b])
        print(f"{label + ' mean':10s} " + " ".join(f"{x:12.2f}" for x in r.mean(0)))
        print(f"{label + ' max':10s} " + " ".join(f"{x:12.2f}" for x in r.max(0)))
    ratio = np.array(tables[after]).sum(0) / np.maximum(np.array(tables[before]).sum(0), 1e-9)
    print(f"{'after/before':10s} " + " ".join(f"{x:12.2f}" for x in ratio))
    print(f"joints and masks identical on {same} of {len(subjects)} characters")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*")
    ap.add_argument("--parts", action="store_true", help="also time voxelize's flood and winding methods apart")
    ap.add_argument("--save", help="write each rig's joints (and the mask's digest) here")
    ap.add_argument("--compare", help="compare each rig's joints with those saved here")
    ap.add_argument("--builds", nargs=2, metavar=("BEFORE", "AFTER"), help="two packages, interleaved")
    ap.add_argument("--rounds", type=int, default=1, help="--builds: runs per character and build (best kept)")
    ap.add_argument("--cpu", action="store_true", help="time CPU seconds (all threads) rather than wall-clock seconds")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args()
    global clock
    clock = CLOCK["cpu" if a.cpu else "wall"]
    if a.child:
        return child(a.names[0], a.child)
    if a.builds:
        return builds(*a.builds, a.names, a.rounds)
    subjects = C.characters(a.names or None)
    cols = STEPS + (("flood", "winding", "flood2", "winding2") if a.parts else ())
    print(f"{'character':28s} {'grid':>15s} " + " ".join(f"{c:>8s}" for c in cols) + f" {'total':>7s}  joints")
    rows = []
    worst = 0.0
    for sub in subjects:
        t, rig, extra = profile(sub, a.parts)
        total = sum(t.get(s, 0.0) for s in STEPS)
        rows.append([t.get(c, 0.0) for c in cols] + [total])
        key = sub.name.replace("/", "_")
        mask = np.asarray(extra["mask"].array)
        status = ""
        if a.save:
            os.makedirs(a.save, exist_ok=True)
            np.savez(os.path.join(a.save, key + ".npz"), joints=rig.joints, bones=np.asarray(rig.bones),
                     mask=np.packbits(mask), shape=mask.shape)
        if a.compare:
            old = np.load(os.path.join(a.compare, key + ".npz"))
            same_mask = tuple(old["shape"]) == mask.shape and np.array_equal(old["mask"], np.packbits(mask))
            if old["joints"].shape == rig.joints.shape:
                d = float(np.abs(old["joints"] - rig.joints).max()) if len(rig.joints) else 0.0
                worst = max(worst, d)
                status = f"max |d| {d:.3g}, mask {'same' if same_mask else 'DIFFERS'}"
            else:
                worst = float("inf")
                status = f"JOINTS DIFFER {old['joints'].shape} vs {rig.joints.shape}"
        grid = "x".join(str(n) for n in extra.get("shape2", extra["shape"]))
        print(f"{sub.name[:28]:28s} {grid:>15s} " + " ".join(f"{x:8.2f}" for x in rows[-1]) + f"  {status}",
              flush=True)
    r = np.array(rows)
    print(f"{'mean':28s} {'':>15s} " + " ".join(f"{x:8.2f}" for x in r.mean(0)))
    print(f"{'max':28s} {'':>15s} " + " ".join(f"{x:8.2f}" for x in r.max(0)))
    if a.compare:
        print(f"largest joint difference over {len(rows)} characters: {worst:.3g}")


if __name__ == "__main__":
    main()

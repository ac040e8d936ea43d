#!/usr/bin/env python3
"""Benchmark: collision detection (issue 19) on the humanoid phantom walking into a ball.

The phantom (scale --scale, --points skeleton points, its automatic rig, rigid and smooth bindings) walks a
--frames frame walk cycle; a ball of radius 12 voxels (one bone) is held still where the left shin passes, so that
some frames are apart and some in contact. Measured in one run:
  * the Collider build (per rig);
  * the average collide() per frame over the clip, split into frames apart and frames in contact;
  * the reference: deforming both frames with the Deformer (binary, rigid) and intersecting them, per frame, and
    the speed-up of collide() over it (both give the same voxels: checked here on every frame);
  * self-contact over the walk (none expected) and of a pose swinging the right forearm into the thigh.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_collide.py [--scale 0.5] [--points 5000] [--frames 24]
Targets (scale 0.5, 2 cores): apart <= 0.5 ms, in contact <= 10 ms, >= 20x faster than deforming both frames and
intersecting them.
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
from volrig.walk import walk_matrices  # noqa: E402
from bench_rig import best_of  # noqa: E402  (this folder is on sys.path when run as a script)


def ball_rig(vol, centre, radius):
    """A ball on the phantom's own grid (one lattice for both), bound to one bone."""
    z, y, x = np.indices(vol.array.shape)
    inside = (x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2 < radius ** 2
    bv = vol.like(np.where(inside, 200, 0).astype(np.uint8))
    mask = volrig.segment(bv)
    pts = volrig.skeletonize(mask).top(400)
    world = np.array(vol.origin) + np.array(vol.spacing) * centre
    rig = volrig.Rig([world, world + [0, 0, 10.0]], [[0, 1]], ["ball"])
    return bv, pts, rig, volrig.bind(pts, rig, mask)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--points", type=int, default=5000)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    vol = phantom.humanoid(args.scale).volume
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(args.points)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    rigid = volrig.bind(pts, rig, mask)
    clip = walk_matrices(rig, args.frames)
    shin = rig.index("shin.L")
    mid = (rig.heads()[shin] + rig.tails()[shin]) / 2
    s = args.scale / 0.5
    centre = (np.asarray(mid) - np.array(vol.origin)) / np.array(vol.spacing) + [0.0, 26.0 * s, 0.0]
    bv, bpts, brig, bbind = ball_rig(vol, centre, 12.0 * s)
    print(f"phantom scale {args.scale}: grid {vol.dims}, {len(pts):,} spheres, {len(rig)} bones; ball of "
          f"{len(bpts)} spheres; walk of {args.frames} frames")

    fig = {}
    fig["collider_build_s"], a = best_of(args.repeat, lambda: volrig.Collider(pts, rigid, rig, shape=vol.array.shape))
    b = volrig.Collider(bpts, bbind, brig, shape=bv.array.shape)
    still = np.eye(4)[None]
    apart, contact = [], []
    for f in range(args.frames):
        t, c = best_of(args.repeat, lambda: volrig.collide(a, clip[f], b, still))
        (contact if c.hit else apart).append((t, c.voxels))
    da, db = volrig.Deformer(vol, pts, rigid, lattice_after=0), volrig.Deformer(bv, bpts, bbind)  # (da: tables)
    fb = db.frame(still, values=False)
    ref = []
    for f in range(args.frames):
        t0 = time.perf_counter()
        fa = da.frame(clip[f], values=False)
        n = fa.shared_voxels(fb)
        ref.append(time.perf_counter() - t0)
        fa = None
        assert n == volrig.collide(a, clip[f], b, still).voxels, f"frame {f}: the two answers differ"
    fig["frames_apart"], fig["frames_in_contact"] = len(apart), len(contact)
    fig["apart_ms"] = 1e3 * float(np.mean([t for t, _ in apart])) if apart else None
    fig["contact_ms"] = 1e3 * float(np.mean([t for t, _ in contact])) if contact else None
    fig["contact_voxels_max"] = max((v for _, v in contact), default=0)
    fig["deform_and_intersect_ms"] = 1e3 * float(np.mean(ref))
    every = [t for t, _ in apart + contact]
    fig["speedup_vs_deform_and_intersect"] = float(np.mean(ref)) / float(np.mean(every))
    fig["speedup_in_contact"] = float(np.mean(ref)) / (fig["contact_ms"] / 1e3) if contact else None
    t0 = time.perf_counter()
    walk = volrig.collisions(a, clip)
    fig["self_walk_ms_per_frame"] = 1e3 * (time.perf_counter() - t0) / args.frames
    fig["self_walk_frames_in_contact"] = len(walk.hit_frames)
    pose = rig.pose({"upper_arm.R": ([0, 1, 0], 8), "forearm.R": ([0, 1, 0], -25)})
    fig["self_hand_in_thigh_ms"], hand = best_of(args.repeat, lambda: volrig.self_collide(a, pose))
    fig["self_hand_in_thigh_ms"] *= 1e3
    fig["self_hand_in_thigh_pairs"] = [f"{x}/{y}" for x, y in hand.bone_pairs]

    for k, v in fig.items():
        print(f"  {k:34s} {v:.4g}" if isinstance(v, float) else f"  {k:34s} {v}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(fig, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

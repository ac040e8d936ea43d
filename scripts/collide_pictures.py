#!/usr/bin/python3
"""Pictures of collision detection (issue 19) on the humanoid phantom at scale 0.5: the phantom walking past a ball
held still (contact voxels in red over the two deformed frames, front view, over the walk's frames), and
self-contact of a pose that swings the right forearm into the thigh. Writes docs/images/collide.png.

    PYTHONPATH=python /usr/bin/python3 scripts/collide_pictures.py [--out docs/images]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402
from bench_collide import ball_rig  # noqa: E402
from volrig.walk import walk_matrices  # noqa: E402
from centerline_pictures import save  # noqa: E402  (scripts/ is this script's folder)


def front(ax, frame, colour, alpha=1.0):
    """The frame's mask projected along y (front view) in world x, z."""
    m = frame.bone.array.max(axis=1) > 0  # [z, x]
    o = np.array(frame.bone.origin)
    s = np.array(frame.bone.spacing)
    extent = (o[0], o[0] + s[0] * m.shape[1], o[2], o[2] + s[2] * m.shape[0])
    rgba = np.zeros(m.shape + (4,))
    rgba[m] = colour + (alpha,)
    ax.imshow(rgba, origin="lower", extent=extent, interpolation="nearest")


def front_points(ax, points, spacing, colour=(0.9, 0.1, 0.1)):
    """World points projected along y as a mask at the voxel size."""
    if points is None or not len(points):
        return
    s = np.asarray(spacing)
    lo = points.min(axis=0)
    ij = np.round((points - lo) / s).astype(int)
    m = np.zeros((ij[:, 2].max() + 1, ij[:, 0].max() + 1), bool)
    m[ij[:, 2], ij[:, 0]] = True
    rgba = np.zeros(m.shape + (4,))
    rgba[m] = colour + (1.0,)
    extent = (lo[0] - s[0] / 2, lo[0] + s[0] * (m.shape[1] - 0.5), lo[2] - s[2] / 2, lo[2] + s[2] * (m.shape[0] - 0.5))
    ax.imshow(rgba, origin="lower", extent=extent, interpolation="nearest")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    args = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    vol = phantom.humanoid(0.5).volume
    mask = volrig.segment(vol)
    pts = volrig.skeletonize(mask).top(5000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    rigid = volrig.bind(pts, rig, mask)
    shin = rig.index("shin.L")
    centre = (rig.heads()[shin] + rig.tails()[shin]) / 2 - np.array(vol.origin) + [0.0, 26.0, 0.0]
    bv, bpts, brig, bbind = ball_rig(vol, centre, 12.0)
    a = volrig.Collider(pts, rigid, rig, shape=vol.array.shape)
    b = volrig.Collider(bpts, bbind, brig, shape=bv.array.shape)
    da, db = volrig.Deformer(vol, pts, rigid), volrig.Deformer(bv, bpts, bbind)
    clip = walk_matrices(rig, 24)
    still = np.eye(4)[None]
    found = volrig.collisions(a, clip, b, np.repeat(still[None], len(clip), axis=0))
    run = max(found.contacts, key=lambda c: c.last - c.first)
    apart = next(f for f in range(len(clip)) if f not in found.hit_frames)
    frames = [run.first, run.peak_frame, run.last, apart]
    fig, axes = plt.subplots(1, len(frames) + 1, figsize=(15, 6.5))
    for ax, f in zip(axes, frames):
        c = volrig.collide(a, clip[f], b, still, points=True)
        front(ax, da.frame(clip[f], values=False), (0.6, 0.6, 0.6))
        front(ax, db.frame(still, values=False), (0.3, 0.45, 0.9), 0.8)
        front_points(ax, c.points, vol.spacing)
        ax.set_title(f"frame {f}: " + (f"{c.voxels:,} voxels\n{c.bone_pairs[0][0]}/ball" if c.hit else "apart\n"),
                     fontsize=10)
        ax.set_xlim(20, 125)
        ax.set_ylim(0, 300)
        ax.set_xticks([])
    pose = rig.pose({"upper_arm.R": ([0, 1, 0], 8), "forearm.R": ([0, 1, 0], -25)})
    sc = volrig.self_collide(a, pose, points=True)
    ax = axes[-1]
    front(ax, da.frame(pose, values=False), (0.6, 0.6, 0.6))
    front_points(ax, sc.points, vol.spacing)
    pairs = sorted(sc.bone_pairs, key=lambda p: "thigh" not in p[1])
    ax.set_title(f"self-contact: {sc.voxels:,} voxels\n" + ", ".join(f"{x}/{y}" for x, y in pairs), fontsize=9,
                 wrap=True)
    ax.set_xlim(0, 145)
    ax.set_ylim(100, 400)
    ax.set_xticks([])
    fig.suptitle(f"The walking phantom and a ball held still (front view): contact (red) in frames "
                 f"{run.first}-{run.last} of 24; right: the right forearm swung into the thigh")
    save(fig, os.path.join(args.out, "collide.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Pictures of the deformation engine: docs/images/deform_bend.png (the thesis' bend test: a cylinder holding a
brighter cuboid bent at its middle joint, rigid and dual-quaternion) and docs/images/deform_phantom.png (the
phantom at rest and in a walking stride, side views coloured by the bone each voxel came from).

Run:  PYTHONPATH=python /usr/bin/python3 scripts/deform_pictures.py [-o docs/images]
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "benchmarks"))

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402
from bench_deform import walking_pose  # noqa: E402


def bend_figure(path):
    Z, Y, X = 128, 64, 64
    z, y, x = np.mgrid[0:Z, 0:Y, 0:X]
    vol = np.zeros((Z, Y, X), np.uint8)
    along = (z >= 29) & (z < 99)
    vol[((x - 31.5) ** 2 + (y - 31.5) ** 2 < 16 ** 2) & along] = 100
    vol[(np.abs(x - 31.5) < 6) & (np.abs(y - 31.5) < 6) & along] = 200
    volume = volrig.Volume(vol)
    mask = volrig.segment(volume)
    pts = volrig.skeletonize(mask, metric="chamfer345").at(1.0)
    rig = volrig.Rig(joints=[[31.5, 31.5, 29], [31.5, 31.5, 64], [31.5, 31.5, 98]], bones=[[0, 1], [1, 2]],
                     names=["lower", "upper"])
    rigid = volrig.Deformer(volume, pts, volrig.bind(pts, rig, mask))
    smooth = volrig.Deformer(volume, pts, volrig.bind(pts, rig, mask, mode="smooth"))
    angles = (0, 60, 90, 120)
    fig, axes = plt.subplots(2, len(angles), figsize=(2.6 * len(angles), 6.2))
    for row, (name, d, mode) in enumerate((("rigid", rigid, "rigid"), ("dual quaternion", smooth, "dual_quaternion"))):
        for col, a in enumerate(angles):
            M = volrig.rest_pose(2)
            M[1] = volrig.rotation_about([1, 0, 0], a, rig.joints[1])
            f = d.frame(M, mode=mode)
            arr = f.values.array
            ax = axes[row, col]
            ax.imshow(arr[:, :, arr.shape[2] // 2], origin="lower", cmap="bone", vmin=0, vmax=220)
            ax.set_title(f"{name}, {a}°", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle(f"Bend test (thesis §6.3.1): {len(pts):,} spheres, two bones, power proximity; mid slice (y, z)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def side_view(ax, frame, bones):
    """Draws a frame seen along x (from -x): each pixel the first covered voxel, coloured by its bone and shaded
    by depth, in world y/z units."""
    cmap = plt.get_cmap("tab20", bones + 1)
    lab = frame.bone.array  # [z, y, x]
    depth = np.argmax(lab > 0, axis=2)
    side = np.take_along_axis(lab, depth[..., None], axis=2)[..., 0]
    shade = np.where(side > 0, 0.55 + 0.45 * (1 - depth / max(lab.shape[2], 1)), 1.0)
    rgb = cmap(side)[..., :3] * shade[..., None]
    rgb[side == 0] = 1.0
    (_, sy, sz), (_, y0, z0) = frame.bone.spacing, frame.bone.origin
    ax.imshow(rgb, origin="lower", extent=(y0, y0 + sy * lab.shape[1], z0, z0 + sz * lab.shape[0]))


def phantom_figure(path):
    ph = phantom.humanoid(0.5)
    mask = volrig.segment(ph.volume)
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    d = volrig.Deformer(ph.volume, pts, volrig.bind(pts, rig, mask))
    frames = [("rest", d.frame(volrig.rest_pose(len(rig)))), ("walking stride", d.frame(walking_pose(rig)))]
    fig, axes = plt.subplots(1, 2, figsize=(7.5, 7.5))
    for ax, (title, f) in zip(axes, frames):
        side_view(ax, f, len(rig))
        ax.set_title(f"{title}: {f.stats['covered']:,} voxels", fontsize=10)
        ax.set_xlabel("y")
        ax.set_ylabel("z")
    fig.suptitle("The phantom (scale 0.5, 15,000 spheres, 21 bones) reconstructed per frame; colour = bone", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=os.path.join(HERE, "..", "docs", "images"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    bend_figure(os.path.join(args.out, "deform_bend.png"))
    phantom_figure(os.path.join(args.out, "deform_phantom.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

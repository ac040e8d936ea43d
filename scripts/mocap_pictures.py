#!/usr/bin/env python3
"""Contact sheet of the phantom walking with CMU motion capture: docs/images/mocap_walk.png.

The phantom (scale 0.5, 15,000 spheres) is auto-rigged, driven in place by ../shared/data/bvh/131_01.bvh
(volrig.animate) and reconstructed per frame (volrig.Deformer, dual-quaternion blend of a smooth binding); each
frame is drawn from the side, coloured by bone.

Run:  PYTHONPATH=python /usr/bin/python3 scripts/mocap_pictures.py [--clip ../shared/data/bvh/131_01.bvh]
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402
from volrig_support import data_root  # noqa: E402
from deform_pictures import side_view  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clip", default=str(data_root() / "bvh" / "131_01.bvh"))
    ap.add_argument("--first", type=int, default=120, help="first BVH frame (0-based)")
    ap.add_argument("--count", type=int, default=8)
    ap.add_argument("--step", type=int, default=16, help="BVH frames between pictures (120 fps)")
    ap.add_argument("-o", "--out", default=os.path.join(HERE, "..", "docs", "images", "mocap_walk.png"))
    args = ap.parse_args()
    if not os.path.exists(args.clip):
        print(f"mocap_pictures: {args.clip} not found (the ../shared/data folder sits beside the checkout)")
        return 2
    clip = volrig.read_bvh(args.clip)
    ph = phantom.humanoid(0.5)
    mask = volrig.segment(ph.volume)
    pts = volrig.skeletonize(mask).top(15000)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask)
    d = volrig.Deformer(ph.volume, pts, volrig.bind(pts, rig, mask, mode="smooth"))
    frames = list(range(args.first, args.first + args.count * args.step, args.step))
    M = volrig.animate(rig, clip, frames=frames, root_motion="in_place")
    fig, axes = plt.subplots(1, len(frames), figsize=(1.6 * len(frames), 3.3))
    for ax, f, m in zip(axes, frames, M):
        side_view(ax, d.frame(m, mode="dual_quaternion"), len(rig))
        ax.set_title(f"BVH frame {f + 1}\n{f / 120:.2f} s", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlim(-130, 220)
        ax.set_ylim(-5, 480)
    axes[0].set_ylabel("z (side view)")
    fig.suptitle(f"The phantom walking with CMU 131_01 (in place): {len(pts):,} spheres, {len(rig)} bones, "
                 "dual-quaternion frames; colour = bone", fontsize=9)
    fig.tight_layout()
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

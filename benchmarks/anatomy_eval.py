#!/usr/bin/python3
"""Issue 18's measure: do bones stay rigid when a labelled body bends? The Visible Human (bone codes 84 and 92
as the rigid tissue) is rigged, a knee and an elbow are bent, and the dual-quaternion frame of a smooth binding
(with and without ``rigid=``, with the default ``keep_volume`` and with the plain blend) is compared with the rigid frame of the same pose: per rig bone, the Dice overlap of
the bone tissue that bone carries at rest (its piece of the label map's bone, sampled nearest) where it lands,
and the body's voxel count against rest.

    PYTHONPATH=python /usr/bin/python3 benchmarks/anatomy_eval.py [--mm 4] [--points 15000] [--knee 90] [--elbow 70]

--knee and --elbow are the pose's rotations (degrees) of shin.L and forearm.R about the body's left-right axis
(the Visible Human's elbows are bent about 50 degrees at rest: --elbow 70 makes about 120).
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import volrig  # noqa: E402
from volrig import subjects as S  # noqa: E402

BONE = (84, 92)


def bone_pieces(labels, pts, rig, binding):
    """The source's bone tissue labelled by the rig bone carrying it at rest (1 + bone; 0 elsewhere): the rest
    frame's bone labels where the label map says bone, on the source grid."""
    rest = volrig.deform(labels, pts, binding, rig.pose({}), sampling="nearest")
    out = np.zeros(labels.array.shape, dtype=np.int16)
    o = np.array(rest.offset)
    sx, sy, sz = rest.bone.array.shape[::-1]
    out[o[2]:o[2] + sz, o[1]:o[1] + sy, o[0]:o[0] + sx] = np.asarray(rest.bone.array)
    out[~np.isin(np.asarray(labels.array), BONE)] = 0
    return labels.like(out)


def on_common_grid(frames):
    """The frames' values (bone pieces) and bone-label arrays placed in one box (source lattice)."""
    lo = np.min([f.offset for f in frames], axis=0)
    hi = np.max([np.array(f.offset) + np.array(f.bone.array.shape[::-1]) for f in frames], axis=0)
    out = []
    for f in frames:
        o = np.array(f.offset) - lo
        sx, sy, sz = f.bone.array.shape[::-1]
        tissue = np.zeros(tuple((hi - lo)[::-1]), dtype=np.int16)
        label = np.zeros(tuple((hi - lo)[::-1]), dtype=np.int16)
        tissue[o[2]:o[2] + sz, o[1]:o[1] + sy, o[0]:o[0] + sx] = np.rint(np.asarray(f.values.array))
        label[o[2]:o[2] + sz, o[1]:o[1] + sy, o[0]:o[0] + sx] = np.asarray(f.bone.array)
        out.append((tissue, label))
    return out


def dice(a, b):
    s = a.sum() + b.sum()
    return 1.0 if s == 0 else 2.0 * np.logical_and(a, b).sum() / s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mm", type=int, default=4)
    ap.add_argument("--points", type=int, default=15000)
    ap.add_argument("--knee", type=float, default=90.0)
    ap.add_argument("--elbow", type=float, default=70.0)
    args = ap.parse_args()
    labels = S.visible_human_labels(args.mm)
    mask = labels.like(np.asarray(labels.array) > 0)
    bone = volrig.rigid_tissue(labels, labels=BONE)
    pts = volrig.skeletonize(mask).top(args.points)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=np.array([0.0, 0.0, 1.0]))
    pose = rig.pose({"shin.L": ([1, 0, 0], args.knee), "forearm.R": ([1, 0, 0], -args.elbow)})
    t0 = time.perf_counter()
    rigid_binding = volrig.bind(pts, rig, mask)
    pieces = bone_pieces(labels, pts, rig, rigid_binding)
    smooth = volrig.bind(pts, rig, mask, mode="smooth")
    with_bone = volrig.bind(pts, rig, mask, mode="smooth", rigid=bone)
    frames = {"rigid binding, rigid": volrig.deform(pieces, pts, rigid_binding, pose, sampling="nearest")}
    for keep in (True, False):  # keep_volume: the smooth modes' volume kept at bends (the default), or the plain blend
        tag = "" if keep else ", plain blend"
        frames["smooth, dual quaternion" + tag] = volrig.deform(pieces, pts, smooth, pose, mode="dual_quaternion",
                                                                 sampling="nearest", keep_volume=keep)
        frames["smooth + rigid bone, dual quaternion" + tag] = volrig.deform(
            pieces, pts, with_bone, pose, mode="dual_quaternion", sampling="nearest", keep_volume=keep)
    print(f"Visible Human {args.mm} mm, {len(pts)} points, {len(rig)} bones; knee {args.knee:g}, elbow "
          f"{args.elbow:g} degrees; {len(frames)} frames in {time.perf_counter() - t0:.1f} s")
    grids = on_common_grid(list(frames.values()))
    (t_ref, l_ref) = grids[0]
    rest = int(np.asarray(mask.array).sum())
    watch = ["thigh.L", "shin.L", "upper_arm.R", "forearm.R", "hand.R"]
    print(f"{'frame':50s} {'body voxels vs rest':>20s}  " + "  ".join(f"{n:>11s}" for n in watch) + "   worst bone")
    for (name, f), (t, l) in zip(frames.items(), grids):
        body = int((np.asarray(f.bone.array) > 0).sum())
        per = {}
        for b, n in enumerate(rig.names):  # the bone tissue rig bone b carries at rest, where it lands
            per[n] = dice(t == b + 1, t_ref == b + 1)
        worst = min(per, key=per.get)
        print(f"{name:50s} {100.0 * (body - rest) / rest:+19.2f}%  " +
              "  ".join(f"{per[n]:11.3f}" for n in watch) + f"   {worst} {per[worst]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

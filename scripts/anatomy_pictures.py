#!/usr/bin/env python3
"""docs/images/anatomy_knee.png: the Visible Human's left knee bent 90 degrees, a sagittal slice through the joint
coloured by tissue: at rest, with plain smooth binding (the ends of femur and tibia bend with the flesh) and with
the rigid bone layer (``bind(..., rigid=)``: the bones move whole, the flesh bends around them); dual quaternion.
docs/images/anatomy_contact.png: the knee folded to 150 degrees, coloured by the limb each voxel's tissue comes from
(sliding contact: where the thigh and the shin meet).

Run:  PYTHONPATH=python /usr/bin/python3 scripts/anatomy_pictures.py [--mm 2] [--knee 90] [-o docs/images]
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: subjects

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import volrig  # noqa: E402
from volrig_support import subjects as S  # noqa: E402
from volrig.tissues import read_tissue_table, tissue_classes  # noqa: E402

BONE = (84, 92)


def colours(labels):
    """An RGB lookup table over the label codes: each code its tissue class's colour, background black."""
    table = read_tissue_table(S._data("visible-human/austinman_tissues.tsv"))
    lut = np.zeros((256, 3))
    for t in tissue_classes(table):
        lut[t.codes] = t.color
    return lut


def on_source(frame, shape):
    """A frame's values placed on the source grid (what falls outside is dropped)."""
    out = np.zeros(shape, np.int32)
    o = np.array(frame.offset)
    v = np.rint(np.asarray(frame.values.array)).astype(np.int32)
    lo, hi = np.maximum(o, 0), np.minimum(o + np.array(v.shape[::-1]), np.array(shape[::-1]))
    out[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] = v[lo[2] - o[2]:hi[2] - o[2], lo[1] - o[1]:hi[1] - o[1],
                                                   lo[0] - o[0]:hi[0] - o[0]]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mm", type=int, default=2)
    ap.add_argument("--knee", type=float, default=90.0)
    ap.add_argument("--fold", type=float, default=150.0, help="the knee's bend in anatomy_contact.png")
    ap.add_argument("--points", type=int, default=15000)
    ap.add_argument("-o", "--out", default=os.path.join(HERE, "..", "docs", "images"))
    args = ap.parse_args()
    labels = S.visible_human_labels(args.mm)
    src = np.asarray(labels.array)
    mask = labels.like(src > 0)
    pts = volrig.skeletonize(mask).top(args.points)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=np.array([0.0, 0.0, 1.0]))
    plain = volrig.bind(pts, rig, mask, mode="smooth")
    anatomy = volrig.bind(pts, rig, mask, mode="smooth", rigid=volrig.rigid_tissue(labels, labels=BONE))
    shin = rig.names.index("shin.L")
    knee = rig.joints[rig.bones[shin][0]]
    pose = rig.pose({"shin.L": ([1, 0, 0], args.knee)})
    shots = [("rest", src),
             (f"plain smooth, knee {args.knee:g}°", on_source(
                 volrig.deform(labels, pts, plain, pose, mode="dual_quaternion", sampling="nearest"), src.shape)),
             (f"rigid bone layer, knee {args.knee:g}°", on_source(
                 volrig.deform(labels, pts, anatomy, pose, mode="dual_quaternion", sampling="nearest"), src.shape))]
    ijk = np.rint((knee - np.asarray(labels.origin)) / np.asarray(labels.spacing)).astype(int)
    half = int(round(130 / args.mm))  # 13 cm around the joint
    z0, z1 = max(ijk[2] - half, 0), min(ijk[2] + half, src.shape[0])
    y0, y1 = max(ijk[1] - half, 0), min(ijk[1] + half + half // 2, src.shape[1])
    lut = colours(labels)
    fig, axes = plt.subplots(1, len(shots), figsize=(3.6 * len(shots), 4.2))
    for ax, (name, arr) in zip(axes, shots):
        sl = arr[z0:z1, y0:y1, ijk[0]]  # sagittal: z up, y (posterior) to the right
        ax.imshow(lut[np.clip(sl, 0, 255)], origin="lower", interpolation="nearest",
                  extent=(y0 * args.mm, y1 * args.mm, z0 * args.mm, z1 * args.mm))
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("anterior → posterior (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(f"Visible Human {args.mm} mm, left knee, sagittal slice (bone white, muscle red, fat yellow)",
                 fontsize=10)
    fig.tight_layout()
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "anatomy_knee.png")
    fig.savefig(path, dpi=110)
    print(path)
    contact_picture(labels, pts, rig, anatomy, args, (z0, z1, y0, y1, ijk[0]))


def contact_picture(labels, pts, rig, binding, args, view):
    """docs/images/anatomy_contact.png: the knee folded to --fold degrees, the same slice coloured by where each
    voxel's tissue comes from (the thigh's territory at rest, the shin's, elsewhere; bone white): the plain blend
    (keep_volume=False: the radical planes of the balls decide where the limbs meet) beside the default
    (keep_volume: volume kept, and the limbs meet at the bend's bisector plane)."""
    thigh, shin = rig.names.index("thigh.L") + 1, rig.names.index("shin.L") + 1
    d = volrig.Deformer(labels, pts, binding)
    rest = on_source(d.frame(volrig.rest_pose(len(rig)), mode="dual_quaternion", sampling="nearest"),
                     labels.array.shape)
    owner = on_source_bone(d.frame(volrig.rest_pose(len(rig)), mode="dual_quaternion", sampling="nearest"),
                           labels.array.shape)
    origin = np.where(owner == thigh, 1, np.where(owner == shin, 2, np.where(owner > 0, 3, 0)))
    origin[np.isin(rest, BONE)] = 4
    limb = volrig.Deformer(labels.like(origin.astype(np.uint8)), pts, binding)
    pose = rig.pose({"shin.L": ([1, 0, 0], args.fold)})
    lut = np.array([[0, 0, 0], [0.85, 0.35, 0.25], [0.25, 0.45, 0.85], [0.55, 0.55, 0.55], [1, 1, 1]])
    shots = [("rest", origin)]
    for name, keep in (("plain blend (keep_volume=False)", False), ("volume kept, limbs in contact", True)):
        f = limb.frame(pose, mode="dual_quaternion", sampling="nearest", keep_volume=keep)
        shots.append((f"{name}, knee {args.fold:g}°", on_source(f, labels.array.shape)))
    z0, z1, y0, y1, x = view
    fig, axes = plt.subplots(1, len(shots), figsize=(3.6 * len(shots), 4.2))
    for ax, (name, arr) in zip(axes, shots):
        ax.imshow(lut[np.clip(arr[z0:z1, y0:y1, x], 0, 4)], origin="lower", interpolation="nearest",
                  extent=(y0 * args.mm, y1 * args.mm, z0 * args.mm, z1 * args.mm))
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("anterior → posterior (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(f"Visible Human {args.mm} mm, left knee: tissue from the thigh (red), the shin (blue), "
                 "elsewhere (grey); bone white", fontsize=10)
    fig.tight_layout()
    path = os.path.join(args.out, "anatomy_contact.png")
    fig.savefig(path, dpi=110)
    print(path)


def on_source_bone(frame, shape):
    """A frame's bone labels placed on the source grid."""
    out = np.zeros(shape, np.int32)
    o = np.array(frame.offset)
    v = np.asarray(frame.bone.array).astype(np.int32)
    lo, hi = np.maximum(o, 0), np.minimum(o + np.array(v.shape[::-1]), np.array(shape[::-1]))
    out[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] = v[lo[2] - o[2]:hi[2] - o[2], lo[1] - o[1]:hi[1] - o[1],
                                                   lo[0] - o[0]:hi[0] - o[0]]
    return out


if __name__ == "__main__":
    main()

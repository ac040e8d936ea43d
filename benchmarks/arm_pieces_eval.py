#!/usr/bin/env python3
"""Issue 56's speck: tissue the showcase's binding sends off with the wrong bone of an arm, at 1, 2 and 4 mm.

Rigs the Visible Human (AustinMan labels, ../shared/data/visible-human) as scripts/showcase.py does (body = codes
not outside, thinness 0.5 voxel, humanoid, +z up, the tissue table's bone rigid, smooth binding), then measures:

1. **rest**: voxels of groin or leg tissue (erectile tissue, code 179) whose owner at rest
   (``pipeline.rest_labels``) is a bone of an arm; and the voxels each hand bone owns;
2. **rigid moves**: skeleton points the rigid layer gives to another bone than the geodesic binding did, by
   (geodesic bone -> final bone), e.g. points on the hand's bones that move with the upper arm;
3. **posed**: the pose at BVH frame 183 of 131_01 (the hand swung forward: the speck of docs/tissues.md) deformed
   as the showcase bakes it (linear, nearest sampling), and for each bone of the arms the voxels it labels that lie
   in pieces apart from the body (26-connected pieces of the frame cropped to that bone's voxels with 40 voxels
   around, not touching the crop's border). A piece of a hand floating free is what the video showed.

    PYTHONPATH=python:tests/support /usr/bin/python3 benchmarks/arm_pieces_eval.py --mm 1 [--mm 2 --mm 4]

Peak memory at 1 mm: about 6 GB.
"""
import argparse
import os
import sys
import time
from collections import Counter

import numpy as np
from scipy import ndimage

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "tests", "support"), os.path.join(REPO, "scripts")]

import volrig  # noqa: E402
from volrig import pipeline  # noqa: E402
from volrig_support import data_root  # noqa: E402
from showcase_plan import rig_labels  # noqa: E402

VHM = data_root() / "visible-human"
CLIP = data_root() / "bvh" / "131_01.bvh"
ARM = ("upper_arm", "forearm", "hand")


def rigged(mm: int):
    """(labels, body, the RiggedSkeleton) of the AustinMan at ``mm`` rigged as the showcase does."""
    labels = volrig.load(str(VHM / f"austinman_{mm}mm_labels.nii.gz"))
    table = volrig.read_tissue_table(str(VHM / "austinman_tissues.tsv"))
    tissues = volrig.tissue_classes(table, present=np.unique(labels.array))
    body, r = rig_labels(labels, table, tissues, 0.5, "humanoid", (0, 0, 1))
    return labels, body, r


def rest_figures(labels, body, r) -> str:
    rest = pipeline.rest_labels(labels, r.points, r.binding, body).array
    names = list(r.rig.names)
    arm = [names.index(f"{b}.{s}") + 1 for b in ARM for s in "LR"]
    groin = int((np.isin(rest, arm) & (labels.array == 179)).sum())
    hands = ", ".join(f"hand.{s} {int((rest == names.index(f'hand.{s}') + 1).sum()):,}" for s in "LR")
    return f"erectile voxels owned by an arm bone {groin:,}; voxels owned: {hands}"


def rigid_moves(body, r) -> str:
    plain = volrig.rig.bind(r.points, r.rig, body, mode="smooth")
    names = list(r.rig.names)
    moves = Counter((names[a], names[b]) for a, b in zip(plain.bone, r.binding.bone) if a != b)
    return ", ".join(f"{a}->{b} {n}" for (a, b), n in moves.most_common(6)) or "none"


def apart(bb, vv, h: int):
    """(voxels labelled h, of them in pieces apart from the body, their codes) of a bricked frame."""
    idx = np.nonzero(bb == h)
    if len(idx[0]) == 0:
        return 0, 0, {}
    zyx = [idx[k] * 8 + idx[k + 3] for k in range(3)]
    lo = np.maximum([a.min() - 40 for a in zyx], 0)
    hi = np.minimum([a.max() + 41 for a in zyx], np.array(bb.shape[:3]) * 8)
    b0, b1 = lo // 8, (hi + 7) // 8
    part = bb[b0[0]:b1[0], b0[1]:b1[1], b0[2]:b1[2]]
    nb = part.shape[:3]
    occ = part.transpose(0, 3, 1, 4, 2, 5).reshape(nb[0] * 8, nb[1] * 8, nb[2] * 8) > 0
    lab, _ = ndimage.label(occ, structure=np.ones((3, 3, 3), bool))
    border = np.unique(np.concatenate([f.ravel() for f in (lab[0], lab[-1], lab[:, 0], lab[:, -1], lab[:, :, 0],
                                                           lab[:, :, -1])]))
    own = lab[tuple(a - b * 8 for a, b in zip(zyx, b0))]
    free = ~np.isin(own, border)
    codes = Counter(vv[idx][free].astype(np.float32).astype(int).tolist())
    return len(own), int(free.sum()), dict(codes.most_common(5))


def posed_figures(labels, r, bvh_frame: int) -> list:
    motion = volrig.read_bvh(str(CLIP))
    _, M = pipeline.mocap_poses(r.rig, motion, [bvh_frame - 1], up_axis="y")
    d = volrig.Deformer(labels, r.points, r.binding, lattice_after=-1)
    fr = d.frame(M[0], mode="linear", sampling="nearest", bricks=True, half=True)
    names, out = list(r.rig.names), []
    for s in "LR":
        for b in ARM:
            n, free, codes = apart(fr.brick_bone, fr.brick_values, names.index(f"{b}.{s}") + 1)
            out.append(f"{b}.{s}: {free:,} of {n:,} apart" + (f" (codes {codes})" if free else ""))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mm", type=int, action="append", choices=[1, 2, 4], help="resolution(s), default 4 2 1")
    ap.add_argument("--frame", type=int, default=183, help="BVH frame of 131_01 posed (1-based)")
    args = ap.parse_args()
    if not VHM.is_dir() or not CLIP.is_file():
        raise SystemExit(f"arm_pieces_eval: {VHM} or {CLIP} not found (the data live in ../shared/data)")
    for mm in args.mm or [4, 2, 1]:
        t = time.perf_counter()
        labels, body, r = rigged(mm)
        print(f"{mm} mm: rigged in {time.perf_counter() - t:.0f} s, {len(r.points):,} spheres", flush=True)
        print(f"  rest: {rest_figures(labels, body, r)}", flush=True)
        print(f"  rigid moves (geodesic bone -> final): {rigid_moves(body, r)}", flush=True)
        print(f"  posed at BVH {args.frame}, voxels in pieces apart from the body: " +
              "; ".join(posed_figures(labels, r, args.frame)), flush=True)
        del labels, body, r


if __name__ == "__main__":
    main()

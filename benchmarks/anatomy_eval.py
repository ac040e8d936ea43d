#!/usr/bin/python3
"""Issue 18's measure: do bones stay rigid when a labelled body bends? The Visible Human (bone codes 84 and 92
as the rigid tissue) is rigged, a knee and an elbow are bent, and the dual-quaternion frame of a smooth binding
(with and without ``rigid=``, with the default ``keep_volume`` and with the plain blend) is compared with the rigid frame of the same pose: per rig bone, the Dice overlap of
the bone tissue that bone carries at rest (its piece of the label map's bone, sampled nearest) where it lands,
against that piece moved by its bone's matrix alone; the body's voxel count against rest and the background
voxels the frame encloses that the rest frame does not (holes in the soft tissue). Binding time with and without
rigid tissue.

    PYTHONPATH=python /usr/bin/python3 benchmarks/anatomy_eval.py [--mm 4] [--points 15000] [--knee 90] [--elbow 70]
                                                  [--mode dual_quaternion]

--knee and --elbow are the pose's rotations (degrees) of shin.L and forearm.R about the body's left-right axis
(the Visible Human's elbows are bent about 50 degrees at rest: --elbow 70 makes about 120).
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "support"))
import volrig  # noqa: E402
from volrig_support import subjects as S  # noqa: E402
from volrig.deform import Frame  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "python"))
# the reference of "a piece moved by its bone": plain numpy, written apart from the core's painter
from test_rigid_layer import piece_moved  # noqa: E402

BONE = (84, 92)


def layer_pieces(labels, pts, binding, pose_mode):
    """The label map's bone tissue labelled by the rig bone whose rigid layer carries it (1 + bone; 0 elsewhere),
    on the source grid: the pieces ``volrig.rigid_layer`` reads from the binding's rest frame."""
    d = volrig.Deformer(labels, pts, binding)
    d.frame(volrig.rest_pose(binding.weights.shape[1]), mode=pose_mode, sampling="nearest", values=False)
    out = np.zeros(labels.array.shape, dtype=np.int16)
    for p in d._layer.pieces:
        x, y, z = p.box[:3]
        sz, sy, sx = p.voxels.shape
        out[z:z + sz, y:y + sy, x:x + sx][p.voxels > 0] = p.bone + 1
    return labels.like(out), d._layer.pieces


def moved_pieces(pieces, pose, labels):
    """The reference: each piece moved by its bone's matrix alone, as a Frame (values = 1 + bone) on the source
    lattice."""
    claims = [(p.bone, piece_moved(p, np.asarray(pose[p.bone]), labels.spacing, labels.origin)) for p in pieces]
    q_all = np.concatenate([q for _, q in claims])
    lo, hi = q_all.min(0), q_all.max(0) + 1
    arr = np.zeros(tuple((hi - lo)[::-1]), np.int16)
    for b, q in claims:
        i = q - lo
        arr[i[:, 2], i[:, 1], i[:, 0]] = b + 1
    return Frame(volrig.Volume(arr.astype(np.float32), labels.spacing),
                 volrig.Volume(arr, labels.spacing), tuple(int(v) for v in lo), {})


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


def enclosed_background(covered):
    """Background voxels the covered voxels enclose (holes inside the body)."""
    from scipy import ndimage
    return int((ndimage.binary_fill_holes(covered) & ~covered).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mm", type=int, default=4)
    ap.add_argument("--points", type=int, default=15000)
    ap.add_argument("--knee", type=float, default=90.0)
    ap.add_argument("--elbow", type=float, default=70.0)
    ap.add_argument("--mode", default="dual_quaternion", choices=("dual_quaternion", "linear"))
    args = ap.parse_args()
    labels = S.visible_human_labels(args.mm)
    mask = labels.like(np.asarray(labels.array) > 0)
    bone = volrig.rigid_tissue(labels, labels=BONE)
    pts = volrig.skeletonize(mask).top(args.points)
    rig = volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=np.array([0.0, 0.0, 1.0]))
    pose = rig.pose({"shin.L": ([1, 0, 0], args.knee), "forearm.R": ([1, 0, 0], -args.elbow)})
    t0 = time.perf_counter()
    plain = volrig.bind(pts, rig, mask, mode="smooth")
    t_plain = time.perf_counter() - t0
    t0 = time.perf_counter()
    anatomy = volrig.bind(pts, rig, mask, mode="smooth", rigid=bone)
    t_anatomy = time.perf_counter() - t0
    print(f"binding: plain {t_plain:.3f} s, with rigid tissue {t_anatomy:.3f} s ({t_anatomy / t_plain:.2f}x)")
    # Frame cost: CPU seconds (both threads), interleaved, best of 3, so that other jobs' load counts less.
    deformers = {"plain": volrig.Deformer(labels, pts, plain, lattice_after=0),  # (frames with the lattice tables)
                 "rigid layer": volrig.Deformer(labels, pts, anatomy, lattice_after=0)}
    # (the rigid layer's frame also with the plain blend: what keep_volume, the bend model and the sliding contact,
    # cost)
    runs = {"plain": ("plain", True), "rigid layer": ("rigid layer", True), "layer, plain blend": ("rigid layer", False)}
    first, best, contact = {}, {}, {}
    for name, (d, keep) in runs.items():
        t0 = time.perf_counter()
        contact[name] = deformers[d].frame(pose, mode=args.mode, sampling="nearest", keep_volume=keep).stats["contact"]
        first[name] = time.perf_counter() - t0
    for _ in range(3):
        for name, (d, keep) in runs.items():
            t0 = time.process_time()
            deformers[d].frame(pose, mode=args.mode, sampling="nearest", keep_volume=keep)
            best[name] = min(best.get(name, float("inf")), time.process_time() - t0)
    del deformers
    print(f"frame (CPU s, best of 3 interleaved): plain {best['plain']:.3f}, with the rigid layer "
          f"{best['rigid layer']:.3f} ({best['rigid layer'] / best['plain']:.2f}x); first frame (per-rig data, and "
          f"the layer's rest frame; wall s) {first['plain']:.2f} / {first['rigid layer']:.2f}")
    print(f"keep_volume (bend model and sliding contact, {contact['rigid layer']:,} voxels given up): the layered "
          f"frame {best['rigid layer'] / best['layer, plain blend']:.2f}x its plain blend's "
          f"({best['layer, plain blend']:.3f} s)")
    pieces, piece_list = layer_pieces(labels, pts, anatomy, args.mode)
    t0 = time.perf_counter()
    frames = {
        "each piece moved by its bone (reference)": moved_pieces(piece_list, pose, labels),
        "thesis rigid frame (rigid binding)": volrig.deform(pieces, pts, volrig.bind(pts, rig, mask), pose,
                                                            sampling="nearest"),
        f"smooth, {args.mode}": volrig.deform(pieces, pts, plain, pose, mode=args.mode, sampling="nearest"),
        f"smooth + rigid layer, {args.mode}": volrig.deform(pieces, pts, anatomy, pose, mode=args.mode,
                                                            sampling="nearest"),
        # keep_volume=False: the plain blend, without the smooth modes' volume kept at bends
        f"smooth, {args.mode}, plain blend": volrig.deform(pieces, pts, plain, pose, mode=args.mode,
                                                           sampling="nearest", keep_volume=False),
        f"smooth + rigid layer, {args.mode}, plain blend": volrig.deform(pieces, pts, anatomy, pose, mode=args.mode,
                                                                         sampling="nearest", keep_volume=False),
    }
    print(f"Visible Human {args.mm} mm, {len(pts)} points, {len(rig)} bones; knee {args.knee:g}, elbow "
          f"{args.elbow:g} degrees; frames in {time.perf_counter() - t0:.1f} s")
    rest_frames = {name: volrig.deform(pieces, pts, b, volrig.rest_pose(len(rig)), mode=args.mode,
                                       sampling="nearest") for name, b in (("plain", plain), ("anatomy", anatomy))}
    rest_holes = {k: enclosed_background(np.asarray(f.bone.array) > 0) for k, f in rest_frames.items()}
    grids = on_common_grid(list(frames.values()))
    (t_ref, _) = grids[0]
    rest = int(np.asarray(mask.array).sum())
    watch = ["thigh.L", "shin.L", "upper_arm.R", "forearm.R", "hand.R"]
    print(f"{'frame':42s} {'body vs rest':>12s} {'holes':>6s}  " + "  ".join(f"{n:>11s}" for n in watch) +
          "   worst bone")
    for (name, f), (t, l) in zip(frames.items(), grids):
        covered = l > 0 if "reference" not in name else None
        body = "" if covered is None else f"{100.0 * (int(covered.sum()) - rest) / rest:+11.2f}%"
        holes = ""
        if covered is not None:
            base = rest_holes["anatomy" if "rigid layer" in name else "plain"]
            holes = f"{enclosed_background(covered) - base:+d}"
        per = {n: dice(t == b + 1, t_ref == b + 1) for b, n in enumerate(rig.names)
               if (np.asarray(pieces.array) == b + 1).any()}
        worst = min(per, key=per.get)
        print(f"{name:42s} {body:>12s} {holes:>6s}  " + "  ".join(f"{per.get(n, float('nan')):11.3f}" for n in watch)
              + f"   {worst} {per[worst]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

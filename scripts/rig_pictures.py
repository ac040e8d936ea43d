#!/usr/bin/python3
"""Pictures of automatic rigs: skeleton points, the level-set tree autorig works on, and the rig, over maximum
intensity projections of the mask. Writes docs/images/rig_<name>.png for the phantom humanoid, the capsule
humanoid in four poses (rig_poses.png: its rig against its true joints), the frog
(../shared/data/frogtissue), the Visible Human at 4 mm (../shared/data/visible-human) and every shared mesh
(../shared/data/meshes: arm, hand, knight, cow, lion, horse, camel; voxelized with 160 voxels along the longest
side), when present. The title gives the kind, the fit and the runner-up.

    PYTHONPATH=python /usr/bin/python3 scripts/rig_pictures.py [--out docs/images] [--only phantom,frog,arm,...]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig.rig import autorig, bind  # noqa: E402
from volrig.tree import skeleton_tree  # noqa: E402
from volrig_support import data_root  # noqa: E402

SHARED = str(data_root())


#: shared meshes: file, TGF with reference joints (or None), the two world axes to draw (horizontal, vertical)
MESHES = {
    "arm": ("arm.obj", "arm.tgf", ((0, 1), (0, 2))),
    "hand": ("hand.mesh", "hand.tgf", ((0, 1), (0, 2))),
    "knight": ("decimated-knight.off", None, ((0, 1), (2, 1))),
    "cow": ("cow.off", None, ((0, 1), (0, 2))),
    "lion": ("lion.off", None, ((0, 1), (2, 1))),
    "horse": ("horse_quad.obj", None, ((0, 1), (0, 2))),
    "camel": ("camel_b.obj", None, ((2, 1), (0, 2))),
}


def rig_case(name: str, mask: volrig.Volume, count: int, reference=None, own_scale: bool = True):
    """Skeleton at `count` points, tree, autorig (own_scale passed on), rigid binding; returns everything the
    picture needs."""
    sk = volrig.skeletonize(mask)
    pts = sk.top(count)
    t0 = time.perf_counter()
    tree = skeleton_tree(pts, mask)
    detail = []
    rig = autorig(pts, tree, mask, detail=detail, own_scale=own_scale)
    binding = bind(pts, rig, mask)
    seconds = time.perf_counter() - t0
    print(f"{name}: {len(pts)} points (TP {sk.tp_for_count(count):.3f}), {rig}, tree+autorig+bind {seconds:.2f} s")
    return dict(name=name, mask=mask, points=pts, tree=tree, rig=rig, detail=detail[0], binding=binding,
                reference=reference, seconds=seconds)


def save(fig, path: str, dpi: int) -> None:
    """The figure written atomically to ``path`` (PNG) and closed."""
    import matplotlib.pyplot as plt
    fig.tight_layout()
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    os.replace(tmp, path)
    print("wrote", path)


def draw(case, path: str, views=((0, 2), (1, 2))):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mask, pts, rig, det = case["mask"], case["points"], case["rig"], case["detail"]
    arr = mask.array
    sp, org = np.asarray(mask.spacing), np.asarray(mask.origin)
    fig, axes = plt.subplots(1, len(views), figsize=(5.5 * len(views), 7.5))
    axis_names = "xyz"
    for ax, (i, j) in zip(np.atleast_1d(axes), views):
        k = 3 - i - j  # the axis projected away
        proj = arr.max(axis=2 - k)  # array axes are [z, y, x]
        img = proj if (2 - j) < (2 - i) else proj.T  # rows = j, columns = i
        ext = (org[i] - sp[i] / 2, org[i] + sp[i] * (arr.shape[2 - i] - 0.5),
               org[j] - sp[j] / 2, org[j] + sp[j] * (arr.shape[2 - j] - 0.5))
        ax.imshow(img, origin="lower", cmap="Greys", alpha=0.25, extent=ext, aspect="equal")
        c = pts.centers
        ax.scatter(c[:, i], c[:, j], s=0.2, c=case["binding"].bone % 20, cmap="tab20", alpha=0.35, linewidths=0)
        nodes, edges, kept = det.nodes, det.node_edges, det.node_kept
        for u, v in edges:
            if kept[u] and kept[v]:
                ax.plot(nodes[[u, v], i], nodes[[u, v], j], "-", color="tab:blue", lw=0.6, alpha=0.7)
        for b, (h, t) in enumerate(rig.bones):
            ax.plot(rig.joints[[h, t], i], rig.joints[[h, t], j], "-", color="crimson", lw=2.2)
        ax.plot(rig.joints[:, i], rig.joints[:, j], "o", color="crimson", ms=3.5)
        if case["reference"] is not None:
            ref = case["reference"]
            ax.plot(ref[:, i], ref[:, j], "+", color="green", ms=10, mew=2)
        if rig.kind in ("humanoid", "quadruped", "winged"):
            for b, name in enumerate(rig.names):
                if name.endswith(".L") or name in ("head", "hips"):
                    h, t = rig.bones[b]
                    m = 0.5 * (rig.joints[h] + rig.joints[t])
                    ax.annotate(name, (m[i], m[j]), fontsize=6, color="black")
        ax.set_xlabel(axis_names[i])
        ax.set_ylabel(axis_names[j])
    fig.suptitle(f"{case['name']}: {len(pts):,} skeleton points, {rig.kind} rig of {len(rig)} bones, fit "
                 f"{rig.fit:.2f} (runner-up {rig.runner_up or 'none'} {rig.runner_up_fit:.2f})\n"
                 f"(points coloured by bone; blue: level-set tree; red: rig" +
                 ("; green +: reference joints)" if case["reference"] is not None else ")"), fontsize=9)
    save(fig, path, dpi=90)


def bone_case(name: str, mask: volrig.Volume, bone: volrig.Volume, count: int, up=None, reference=None):
    """A scan rigged from its bones (``autorig(..., bone=)``), drawn over its bone tissue."""
    pts = volrig.skeletonize(mask).top(count)
    t0 = time.perf_counter()
    tree = skeleton_tree(pts, mask)
    detail = []
    rig = autorig(pts, tree, mask, detail=detail, up=up, bone=bone)
    seconds = time.perf_counter() - t0
    moved = sum(j.moved for j in rig.bone_joints)
    print(f"{name}: {rig}, {moved} of {len(rig.bone_joints)} limb joints placed by the bones, {seconds:.2f} s"
          + (f" ({rig.note})" if rig.note else ""))
    return dict(name=f"{name}: {moved} of {len(rig.bone_joints)} limb joints from the bones", mask=bone,
                points=pts, tree=tree, rig=rig, detail=detail[0], binding=bind(pts, rig, mask), reference=reference,
                seconds=seconds)


def draw_bone_rigs(out: str, only: set) -> None:
    """Rigs from the bones over projections of each shared scan's bone tissue (docs/images/rig_bones_<scan>.png)."""
    vhm = os.path.join(SHARED, "visible-human", "austinman_2mm_labels.nii.gz")
    if "bones_vhm" in only and os.path.exists(vhm):
        from volrig_support import subjects as S
        labels = S.visible_human_labels(2)
        a = np.asarray(labels.array)
        ref = S.visible_human_joints(labels)
        draw(bone_case("Visible Human 2 mm (bone labels)", labels.like(a > 0), labels.like(np.isin(a, S.BONE_LABELS)), 15000,
                       up=(0, 0, 1), reference=np.array(list(ref.values()))),
             os.path.join(out, "rig_bones_vhm.png"), views=((0, 2), (1, 2)))
    if "bones_posed" in only and os.path.exists(vhm):
        from volrig.pipeline import rig_skeleton
        from volrig_support import subjects as S
        labels = S.visible_human_labels(2)
        a = np.asarray(labels.array)
        mask, bone = labels.like(a > 0), labels.like(np.isin(a, S.BONE_LABELS))
        rigged = rig_skeleton(volrig.skeletonize(mask).top(15000), mask, up=(0, 0, 1), rigid=bone, bone=bone)
        posed, ref = S.posed_visible_human(labels, rigged, 150, 15, S.visible_human_joints(labels))
        b = np.asarray(posed.array)
        draw(bone_case("Visible Human 2 mm, posed (arms up 150°, legs 15° apart)",
                       posed.like(b > 0), posed.like(np.isin(b, S.BONE_LABELS)), 15000, up=(0, 0, 1),
                       reference=np.array(list(ref.values()))),
             os.path.join(out, "rig_bones_posed.png"), views=((0, 2), (1, 2)))
    frog = os.path.join(SHARED, "frogtissue", "frogtissue.mhd")
    if "bones_frog" in only and os.path.exists(frog):
        vol = volrig.load(frog)  # organs and bones, no skin: the plan comes from the bone (label 13) itself
        draw(bone_case("frog (label 13 its skeleton)", volrig.segment(vol), volrig.rigid_tissue(vol, labels=[13]),
                       40000),
             os.path.join(out, "rig_bones_frog.png"), views=((0, 1), (0, 2)))
    if "bones_mouse" in only:  # synthetic: a small quadruped's bone labels, its tail longer than its trunk
        from volrig_support import subjects as S
        labels, _ = S.bones_only_quadruped(tail=14)
        draw(bone_case("small quadruped (synthetic bones), tail longer than its trunk",
                       volrig.segment(labels), volrig.rigid_tissue(labels, labels=[13]), 40000),
             os.path.join(out, "rig_bones_mouse.png"), views=((1, 2), (0, 1)))
    ct = os.path.join(SHARED, "totalseg", "example_ct.nii.gz")
    if "bones_ct" in only and os.path.exists(ct):
        vol = volrig.load(ct)  # an abdominal CT (part of a body): bone by Hounsfield units
        body = volrig.segment(vol, lo=-300, largest_component=True)  # the body: above -300 HU (air and lungs out)
        draw(bone_case("abdominal CT (bone 250-3000 HU)", body, volrig.rigid_tissue(vol, value_range=(250, 3000)),
                       15000),
             os.path.join(out, "rig_bones_ct.png"), views=((0, 2), (1, 2)))


def draw_poses(path: str, poses=("knees_apart", "wide", "stride", "tpose"), scale: float = 0.9):
    """The capsule humanoid (volrig_support.subjects.capsule_subject) in ``poses``, front view: its rig and true
    joints."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from volrig_support import subjects as S
    fig, axes = plt.subplots(1, len(poses), figsize=(3.4 * len(poses), 4.6))
    for ax, pose in zip(axes, poses):
        s = S.capsule_subject(pose, scale)
        pts = volrig.skeletonize(s.mask).top(15000)
        rig = autorig(pts, skeleton_tree(pts, s.mask), s.mask)
        ax.imshow(s.mask.array.max(axis=1), origin="lower", cmap="Greys", alpha=0.35)
        for head, tail in rig.bones[:, :2]:
            ax.plot(*rig.joints[[head, tail]][:, [0, 2]].T, "-o", color="C0", ms=3, lw=1.5)
        for name, p in s.joints.items():
            if not name.startswith("wrist"):  # the capsules have no wrist to find
                ax.plot(p[0], p[2], "x", color="C3", ms=8, mew=2)
        ax.set_title(f"{pose}: {rig.kind}, fit {rig.fit:.2f}", fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"autorig (blue) and the true limb joints (red x) of a capsule humanoid {scale:g} voxels per unit "
                 f"({s.mask.array.shape[0]} voxels tall), front view", fontsize=10)
    save(fig, path, dpi=80)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    ap.add_argument("--only", default=",".join(["phantom", "poses", "bird", "frog", "arm", *MESHES, "vhm4", "bones_vhm",
                                                "bones_posed", "bones_frog", "bones_mouse", "bones_ct"]),
                    help="comma list of pictures to draw (default: all)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    only = set(args.only.split(","))
    if "phantom" in only:
        ph = volrig.phantom.humanoid(0.5)
        ref = np.array([v for k, v in ph.joints.items()])
        draw(rig_case("phantom humanoid (scale 0.5)", volrig.segment(ph.volume), 15000, ref),
             os.path.join(args.out, "rig_phantom.png"))
    if "poses" in only:
        draw_poses(os.path.join(args.out, "rig_poses.png"))
    if "bird" in only:  # synthetic: two flat wings held out, two legs, a head (the winged template)
        from volrig_support import subjects as S
        bird = S.capsule_bird_subject(1.0)
        draw(rig_case("capsule bird (volrig_support.subjects.capsule_bird_subject)", bird.mask, 15000,
                      np.array(list(bird.joints.values()))),
             os.path.join(args.out, "rig_bird.png"), views=((0, 2), (1, 2)))
    frog = os.path.join(SHARED, "frogtissue", "frogtissue.mhd")
    if "frog" in only:
        if os.path.exists(frog):
            # Organs and thin bones without flesh: its 40,000 points rigged (autorig's own skeleton misses the front
            # legs); it still comes out as chains (docs/rig.md, Known limits).
            draw(rig_case("frog (frogtissue, labels > 0, own_scale=False)", volrig.segment(volrig.load(frog)), 40000,
                          own_scale=False),
                 os.path.join(args.out, "rig_frog.png"), views=((0, 1), (0, 2)))
        else:
            print(f"skipping the frog: {frog} is absent")
    arm = os.path.join(SHARED, "meshes", "arm.obj")
    if "arm" in only:
        if os.path.exists(arm) and hasattr(volrig, "voxelize"):
            v, f = volrig.read_mesh(arm)
            joints, _ = volrig.read_tgf(os.path.join(SHARED, "meshes", "arm.tgf"))
            draw(rig_case("libigl arm (arm.obj voxelized at 0.01)", volrig.voxelize(v, f, 0.01), 4000, joints),
                 os.path.join(args.out, "rig_arm.png"), views=((0, 1), (0, 2)))
        else:
            print("skipping the arm: arm.obj or volrig.voxelize is absent")
    for name, (file, tgf, views) in MESHES.items():
        path = os.path.join(SHARED, "meshes", file)
        if name == "arm" or name not in only:
            continue
        if not os.path.exists(path):
            print(f"skipping the {name}: {path} is absent")
            continue
        try:
            v, f = volrig.read_mesh(path)
        except ValueError as e:  # OFF and Medit come with the mesh readers' branch
            print(f"skipping the {name}: {e}")
            continue
        ref = volrig.read_tgf(os.path.join(SHARED, "meshes", tgf))[0] if tgf else None
        mask = volrig.voxelize(v, f, float(np.ptp(v, axis=0).max()) / 160)
        draw(rig_case(f"{name} ({file}, 160 voxels long)", mask, 15000, ref),
             os.path.join(args.out, f"rig_{name}.png"), views=views)
    draw_bone_rigs(args.out, only)
    vhm = os.path.join(SHARED, "visible-human", "austinman_4mm_labels.nii.gz")
    if "vhm4" in only:
        if os.path.exists(vhm):
            labels = volrig.load(vhm)
            # The body: every label but the outside air (0), its internal air (gut gas, airways) included.
            body = volrig.Volume((labels.array != 0).astype(np.uint8), labels.spacing, labels.origin)
            draw(rig_case("Visible Human (AustinMan 4 mm, labels other than 0)", body, 15000),
                 os.path.join(args.out, "rig_vhm4.png"), views=((0, 2), (1, 2)))
        else:
            print(f"skipping the Visible Human: {vhm} is absent")


if __name__ == "__main__":
    main()

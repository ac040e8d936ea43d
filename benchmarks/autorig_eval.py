#!/usr/bin/env python3
"""Evaluate volrig.autorig on the shared subjects (issue 16): the measuring stick for the automatic rig.

For every subject (volrig_support.subjects): segment -> skeletonize -> top N points -> skeleton_tree -> autorig -> bind,
and one table row per (subject, point count): voxels, points, kind expected/got, fit (Rig.fit when autorig gives
one), bones, the error of each reference joint (phantom: shoulders/elbows/wrists/hips/knees/ankles vs its true
joints; VHM: vs its bone-derived joints; hand/arm: each TGF joint vs the nearest rig joint) in local radii and mm
(world units), quadrupeds: head bone at the head end, a tail chain; the time of tree/autorig/bind. With
--rotations, the 24 axis-aligned rotations of the mask are rigged too (the rotated up passed when autorig accepts
up=) and the row says how many gave the same kind and joints mapping back within half a local radius.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/autorig_eval.py [--subjects phantom,vhm4,cow] [--scales 0.5,1]
      [--points 5000,40000] [--rotations] [--joints] [--pictures DIR] [--json out.json]
--pictures also draws the Visible Human's bone with its bone-derived joints (to check them by eye).
Default: every subject except vhm1 (phantom at scale 0.5 and 1; --slow adds vhm1 and phantom scale 2) and the
capsule humanoids (``--subjects capsules_wide,capsules_stride,...``, one per volrig_support.subjects.CAPSULE_POSES, at
--scales; their wrists, capsules as thin as the forearm, have no anatomy to place them by).
"""
import argparse
import inspect
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig_support import subjects as S  # noqa: E402

DEFAULT = ["phantom", "vhm4", "vhm2", "arm", "hand", "knight", "cow", "lion", "horse", "camel"]
LIMB_JOINTS = S.LIMB_JOINTS


def autorig_accepts(name: str) -> bool:
    return name in inspect.signature(volrig.autorig).parameters


def run_autorig(pts, tree, mask, up=None, kind=None):
    kw = {}
    if up is not None and autorig_accepts("up"):
        kw["up"] = np.asarray(up, dtype=np.float64)
    if kind is not None and autorig_accepts("kind"):
        kw["kind"] = kind
    return volrig.autorig(pts, tree, mask, **kw)


def rig_pipeline(mask, points, up=None):
    """Skeleton, tree, rig and binding of a mask with ``points`` skeleton points; times in seconds."""
    t = {}
    t0 = time.perf_counter()
    sk = volrig.skeletonize(mask)
    t["skeleton"] = time.perf_counter() - t0
    pts = sk.top(points)
    t0 = time.perf_counter()
    tree = volrig.skeleton_tree(pts, mask)
    t["tree"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rig = run_autorig(pts, tree, mask, up=up)
    t["autorig"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    volrig.bind(pts, rig, mask)
    t["bind"] = time.perf_counter() - t0
    return sk, pts, rig, t


def joint_errors(subject, rig, dt):
    """name -> (error in local radii, error in world units, local radius) for the subject's reference joints."""
    out = {}
    if subject.bones is not None:  # TGF skeleton: nearest rig joint
        for name, p in subject.joints.items():
            d = float(np.linalg.norm(rig.joints - p, axis=1).min()) if len(rig.joints) else np.inf
            r = S.local_radius(dt, subject.mask, p)
            out[name] = (d / r, d, r)
        return out
    for name in LIMB_JOINTS:
        if name not in subject.joints:
            continue
        p = subject.joints[name]
        r = S.local_radius(dt, subject.mask, p)
        q = S.rig_joint(rig, name)
        d = float(np.linalg.norm(q - p)) if q is not None else np.inf
        out[name] = (d / r, d, r)
    return out


def quadruped_checks(subject, rig):
    """Problems with a quadruped's rig (kind, head end, tail chain); None for other subjects."""
    return S.quadruped_problems(subject, rig) if subject.kind == "quadruped" else None


def rotation_check(subject, points, rig0, dt, verbose=False):
    """Over the 24 rotations (the rotated up passed): how many give the expected kind, how many the same bones
    (by name) whose ends map back within half a local radius of the unrotated rig's, and how many give the
    expected kind with up=None (the same rigs when autorig takes no up=)."""
    kind = same = free = 0
    for k, m in enumerate(S.rotations24()):
        rmask, to_rot = S.rotate_mask(subject.mask, m)
        _, pts, rig, _ = rig_pipeline(rmask, points, up=m @ subject.up)
        kind += rig.kind == subject.kind
        free_rig = rig
        if autorig_accepts("up"):
            free_rig = run_autorig(pts, volrig.skeleton_tree(pts, rmask), rmask)
        free += free_rig.kind == subject.kind
        worst = S.rig_difference(rig0, rig, to_rot,
                                 lambda p: S.local_radius(dt, subject.mask, p, S.SAME_JOINT_VOXELS))
        same += worst <= 0.5
        if verbose:
            print(f"    rotation {k:2d} {m.astype(int).tolist()}: {rig.kind} ({free_rig.kind} with up=None), "
                  f"{len(rig)} bones, worst bone end {worst:.2f} radii")
    return kind, same, free


def evaluate(subject, points, rotations=False, verbose=False, pictures=None):
    sk, pts, rig, t = rig_pipeline(subject.mask, points, up=subject.up)
    if pictures:
        os.makedirs(pictures, exist_ok=True)
        draw(subject, rig, os.path.join(pictures, f"{subject.name}_{len(pts)}.png"))
        if subject.name.startswith("vhm"):
            draw_bone_joints(subject, os.path.join(pictures, f"{subject.name}_bone_joints.png"))
    dt = sk.dt
    row = dict(subject=subject.name, voxels=int(sk.object_count), voxel=float(min(subject.mask.spacing)),
               points=len(pts), expected=subject.kind,
               kind=rig.kind, fit=getattr(rig, "fit", None), bones=len(rig), times=t,
               joints=joint_errors(subject, rig, dt), quadruped=quadruped_checks(subject, rig))
    if rotations:
        row["rotations"] = rotation_check(subject, points, rig, dt, verbose)
    return row


def draw(subject, rig, path):
    """Silhouettes along the three axes with the rig (red), the reference joints (green dots) and the up (blue)
    and head (orange) directions drawn from the centre: how the mesh metadata were read and rigs are inspected."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    m = subject.mask
    sp, org = np.asarray(m.spacing), np.asarray(m.origin)
    hi = org + (np.asarray(m.array.shape[::-1]) - 1) * sp
    centre = 0.5 * (org + hi)
    arrow = 0.3 * (hi - org).max()
    fig, axes = plt.subplots(1, 3, figsize=(15, 6))
    for ax, (a, b, along) in zip(axes, ((0, 1, 0), (0, 2, 1), (1, 2, 2))):
        ax.imshow(m.array.any(axis=along), origin="lower", cmap="gray_r", alpha=0.5,
                  extent=(org[a], hi[a], org[b], hi[b]))
        for h, t in rig.bones:
            ax.plot(rig.joints[[h, t], a], rig.joints[[h, t], b], "r-", lw=2)
        ax.plot(rig.joints[:, a], rig.joints[:, b], "r.", ms=6)
        if subject.joints:
            ref = np.array(list(subject.joints.values()))
            ax.plot(ref[:, a], ref[:, b], "go", ms=5, mfc="none")
        for v, c in ((subject.up, "blue"), (subject.head, "orange")):
            ax.annotate("", xy=(centre[a] + arrow * v[a], centre[b] + arrow * v[b]), xytext=(centre[a], centre[b]),
                        arrowprops=dict(color=c, width=2))
        ax.set_title(f"{subject.name}: {'xyz'[a]} right, {'xyz'[b]} up ({rig.kind})")
        ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=60)
    plt.close(fig)


def draw_bone_joints(subject, path):
    """The Visible Human's bone (max projections, front and side) with its bone-derived joints: to check them."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = S.visible_human_labels(int(subject.name[3:]))
    bone = np.isin(labels.array, S.BONE_LABELS)
    sp = np.asarray(labels.spacing)
    fig, axes = plt.subplots(1, 2, figsize=(12, 14))
    for ax, (a, along) in zip(axes, ((0, 1), (1, 2))):
        ax.imshow(bone.sum(axis=along), origin="lower", cmap="gray",
                  extent=(0, bone.shape[2 - a] * sp[a], 0, bone.shape[0] * sp[2]))
        for name, p in subject.joints.items():
            ax.plot(p[a], p[2], "+", color="r" if name.endswith(".L") else "c", ms=14, mew=2)
        ax.set_title(f"{subject.name} bone, {'xy'[a]} right, z up: joints .L red, .R cyan")
    fig.tight_layout()
    fig.savefig(path, dpi=55)
    plt.close(fig)


def fmt_fit(fit):
    if fit is None:
        return "-"
    if isinstance(fit, (int, float, np.floating)):
        return f"{float(fit):.2f}"
    return str(fit)[:12]


def print_row(row):
    j = row["joints"]
    if j:
        rad = np.array([v[0] for v in j.values()])
        mm = np.array([v[1] for v in j.values()])
        finite = np.isfinite(rad)
        within1 = int((rad <= 1).sum())
        within2 = int((rad <= 2).sum())
        js = (f"{within1}/{len(rad)}<=1r {within2}/{len(rad)}<=2r  median {np.median(rad):.2f}r "
              f"{np.median(mm):.3g}  worst {rad.max():.2f}r" + ("" if finite.all() else " (missing joints)"))
    else:
        js = "-"
    q = row["quadruped"]
    qs = "-" if q is None else ("ok" if not q else "; ".join(q))
    rot = row.get("rotations")
    rs = "-" if rot is None else f"{rot[0]} kind {rot[1]} same {rot[2]} free"
    t = row["times"]
    ok = "ok" if row["kind"] == row["expected"] else "WRONG"
    print(f"{row['subject']:<11} {row['voxels']:>10,} {row['points']:>7,} {row['expected']:>9}/{row['kind']:<9} "
          f"{ok:<5} {fmt_fit(row['fit']):>6} {row['bones']:>3}  {t['tree']:5.2f} {t['autorig']:5.2f} "
          f"{t['bind']:5.2f}  {qs:<22} {rs:<24} {js}")


def detail(row):
    for name, (r, d, lr) in row["joints"].items():
        print(f"    {name:<12} {r:6.2f} radii  {d:10.4g} = {d / row['voxel']:6.1f} voxels (local radius {lr:.4g})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--subjects", default=",".join(DEFAULT), help=f"comma list from {', '.join(S.SUBJECTS)}")
    ap.add_argument("--scales", default="0.5,1", help="phantom and capsule scales")
    ap.add_argument("--points", default="5000,15000,40000", help="comma list of skeleton point counts")
    ap.add_argument("--rotations", action="store_true", help="also rig the 24 axis-aligned rotations (slow)")
    ap.add_argument("--slow", action="store_true", help="add vhm1 and phantom scale 2")
    ap.add_argument("--voxels", type=int, default=S.MESH_VOXELS, help="mesh voxels along the longest side")
    ap.add_argument("--joints", action="store_true", help="print each reference joint's error")
    ap.add_argument("--json", help="write the rows to this JSON file")
    ap.add_argument("--pictures", help="draw each subject's silhouettes, rig and reference joints into this folder")
    args = ap.parse_args()

    names = [s for s in args.subjects.split(",") if s]
    scales = [float(s) for s in args.scales.split(",") if s]
    if args.slow:
        names += [n for n in ("vhm1",) if n not in names]
        scales += [s for s in (2.0,) if s not in scales]
    counts = [int(p) for p in args.points.split(",") if p]
    print(f"autorig accepts up={autorig_accepts('up')} kind={autorig_accepts('kind')}")
    print(f"{'subject':<11} {'voxels':>10} {'points':>7} {'expected/got':>19} {'':<5} {'fit':>6} {'B':>3}  "
          f"{'tree':>5} {'rig':>5} {'bind':>5}  {'quadruped':<22} {'rotations (of 24)':<24} "
          "reference joints (r = local radius)")
    rows = []
    for name in names:
        loads = [dict(scale=s) for s in scales] if name == "phantom" or name.startswith("capsules_") else \
            ([dict(voxels=args.voxels)] if name in S.MESHES else [{}])
        for kw in loads:
            try:
                subject = S.load_subject(name, **kw)
            except FileNotFoundError as e:
                print(f"{name:<11} skipped: {e}")
                continue
            for n in counts:
                row = evaluate(subject, n, args.rotations, args.joints, args.pictures)
                print_row(row)
                if args.joints:
                    detail(row)
                rows.append(row)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    return 0


if __name__ == "__main__":
    sys.exit(main())

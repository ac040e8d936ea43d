#!/usr/bin/env python3
"""Evaluate volrig.autorig on the shared subjects (issue 16): the measuring stick for the automatic rig.

For every subject (volrig.subjects): segment -> skeletonize -> top N points -> skeleton_tree -> autorig -> bind,
and one table row per (subject, point count): voxels, points, kind expected/got, fit (Rig.fit when autorig gives
one), bones, the error of each reference joint (phantom: shoulders/elbows/wrists/hips/knees/ankles vs its true
joints; VHM: vs its bone-derived joints; hand/arm: each TGF joint vs the nearest rig joint) in local radii and mm
(world units), quadrupeds: head bone at the head end, a tail chain; the time of tree/autorig/bind. With
--rotations, the 24 axis-aligned rotations of the mask are rigged too (the rotated up passed when autorig accepts
up=) and the row says how many gave the same kind and joints mapping back within half a local radius.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/autorig_eval.py [--subjects phantom,vhm4,cow] [--scales 0.5,1]
      [--points 15000,40000] [--rotations] [--json out.json]
Default: every subject except vhm1 (phantom at scale 0.5 and 1; --slow adds vhm1 and phantom scale 2).
"""
import argparse
import inspect
import itertools
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
from volrig import subjects as S  # noqa: E402

DEFAULT = ["phantom", "vhm4", "vhm2", "arm", "hand", "knight", "cow", "lion", "horse", "camel"]
LIMB_JOINTS = [f"{j}.{s}" for s in "LR" for j in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]


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
    """(head bone at the head end, tail chain present) for a quadruped subject; None when not applicable."""
    if subject.kind != "quadruped":
        return None
    along = rig.joints @ subject.head
    span = along.max() - along.min() if len(along) else 0.0
    head_ok = False
    if "head" in rig.names:
        tip = rig.joints[rig.bones[rig.names.index("head")][1]] @ subject.head
        head_ok = bool(tip > along.min() + 0.75 * span)
    tail = [n for n in rig.names if n.startswith("tail")]
    return head_ok, len(tail)


def rotations24():
    """The 24 proper axis permutations with signs: (perm, signs) acting on (x, y, z)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product([-1, 1], repeat=3):
            m = np.zeros((3, 3))
            for i, (p, s) in enumerate(zip(perm, signs)):
                m[i, p] = s
            if np.linalg.det(m) > 0:
                out.append(m)
    return out


def rotate_mask(mask, m):
    """The mask's array rotated by m (acting on world xyz, x' = m x about the grid's corner) and the map taking a
    world point of the original to the rotated grid's world."""
    a = mask.array.transpose(2, 1, 0)  # [x, y, z]
    perm = [int(np.nonzero(m[i])[0][0]) for i in range(3)]
    signs = [int(m[i, perm[i]]) for i in range(3)]
    b = a.transpose(perm)
    for i, s in enumerate(signs):
        if s < 0:
            b = np.flip(b, axis=i)
    sp = np.asarray(mask.spacing)
    org = np.asarray(mask.origin)
    dims = np.asarray(a.shape)
    new = volrig.Volume(np.ascontiguousarray(b.transpose(2, 1, 0)), tuple(sp[perm]), (0.0, 0.0, 0.0))

    def to_rot(p):
        idx = (np.asarray(p) - org) / sp
        out = np.empty_like(idx)
        for i in range(3):
            v = idx[..., perm[i]]
            out[..., i] = v if signs[i] > 0 else dims[perm[i]] - 1 - v
        return out * sp[perm]
    return new, to_rot


def bone_ends(rig):
    """Bone name -> (head, tail) world positions."""
    return {n: (rig.joints[h], rig.joints[t]) for n, (h, t) in zip(rig.names, rig.bones)}


def rotation_check(subject, points, rig0, dt, verbose=False):
    """How many of the 24 rotations give the expected kind, and how many give the same bones (by name) whose
    ends map back within half a local radius of the unrotated rig's."""
    same_kind = same_joints = 0
    ends0 = bone_ends(rig0)
    for k, m in enumerate(rotations24()):
        rmask, to_rot = rotate_mask(subject.mask, m)
        _, _, rig, _ = rig_pipeline(rmask, points, up=m @ subject.up)
        same_kind += rig.kind == subject.kind
        ends = bone_ends(rig)
        worst = np.inf
        if sorted(ends) == sorted(ends0):
            worst = 0.0
            for name, (h0, t0) in ends0.items():
                for p0, p in zip((h0, t0), ends[name]):
                    r = S.local_radius(dt, subject.mask, p0)
                    worst = max(worst, float(np.linalg.norm(p - to_rot(p0))) / r)
        same_joints += worst <= 0.5
        if verbose:
            print(f"    rotation {k:2d} {m.astype(int).tolist()}: {rig.kind}, {len(rig)} bones, worst end "
                  f"{worst:.2f} radii")
    return same_kind, same_joints


def evaluate(subject, points, rotations=False, verbose=False):
    sk, pts, rig, t = rig_pipeline(subject.mask, points, up=subject.up)
    dt = sk.dt
    row = dict(subject=subject.name, voxels=int(sk.object_count), points=len(pts), expected=subject.kind,
               kind=rig.kind, fit=getattr(rig, "fit", None), bones=len(rig), times=t,
               joints=joint_errors(subject, rig, dt), quadruped=quadruped_checks(subject, rig))
    if rotations:
        row["rotations"] = rotation_check(subject, points, rig, dt, verbose)
    return row


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
    qs = "-" if q is None else f"head {'ok' if q[0] else 'NO'}, tail {q[1]}"
    rot = row.get("rotations")
    rs = "-" if rot is None else f"{rot[0]}/24 kind {rot[1]}/24 joints"
    t = row["times"]
    ok = "ok" if row["kind"] == row["expected"] else "WRONG"
    print(f"{row['subject']:<11} {row['voxels']:>10,} {row['points']:>7,} {row['expected']:>9}/{row['kind']:<9} "
          f"{ok:<5} {fmt_fit(row['fit']):>6} {row['bones']:>3}  {t['tree']:5.2f} {t['autorig']:5.2f} "
          f"{t['bind']:5.2f}  {qs:<17} {rs:<22} {js}")


def detail(row):
    for name, (r, d, lr) in row["joints"].items():
        print(f"    {name:<12} {r:6.2f} radii  {d:10.4g} (local radius {lr:.4g})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--subjects", default=",".join(DEFAULT), help=f"comma list from {', '.join(S.SUBJECTS)}")
    ap.add_argument("--scales", default="0.5,1", help="phantom scales")
    ap.add_argument("--points", default="15000", help="comma list of skeleton point counts")
    ap.add_argument("--rotations", action="store_true", help="also rig the 24 axis-aligned rotations (slow)")
    ap.add_argument("--slow", action="store_true", help="add vhm1 and phantom scale 2")
    ap.add_argument("--voxels", type=int, default=S.MESH_VOXELS, help="mesh voxels along the longest side")
    ap.add_argument("--joints", action="store_true", help="print each reference joint's error")
    ap.add_argument("--json", help="write the rows to this JSON file")
    args = ap.parse_args()

    names = [s for s in args.subjects.split(",") if s]
    scales = [float(s) for s in args.scales.split(",") if s]
    if args.slow:
        names += [n for n in ("vhm1",) if n not in names]
        scales += [s for s in (2.0,) if s not in scales]
    counts = [int(p) for p in args.points.split(",") if p]
    print(f"autorig accepts up={autorig_accepts('up')} kind={autorig_accepts('kind')}")
    print(f"{'subject':<11} {'voxels':>10} {'points':>7} {'expected/got':>19} {'':<5} {'fit':>6} {'B':>3}  "
          f"{'tree':>5} {'rig':>5} {'bind':>5}  {'quadruped':<17} {'rotations':<22} reference joints (r = local radius)")
    rows = []
    for name in names:
        loads = [dict(scale=s) for s in scales] if name == "phantom" else \
            ([dict(voxels=args.voxels)] if name in S.MESHES else [{}])
        for kw in loads:
            try:
                subject = S.load_subject(name, **kw)
            except FileNotFoundError as e:
                print(f"{name:<11} skipped: {e}")
                continue
            for n in counts:
                row = evaluate(subject, n, args.rotations, args.joints)
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

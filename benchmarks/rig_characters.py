#!/usr/bin/env python3
"""The one-click rig over every shared character (issue 53), measured the way the learned riggers measure
themselves: per category, the share of body plans right and CD-J2J / J2B / B2B (x 100, the mesh's longest side = 1;
volrig_support.characters.rig_distances) against the reference skeletons, and seconds per character.

Cross-validated: each character is rigged with the plan weights fitted without it (benchmarks/fit_plan_weights.py,
leave-one-out), so the table says how the method does on characters it was not fitted to. Two passes: without
markers, and with five markers a user would click (chin, both wrists, groin, one knee) taken from the reference
skeleton of each humanoid that has one (reference_markers: the skeleton's joints found by their place in its tree
and along up, not by name: the references name their joints joint0, joint1...).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/rig_characters.py [--fitted] [--turned] [--phase FX FY FZ]
      [--no-markers] [--json out.json]
--fitted uses the weights compiled in (fitted on every subject, these included) instead of leave-one-out ones.
--turned rigs each character turned as Blender's OBJ import turns it (volrig_support.characters.turned): the same
shapes on another voxel lattice, what an add-on user rigs; the weights (fitted on the unturned ones) stay.
--phase moves the voxel lattice by those fractions of a voxel (pipeline.mesh_skeleton's lattice_phase).
"""
import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))
sys.path.insert(0, HERE)

import fit_plan_weights as FW  # noqa: E402
from volrig_support import characters as C  # noqa: E402

#: The learned riggers' published figures on the Articulation-XL test set (CD-J2J, J2B, B2B x 100).
PUBLISHED = {"MagicArticulate": (3.04, 2.29, 1.95), "Puppeteer": (3.05, None, None)}


def _tree(bones, n):
    children = [[] for _ in range(n)]
    parent = -np.ones(n, int)
    for a, b in bones:
        children[a].append(b)
        parent[b] = a
    return children, parent


def _path_to_root(parent, j):
    out = [j]
    while parent[out[-1]] >= 0:
        out.append(parent[out[-1]])
    return out


def reference_markers(joints, bones, up):
    """Five markers a user would click on a humanoid (chin, wrist.L, wrist.R, groin, knee.L), found in a reference
    skeleton by its shape: the feet are the two lowest leaves along up, the head the highest, the hands the two
    leaves farthest out across the body among the rest (a hand's fingers: the one farthest out). Knee: the joint
    of the left leg's chain nearest half-way from the legs' fork to the foot; wrist: where the hand's fingers
    branch (_wrist); chin: the head leaf's parent; groin: the legs' fork. Up is the given one when the skeleton
    stands along it (_standing), else the first axis it stands along: a user clicks the chin on the chin even
    when the file's up is wrong (the AXL cartoon 37e2c lies along +z, its index says +y). None when the skeleton
    has fewer than five leaves or stands along no axis."""
    J = np.asarray(joints, float)
    children, parent = _tree(bones, len(J))
    leaves = [j for j in range(len(J)) if not children[j]]
    if len(leaves) < 5:
        return None
    given = np.asarray(up, float) / np.linalg.norm(up)
    axes = [given] + [s * e for e in np.eye(3) for s in (1, -1) if abs(e @ given) < 0.5]
    body = next((b for b in (_standing(J, parent, leaves, a) for a in axes) if b is not None), None)
    if body is None:
        return None
    feet, head, hands, across, side, fork = body
    paths = {j: _path_to_root(parent, j) for j in feet + hands + [head]}
    leg = paths[feet[0]][:paths[feet[0]].index(fork) + 1][::-1]  # fork .. foot
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(J[leg], axis=0), axis=1))])
    knee = leg[int(np.argmin(np.abs(arc - 0.5 * arc[-1])))]
    wrists = [_wrist(J, children, paths[hand], paths[head]) for hand in hands]
    chin = parent[head] if parent[head] >= 0 else head
    names = ("wrist.L", "wrist.R") if across[hands[0]] @ side >= 0 else ("wrist.R", "wrist.L")
    return {"chin": J[chin], names[0]: J[wrists[0]], names[1]: J[wrists[1]], "groin": J[fork], "knee.L": J[knee]}


def _standing(J, parent, leaves, up):
    """The skeleton read standing along up, or None when it does not: the feet (two lowest leaves along up), the
    head (highest), the hands (farthest out across the body among the rest), the joints' offsets across up, the
    body's widest direction across it, and the legs' fork. It stands when both legs reach down a quarter of its
    height from their fork and the head is above the fork: read along a wrong axis a T-pose's "feet" are two fingers
    of one hand, forking in the palm."""
    h = J @ up
    by_height = sorted(leaves, key=lambda j: h[j])
    feet, head = by_height[:2], by_height[-1]
    paths = [_path_to_root(parent, f) for f in feet]
    fork = next(k for k in paths[0] if k in paths[1])
    if min(h[fork] - h[f] for f in feet) < 0.25 * (h.max() - h.min()) or h[head] <= h[fork]:
        return None
    centre = J.mean(0)
    across = J - centre - np.outer(J @ up - centre @ up, up)
    rest = [j for j in leaves if j not in feet and j != head]
    side = np.linalg.svd(across[rest] - across[rest].mean(0))[2][0]  # the body's widest direction across up
    hands = [max(rest, key=lambda j: across[j] @ side), min(rest, key=lambda j: across[j] @ side)]
    return feet, head, hands, across, side, fork


def _wrist(J, children, hand_path, head_path):
    """The wrist on a hand's path (tip first, to the root): the first joint where fingers branch, when it lies in
    the outer 35% of the arm (from the tip to where the path meets the head's), else the joint 20% of the way in."""
    meet = next(i for i, k in enumerate(hand_path) if k in head_path)
    arm = hand_path[:meet + 1]
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(J[arm], axis=0), axis=1))])
    for i, k in enumerate(arm[1:], 1):
        if len(children[k]) > 1:
            if arc[i] <= 0.35 * arc[-1]:
                return k
            break
    return arm[int(np.argmin(np.abs(arc - 0.2 * arc[-1])))]


def plan_right(plan, kind):
    return kind == C.plan_label(plan)


def rig_row(sub, weights, markers=None):
    t = time.perf_counter()
    try:
        rig = sub.rig(plan_weights=weights, markers=markers)
    except Exception as e:  # a failure is a row, not the end of the table
        return {"name": sub.name, "category": sub.category, "plan": sub.plan, "error": str(e)[:120]}
    row = {"name": sub.name, "category": sub.category, "plan": sub.plan, "kind": rig.kind,
           "right": plan_right(sub.plan, rig.kind), "seconds": time.perf_counter() - t}
    if sub.reference is not None:
        row["d"] = list(C.rig_distances(rig.joints, rig.bones, *sub.reference, sub.vertices()))
    return row


def table(rows, title):
    print(f"\n{title}")
    print(f"{'category':10s} {'n':>3s} {'plans':>7s} {'J2J':>6s} {'J2B':>6s} {'B2B':>6s} {'(n)':>4s} {'s':>5s}"
          "   (n): characters with a reference skeleton; s: seconds per character")
    cats = sorted({r["category"] for r in rows}) + ["all", "bodies"]
    for cat in cats:  # bodies: the humanoids and quadrupeds of every category
        rs = [r for r in rows if cat == "all" or r["category"] == cat
              or (cat == "bodies" and r.get("plan") in ("humanoid", "quadruped"))]
        ok = [r for r in rs if "error" not in r]
        d = np.array([r["d"] for r in ok if "d" in r]) if any("d" in r for r in ok) else np.full((0, 3), np.nan)
        m = d.mean(0) if len(d) else [np.nan] * 3
        s = np.mean([r["seconds"] for r in ok]) if ok else np.nan
        dist = " ".join(f"{x:6.2f}" if len(d) else "     -" for x in m)
        print(f"{cat:10s} {len(rs):3d} {sum(r.get('right', False) for r in rs):3d}/{len(rs):<3d} "
              f"{dist} {len(d):4d} {s:5.1f}")
    for r in rows:
        if "error" in r:
            print(f"  {r['name']}: {r['error']}")
    print("published (Articulation-XL test set): " + "; ".join(
        f"{k} J2J {v[0]:.2f}" + (f" J2B {v[1]:.2f} B2B {v[2]:.2f}" if v[1] else "") for k, v in PUBLISHED.items()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fitted", action="store_true", help="the compiled-in weights, not leave-one-out ones")
    ap.add_argument("--turned", action="store_true", help="each character turned as Blender's OBJ import turns it")
    ap.add_argument("--phase", type=float, nargs=3, help="the voxel lattice moved by these fractions of a voxel")
    ap.add_argument("--no-markers", action="store_true", help="skip the pass with markers")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args()
    subjects = C.characters()
    weights = {}
    if not a.fitted:
        problems = FW.load_problems(log=lambda *_: None)
        for sub in subjects:
            train = [p for p in problems if FW.base_name(p.name) != sub.name]
            weights[sub.name] = [float(x) for x in FW.fit(train)]
    how = "fitted on all" if a.fitted else "leave-one-out"
    if a.turned:
        subjects = [C.turned(s) for s in subjects]
        how += ", characters turned as Blender imports them"
    if a.phase:
        from dataclasses import replace
        subjects = [replace(s, phase=tuple(a.phase)) for s in subjects]
        how += f", the lattice moved by {tuple(a.phase)} voxel"
    rows = [rig_row(s, weights.get(s.name)) for s in subjects]
    table(rows, f"shared characters, no markers, plan weights {how}")
    out = {"plain": rows}
    if not a.no_markers:
        marked = []
        for s in subjects:
            if s.plan == "humanoid" and s.reference is not None:
                m = reference_markers(*s.reference, s.up)
                if m is not None:
                    marked.append(rig_row(s, weights.get(s.name), {k: tuple(v) for k, v in m.items()}))
        table(marked, f"humanoids with a reference skeleton, five markers from it, plan weights {how}")
        out["markers"] = marked
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)


if __name__ == "__main__":
    main()

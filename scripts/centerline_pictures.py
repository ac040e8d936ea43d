#!/usr/bin/python3
"""Pictures of centerlines (issue 20): the airway tree's centerlines (../shared/data/airway, when present) over the
mask's maximum intensity projections, front and side, coloured by generation with the branch points; and a helix
tube with its centerline, straightened. Writes docs/images/centerline_airway.png and centerline_helix.png.

    PYTHONPATH=python /usr/bin/python3 scripts/centerline_pictures.py [--out docs/images]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
sys.path.insert(0, os.path.join(ROOT, "tests", "support"))  # volrig_support: data_root

import volrig  # noqa: E402
from volrig.files import atomic_output  # noqa: E402
from volrig_support import data_root  # noqa: E402

AIRWAY = str(data_root() / "airway" / "Patient1_bronchialTree.nii.gz")


def save(fig, path):
    import matplotlib.pyplot as plt
    fig.tight_layout()
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)
    print("wrote", path)


def airway(out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    v = volrig.load(AIRWAY)
    mask = volrig.Volume(v.array != 0, v.spacing, v.origin)
    t0 = time.perf_counter()
    tree = volrig.centerline_tree(mask)
    elapsed = time.perf_counter() - t0
    sp, org = np.array(mask.spacing), np.array(mask.origin)
    fig, axes = plt.subplots(1, 2, figsize=(12, 7))
    cmap = plt.get_cmap("viridis", int(tree.generations.max()) + 1)
    for ax, (i, j, proj) in zip(axes, ((0, 2, 1), (1, 2, 2))):
        mip = mask.array.max(axis=proj)  # [z, x] (front) or [z, y] (side)
        extent = (org[i], org[i] + sp[i] * (mip.shape[1] - 1), org[j], org[j] + sp[j] * (mip.shape[0] - 1))
        ax.imshow(mip, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=3, aspect="equal")
        for b, g in zip(tree.branches, tree.generations):
            ax.plot(b.points[:, i], b.points[:, j], color=cmap(g), lw=1.6)
        bp = tree.branch_points
        ax.plot(bp[:, i], bp[:, j], "o", ms=3.5, color="red")
        ax.plot(tree.root[i], tree.root[j], "s", ms=6, color="black")
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(-0.5, tree.generations.max() + 0.5))
    fig.colorbar(sm, ax=axes, label="generation", shrink=0.7)
    fig.suptitle(f"Patient1 bronchial tree: {len(tree)} branches, generations 0-{tree.generations.max()}, "
                 f"{len(tree.branch_points)} branch points (red), root (black); centerline_tree in {elapsed:.2f} s",
                 fontsize=10)
    with atomic_output(os.path.join(out, "centerline_airway.png"), suffix=".png") as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)
    print("wrote", os.path.join(out, "centerline_airway.png"))


def helix(out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from bench_centerline import helix_tube
    mask, axis = helix_tube(turns=2.0, helix_radius=20.0, pitch=30.0, radius=5.0)
    line = volrig.centerline(mask)
    vol = volrig.Volume(mask.array.astype(np.float32), mask.spacing, mask.origin)
    straight, where = volrig.straighten(vol, line, 9.0)
    fig = plt.figure(figsize=(12, 4.5))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.plot(*axis[::200].T, color="green", lw=3, alpha=0.5, label="true axis")
    ax.plot(*line.points.T, color="red", lw=1, label="centerline")
    ax.legend(fontsize=8)
    ax.set_title(f"helix tube, radius 5: centerline {line.length:.1f} long", fontsize=9)
    ax2 = fig.add_subplot(1, 3, (2, 3))
    ax2.imshow(straight.array[:, where.half, :].T, origin="lower", cmap="Greys_r", aspect="auto",
               extent=(0, line.length, -where.half * where.step, where.half * where.step))
    ax2.set_xlabel("arc length")
    ax2.set_ylabel("across the tube (normal)")
    ax2.set_title("volrig.straighten(tube, centerline, 9): the tube straightened (a slice through the axis)",
                  fontsize=9)
    save(fig, os.path.join(out, "centerline_helix.png"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    args = ap.parse_args(argv)
    if os.path.exists(AIRWAY):
        airway(args.out)
    else:
        print(f"airway picture skipped: {AIRWAY} is absent")
    helix(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

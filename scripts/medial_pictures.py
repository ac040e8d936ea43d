#!/usr/bin/python3
"""Picture of the medial surface (issue 22): the Visible Human Male's skull at 1 mm (bone labels 84, 92, the top
230 mm), volrig.medial_surface at t = 5 voxels, its triangles coloured by plate thickness and shaded by their
facing, seen from the left and from the top; rods drawn as thin black lines. Needs ../shared/data.
Writes docs/images/medial_surface.png.

    PYTHONPATH=python /usr/bin/python3 scripts/medial_pictures.py [--out docs/images] [--t 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "scripts"))

import volrig  # noqa: E402
from thickness_pictures import skull_1mm  # noqa: E402


def draw(ax, ms, view: int, flip: bool, top: float, title: str) -> None:
    """Orthographic view along world axis ``view`` (from its far end when ``flip``): faces painted far to near,
    coloured by the mean thickness of their vertices, darkened where seen edge-on."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection
    h, v = [a for a in range(3) if a != view]
    p = ms.vertices[ms.faces]                                  # (F, 3, 3)
    depth = p[:, :, view].mean(axis=1) * (-1 if flip else 1)   # larger: nearer the viewer
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    facing = np.abs(n[:, view]) / np.maximum(np.linalg.norm(n, axis=1), 1e-12)
    colour = plt.get_cmap("turbo")(np.clip(ms.thickness[ms.faces].mean(axis=1) / top, 0, 1))[:, :3]
    colour *= (0.35 + 0.65 * facing)[:, None]
    order = np.argsort(depth)
    xy = p[order][:, :, [h, v]]
    if flip:
        xy[:, :, 0] *= -1
    ax.add_collection(PolyCollection(xy, facecolors=colour[order], edgecolors="none", antialiased=False))
    segs = []
    for line in ms.rods:
        q = line[:, [h, v]].copy()
        if flip:
            q[:, 0] *= -1
        segs.append(q)
    ax.add_collection(LineCollection(segs, colors="k", linewidths=0.3, alpha=0.6))
    ax.autoscale()
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])


def main() -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    ap.add_argument("--t", type=float, default=5.0)
    args = ap.parse_args()
    skull = skull_1mm()
    t0 = time.perf_counter()
    ms = volrig.medial_surface(skull, t=args.t)
    took = time.perf_counter() - t0
    q = np.percentile(ms.thickness, [5, 50, 95])
    print(f"{skull.array.shape} voxels, {int(skull.array.sum()):,} bone: {len(ms.faces):,} triangles, "
          f"{len(ms.rods):,} rods, {took:.1f} s; thickness 5/50/95% {q[0]:.1f}/{q[1]:.1f}/{q[2]:.1f} mm")
    top = 10.0
    fig = plt.figure(figsize=(13, 6.2))
    left = fig.add_axes([0.02, 0.04, 0.5, 0.84])
    above = fig.add_axes([0.54, 0.04, 0.36, 0.84])
    cax = fig.add_axes([0.92, 0.2, 0.015, 0.55])
    draw(left, ms, 0, True, top, "from the left (y: front to back, z: up)")
    draw(above, ms, 2, False, top, "from above (x, y)")
    sm = plt.cm.ScalarMappable(cmap="turbo", norm=plt.Normalize(0, top))
    fig.colorbar(sm, cax=cax, label="plate thickness (mm)")
    fig.suptitle(f"Medial surface of the Visible Human's skull (1 mm, t = {args.t:g} voxels): {len(ms.faces):,} "
                 f"triangles, {len(ms.rods):,} rods (black), {took:.0f} s on 2 cores; "
                 f"thickness 5/50/95%: {q[0]:.1f}/{q[1]:.1f}/{q[2]:.1f} mm", fontsize=10)
    path = os.path.join(args.out, "medial_surface.png")
    from volrig.files import atomic_output
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110)
    print("wrote", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

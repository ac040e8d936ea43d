#!/usr/bin/python3
"""Picture of the medial surface (issue 22): the Visible Human Male's skull at 1 mm (bone labels 84, 92, the top
230 mm) seen from the left and from the top, and the lidc2 chest CT's bone (>= 200 of 255, 1.4 x 1.4 x 2.5 mm) seen
from the front: volrig.medial_surface at t = 5 voxels, its triangles coloured by plate thickness and shaded by their
facing; rods drawn as thin black lines. Needs ../shared/data.
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
from thickness_pictures import DATA, skull_1mm  # noqa: E402


def draw(ax, ms, view: int, flip: bool, top: float, title: str, upside_down: bool = False) -> None:
    """Orthographic view along world axis ``view`` (from its far end when ``flip``): faces painted far to near,
    coloured by the mean thickness of their vertices, darkened where seen edge-on (``upside_down``: the vertical
    axis points down, for a scan whose z runs feet-wards)."""
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
    if upside_down:
        xy[:, :, 1] *= -1
    ax.add_collection(PolyCollection(xy, facecolors=colour[order], edgecolors="none", antialiased=False))
    segs = []
    for line in ms.rods:
        q = line[:, [h, v]].copy()
        if flip:
            q[:, 0] *= -1
        if upside_down:
            q[:, 1] *= -1
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
    ct = volrig.load(os.path.join(DATA, "lidc2", "LIDC2.mha"))
    chest = volrig.Volume(ct.array >= 200, ct.spacing, ct.origin)
    t0 = time.perf_counter()
    cs = volrig.medial_surface(chest, t=args.t)
    chest_took = time.perf_counter() - t0
    top = 10.0
    fig = plt.figure(figsize=(13, 12.6))
    left = fig.add_axes([0.02, 0.5, 0.5, 0.43])
    above = fig.add_axes([0.54, 0.5, 0.36, 0.43])
    front = fig.add_axes([0.12, 0.02, 0.66, 0.43])
    cax = fig.add_axes([0.92, 0.3, 0.015, 0.4])
    draw(left, ms, 0, True, top, f"skull from the left: {len(ms.faces):,} triangles, {len(ms.rods):,} rods, {took:.0f} s; "
                                 f"thickness 5/50/95% {q[0]:.1f}/{q[1]:.1f}/{q[2]:.1f} mm")
    draw(above, ms, 2, False, top, "skull from above")
    cq = np.percentile(cs.thickness, [5, 50, 95])
    draw(front, cs, 1, False, top, f"lidc2 chest CT bone (>= 200) from the front: {len(cs.faces):,} triangles "
                                   f"(scapulae, sternum, spine), {len(cs.rods):,} rods (the ribs), {chest_took:.1f} s; "
                                   f"thickness 5/50/95% {cq[0]:.1f}/{cq[1]:.1f}/{cq[2]:.1f} mm", upside_down=True)
    sm = plt.cm.ScalarMappable(cmap="turbo", norm=plt.Normalize(0, top))
    fig.colorbar(sm, cax=cax, label="plate thickness (mm)")
    fig.suptitle(f"volrig.medial_surface (t = {args.t:g} voxels) on 2 cores: triangles coloured by plate thickness, "
                 f"rods black", fontsize=10)
    path = os.path.join(args.out, "medial_surface.png")
    from volrig.files import atomic_output
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110)
    print("wrote", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

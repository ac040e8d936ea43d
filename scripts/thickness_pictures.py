#!/usr/bin/python3
"""Pictures of local thickness (issue 22): the Visible Human Male's bone (labels 84, 92) at 2 mm seen from the front,
its skull at 1 mm seen from the left, and the skull's plane-like skeleton (volrig.plane_like, t = 5), each coloured
by local thickness (the colour of the first voxel along each line of sight, shaded by its depth). Needs ../shared/data. Writes docs/images/thickness.png.

    PYTHONPATH=python /usr/bin/python3 scripts/thickness_pictures.py [--out docs/images]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "tests", "support"))  # volrig_support: data_root

import volrig  # noqa: E402
from volrig_support import data_root  # noqa: E402

DATA = str(data_root())


def first_hit(a: np.ndarray, axis: int, flip: bool):
    """Thickness of the first object voxel seen along ``axis`` of a [z, y, x] array (from its far end when
    ``flip``), and its depth shading in [0.55, 1]."""
    if flip:
        a = np.flip(a, axis=axis)
    hit = a > 0
    any_hit = hit.any(axis=axis)
    first = np.argmax(hit, axis=axis)
    value = np.where(any_hit, np.take_along_axis(a, np.expand_dims(first, axis), axis).squeeze(axis), np.nan)
    shade = np.where(any_hit, 1.0 - 0.45 * first / max(a.shape[axis] - 1, 1), 1.0)
    return value, shade


def panel(ax, thick, title, top, axis, flip):
    """Rows of the picture are z; columns x (seen along y, axis 1) or y (seen along x, axis 2)."""
    import matplotlib.pyplot as plt
    value, shade = first_hit(thick.array, axis, flip)
    rgb = plt.get_cmap("turbo")(np.clip(np.nan_to_num(value) / top, 0, 1))[..., :3] * shade[..., None]
    rgb[np.isnan(value)] = 1.0
    s, o, n = thick.spacing, thick.origin, thick.array.shape
    h = 0 if axis == 1 else 1  # world axis across the picture
    ax.imshow(rgb, origin="lower", extent=(o[h], o[h] + s[h] * n[2 - h], o[2], o[2] + s[2] * n[0]),
              interpolation="nearest")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x (mm)" if h == 0 else "y (mm, front to back)")
    ax.set_ylabel("z (mm)")


def skull_1mm():
    """The bone of the Visible Human's head at 1 mm (the top 230 mm), as a bool Volume."""
    v = volrig.load(os.path.join(DATA, "visible-human", "austinman_1mm_labels.nii.gz"))
    top = v.array.shape[0]
    z0 = top - int(230 / v.spacing[2])
    head = v.array[z0:]
    o = (v.origin[0], v.origin[1], v.origin[2] + z0 * v.spacing[2])
    return volrig.Volume(np.isin(head, (84, 92)), v.spacing, o)


def main() -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    args = ap.parse_args()
    vhm = volrig.load(os.path.join(DATA, "visible-human", "austinman_2mm_labels.nii.gz"))
    cases = [(volrig.Volume(np.isin(vhm.array, (84, 92)), vhm.spacing, vhm.origin),
              "Visible Human Male, bone, 2 mm, front", 1, False),
             (skull_1mm(), "its skull at 1 mm, from the left", 2, True)]
    top = 40.0
    fig = plt.figure(figsize=(12, 11.5))
    axes = [fig.add_axes([0.05, 0.05, 0.33, 0.88]), fig.add_axes([0.45, 0.53, 0.42, 0.40]),
            fig.add_axes([0.45, 0.05, 0.42, 0.40])]
    cax = fig.add_axes([0.91, 0.3, 0.015, 0.4])
    skull = cases[1][0]
    t0 = time.perf_counter()
    plates = volrig.plane_like(skull, t=5.0)
    pt = time.perf_counter() - t0
    cases.append((volrig.Volume(plates.array, skull.spacing, skull.origin),
                  f"its plane-like skeleton (t = 5 voxels, {pt:.1f} s): the medial surface of the plates", 2, True))
    for ax, (mask, title, axis, flip) in zip(axes, cases):
        t0 = time.perf_counter()
        thick = volrig.local_thickness(skull if mask.array is plates.array else mask)
        if mask.array is plates.array:  # the skull's thickness on its plane-like voxels
            thick = volrig.Volume(np.where(plates.array, thick.array, 0.0).astype(np.float32), skull.spacing,
                                  skull.origin)
        dt = time.perf_counter() - t0
        vals = thick.array[mask.array]
        q = np.percentile(vals, [5, 50, 95])
        panel(ax, thick, f"{title}\n{mask.array.sum():,} voxels, thickness 5/50/95%: {q[0]:.0f}/{q[1]:.0f}/{q[2]:.0f} mm"
                         f" ({dt:.1f} s)", top, axis, flip)
    sm = plt.cm.ScalarMappable(cmap="turbo", norm=plt.Normalize(0, top))
    fig.colorbar(sm, cax=cax, label="local thickness (mm)")
    fig.suptitle("Local thickness: each voxel's largest inscribed ball (first bone voxel along the view, shaded by depth)",
                 fontsize=10)
    path = os.path.join(args.out, "thickness.png")
    from volrig.files import atomic_output
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=90)
    print("wrote", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

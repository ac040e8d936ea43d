#!/usr/bin/python3
"""Pictures of feature tracking (issue 57): the shared viscous-fingering run below its source layer (z < 52, salt
>= 30), tracked at thinness 1 (volrig.track). Top: four steps seen from the side, each finger coloured by its track
id (stable colours per track), its skeleton's points drawn over it. Bottom: the tracking graph, one node per
feature (x: step, y: centroid x, size: volume, colour: track), edges for matches, splits and merges marked.
Needs ../shared/data. Writes docs/images/track_fingers.png.
With --blender, run inside Blender: the same run imported with the add-on's Import Tracked Series (salt >= 30,
the whole box) and four frames rendered in Cycles (EEVEE where Cycles renders no grids): docs/images/track_blender.png.

    PYTHONPATH=python /usr/bin/python3 scripts/track_pictures.py [--out docs/images]
    blender -b --factory-startup --python scripts/track_pictures.py -- --blender [--out docs/images]
"""
from __future__ import annotations

import argparse
import glob
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "tests", "support"))

import volrig  # noqa: E402
from volrig_support import data_root  # noqa: E402

RUN = os.path.join(str(data_root()), "timevarying", "viscous_fingers_run01")


def colours(n):
    """A stable colour per track id (1..n): the tab20 cycle."""
    import matplotlib
    cmap = matplotlib.colormaps["tab20"]
    return np.array([(0.08, 0.08, 0.1, 1.0)] + [cmap(i % 20) for i in range(n)])


def side_view(ax, tr, step, palette):
    vol = tr.track_volume(step)
    hit = vol > 0
    depth = np.where(hit.any(axis=1), hit.argmax(axis=1), 0)  # first feature voxel along y, per (z, x)
    ids = np.take_along_axis(vol, depth[:, None, :], axis=1)[:, 0, :]
    img = palette[ids][:, :, :3] * np.where(ids > 0, 1.0 - 0.5 * depth / vol.shape[1], 1.0)[..., None]
    ax.imshow(img, origin="lower", interpolation="nearest")
    for f in range(1, len(tr.volumes[step]) + 1):
        ijk, _ = tr.skeleton_points(step, f)
        ax.plot(ijk[:, 2], ijk[:, 0], ",", color="white", alpha=0.6)
    ax.set_title(f"step {step}: {len(tr.volumes[step])} features", fontsize=9)
    ax.set_xticks([]), ax.set_yticks([])


def graph(ax, tr, palette):
    for s, a, b, _ in tr.edges:
        ya, yb = tr.centroids[s][a - 1][0], tr.centroids[s + 1][b - 1][0]
        ax.plot([s, s + 1], [ya, yb], "-", color=palette[tr.track_ids[s][a - 1]], lw=1.2, alpha=0.8)
    for s in range(tr.steps):
        ax.scatter(np.full(len(tr.volumes[s]), s), tr.centroids[s][:, 0], s=6 + tr.volumes[s] / 40,
                   c=palette[tr.track_ids[s]], edgecolors="k", linewidths=0.4, zorder=3)
    for e in tr.events:
        if e.kind in ("split", "merge", "split-merge"):
            y = tr.centroids[e.step][e.before[0] - 1][0]
            ax.annotate(e.kind, (e.step + 0.5, y), fontsize=6, ha="center", va="bottom", color="0.3")
    ax.set_xlabel("time step"), ax.set_ylabel("centroid x (voxels)")
    counts = ", ".join(f"{n} {k}" for k, n in tr.event_counts().items() if n)
    ax.set_title(f"tracking graph at thinness {tr.thinness:g}: {counts}", fontsize=9)


def blender_sheet(out: str) -> None:
    """Import Tracked Series on the run in an empty scene (saved in a temporary folder), four frames in Cycles."""
    import tempfile
    sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "scripts")]
    import bpy
    import mathutils
    import volrig_addon
    from volrig_addon import engines
    from blender_scenes import engine_name, new_scene, render_frames, sheet
    volrig_addon.register()
    work = tempfile.mkdtemp(prefix="volrig_tracks_")
    scene = new_scene(os.path.join(work, "tracks.blend"))
    first = sorted(glob.glob(os.path.join(RUN, "*.vti")))[0]
    if bpy.ops.volrig.import_tracks(filepath=first, lo=30, thinness=1.0, size=2.0) != {"FINISHED"}:
        raise RuntimeError("Import Tracked Series failed")
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (1.0, -2.6, 0.4)
    cam.rotation_euler = (mathutils.Vector((1.0, 1.0, 1.2)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    scene.collection.objects.link(sun)
    sun.rotation_euler, sun.data.energy = (0.6, 0.2, 0.3), 6.0
    scene.world = bpy.data.worlds.new("world")
    scene.world.color = (0.35, 0.35, 0.38)
    engines.use(scene, samples=32)  # Cycles, or EEVEE where this Blender's Cycles renders no grids
    scene.render.resolution_x, scene.render.resolution_y = 480, 400
    frames = [1, 10, 19, 28]
    paths = render_frames(scene, frames, work)
    sheet(paths, [f"frame {f}" for f in frames], os.path.join(out, "track_blender.png"),
          f"viscous fingers (salt >= 30) by Import Tracked Series: a colour per track ({engine_name(scene)})")
    print(f"-> {os.path.join(out, 'track_blender.png')}")


def main():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    ap.add_argument("--blender", action="store_true", help="inside Blender: the add-on's import, rendered")
    args = ap.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
    if not os.path.isdir(RUN):
        print(f"skipped: {RUN} is absent")
        return 0
    if args.blender:
        blender_sheet(args.out)
        return 0
    steps = [volrig.load(f).array[:52] for f in sorted(glob.glob(os.path.join(RUN, "*.vti")))]
    tr = volrig.track(steps, lo=30, thinness=1.0)
    palette = colours(int(max(t.max() for t in tr.track_ids)))
    fig = plt.figure(figsize=(10, 7.2), dpi=110)
    for k, step in enumerate((0, 8, 18, 28)):
        side_view(fig.add_subplot(2, 4, k + 1), tr, step, palette)
    graph(fig.add_subplot(2, 1, 2), tr, palette)
    fig.tight_layout()
    out = os.path.join(args.out, "track_fingers.png")
    fig.savefig(out)
    print(f"-> {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

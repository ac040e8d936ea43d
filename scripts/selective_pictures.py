"""The README's selective-rendering picture: the humanoid phantom rigged by the add-on and rendered in Cycles with
per-part looks (the Parts list) and an exploded view (the Explode factor, baked).

    blender -b --factory-startup --python scripts/selective_pictures.py [-- --scale 0.5 --samples 16]

Writes docs/images/selective_phantom.png, a contact sheet of four renders: the left arm red and the rest
translucent, the left arm hidden, the skeleton's parts taken apart (Explode 0.5, baked), and the same with every part in
its own colour. The .blend and its cache go to a temporary folder.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "scripts")]

import bpy  # noqa: E402

import volrig  # noqa: E402
import volrig_addon  # noqa: E402
from blender_scenes import contact_sheet, log, new_scene, quiet_stdout, rigged_volume, run_and_exit  # noqa: E402

volrig_addon.register()
from volrig_addon import looks, staging  # noqa: E402

OUT = os.path.join(REPO, "docs", "images", "selective_phantom.png")


def set_looks(vol, colored=(), hidden=(), opacity=1.0, own_colours=False):
    """Every part's look: ``colored`` parts red and denser (or each its own colour), ``hidden`` parts hidden, the
    others at ``opacity``."""
    vol.volrig.use_parts = True
    for k, p in enumerate(vol.volrig.parts):
        p.visible = p.name not in hidden
        p.colored = own_colours or p.name in colored
        p.color = looks.PART_COLORS[k % len(looks.PART_COLORS)] if own_colours else (1.0, 0.05, 0.02)
        p.opacity = 2.0 if (own_colours or p.name in colored) else opacity


def render(scene, path):
    started = time.perf_counter()
    scene.render.filepath = path
    with quiet_stdout():
        bpy.ops.render.render(write_still=True)
    log(f"rendered {os.path.basename(path)} in {time.perf_counter() - started:.1f} s")
    return path


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args(argv)
    work = tempfile.mkdtemp(prefix="volrig_selective_")
    try:
        source = os.path.join(work, "phantom.nrrd")
        volrig.phantom.humanoid(scale=args.scale).volume.save(source)
        new_scene(os.path.join(work, "selective.blend"))
        vol = rigged_volume(source, "phantom", thinness=0.3, low=1.0)
        s = vol.volrig
        s.preset, s.density_scale = "GREY", 0.15 / args.scale  # per mm (the Volume renders in object space)
        scene = bpy.context.scene
        scene.frame_start = scene.frame_end = 1
        staging.stage(scene, vol, resolution=(200, 300), samples=args.samples, margin=1.8)
        scene.view_settings.view_transform = "Standard"  # (Filmic turns saturated colours towards white)
        shots = []
        set_looks(vol, colored={"left arm"}, opacity=0.08)
        shots.append((render(scene, os.path.join(work, "red_arm.png")), "left arm red, the rest translucent"))
        set_looks(vol, hidden={"left arm"})
        shots.append((render(scene, os.path.join(work, "hidden_arm.png")), "left arm hidden"))
        s.explode = 0.5
        if bpy.ops.volrig.bake() != {"FINISHED"}:
            raise RuntimeError("bake did not finish")
        set_looks(vol)
        shots.append((render(scene, os.path.join(work, "exploded.png")), "exploded (Explode 0.5)"))
        set_looks(vol, own_colours=True)
        shots.append((render(scene, os.path.join(work, "exploded_parts.png")), "a colour per part"))
        contact_sheet([p for p, _ in shots], [t for _, t in shots], args.out,
                      f"volrig: per-part looks and an exploded view of the phantom in Cycles "
                      f"({len(s.parts)} parts from the rig's bone names)")
        log(f"wrote {args.out}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


run_and_exit(main)

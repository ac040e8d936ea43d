"""docs/parts.md's selective-rendering picture: the humanoid phantom rigged by the add-on and rendered in Cycles with
per-part looks (the Parts list) and an exploded view (the Explode factor, baked).

    blender -b --factory-startup --python scripts/selective_pictures.py [-- --scale 0.5 --samples 16]

Writes docs/images/selective_phantom.png, a contact sheet of four renders: the left arm red and the rest
translucent, the left arm hidden, the skeleton's parts taken apart (Explode 0.5, baked), and the same with every part in
its own colour; and, when ../shared/data/frogtissue is present, two more of the frog's label map rigged by the add-on,
taken apart (Explode 0.3, baked) and seen from above with per-tissue looks: its skeleton alone, and the skeleton with
the soft tissues as translucent context. The .blend and its cache go to a temporary folder.

The frog's tissue codes follow VTK's frog examples (1 blood, 2 brain, 3 duodenum, 4 eye retina, 5 eye white, 6 heart,
7 ileum, 8 kidney, 9 large intestine, 10 liver, 11 lung, 12 nerve, 13 skeleton, 14 spleen, 15 stomach; the file's few
voxels of higher codes are "other"); code 13 is the one spanning the whole body.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "scripts"),
                os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402

import volrig  # noqa: E402
import volrig_addon  # noqa: E402
from blender_scenes import contact_sheet, log, new_scene, quiet_stdout, rigged_volume, run_and_exit  # noqa: E402

volrig_addon.register()
from volrig_addon import looks, objects, staging  # noqa: E402
from volrig_support import data_root  # noqa: E402

OUT = os.path.join(REPO, "docs", "images", "selective_phantom.png")
FROG = str(data_root() / "frogtissue" / "frogtissue.mhd")
FROG_TISSUES = ["blood", "brain", "duodenum", "eye retina", "eye white", "heart", "ileum", "kidney",
                "large intestine", "liver", "lung", "nerve", "skeleton", "spleen", "stomach"]


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


def frog_shots(work, samples):
    """The frog rigged, taken apart (Explode 0.3, baked) and rendered from above with per-tissue looks: the skeleton
    alone, then with the other tissues as translucent context."""
    from mathutils import Matrix
    new_scene(os.path.join(work, "frog.blend"))
    vol = rigged_volume(FROG, "frog", points=12000, largest=True, rig_kept_points=True)
    table = os.path.join(work, "frog_tissues.tsv")
    with open(table, "w") as f:
        f.write("code\tname\n" + "".join(f"{k}\t{n}\n" for k, n in enumerate(FROG_TISSUES, start=1)))
    s = vol.volrig
    s.tissue_table, s.use_tissues, s.density_scale = table, True, 2.0
    s.explode = 0.3
    scene = bpy.context.scene
    scene.frame_start = scene.frame_end = 1
    if bpy.ops.volrig.bake() != {"FINISHED"}:
        raise RuntimeError("bake did not finish")
    cam = staging.stage(scene, vol, resolution=(300, 300), samples=samples)
    lo, hi = staging.volume_box(vol)
    size = hi - lo
    cam.data.ortho_scale = 1.3 * float(max(size[0], size[1]))  # taken apart, the frog spreads out
    cam.data.clip_start, cam.data.clip_end = 0.001, 10.0
    cam.matrix_world = Matrix.Translation(((lo + hi) / 2 + [0.0, 0.0, 2.0 * float(size.max())]).tolist())
    scene.view_settings.view_transform = "Standard"
    shots = []
    for t in s.tissues:
        t.visible = t.name == "bone"
    shots.append((render(scene, os.path.join(work, "frog_bones.png")), "frog: skeleton, apart (0.3)"))
    for t in s.tissues:
        t.visible, t.opacity = True, 1.0 if t.name == "bone" else 0.05
    shots.append((render(scene, os.path.join(work, "frog_context.png")), "with soft tissue as context"))
    log(f"frog: {len(objects.members(vol)['RIG'].data.bones)} bones, {len(s.parts)} parts, tissues "
        + ", ".join(t.name for t in s.tissues))
    return shots


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
        parts = len(s.parts)
        if os.path.exists(FROG):
            shots += frog_shots(work, args.samples)
        else:
            log(f"skipped the frog: {FROG} is absent")
        contact_sheet([p for p, _ in shots], [t for _, t in shots], args.out,
                      f"volrig: per-part looks and exploded views in Cycles (the phantom's {parts} parts from its "
                      f"bone names; the frog's label map with per-tissue looks)")
        log(f"wrote {args.out}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


run_and_exit(main)

"""docs/images/drawing.png: a drawing becomes a character. A procedural front-view drawing
(``volrig_support.sketches.character``) imported with the add-on's Import Drawing (inflated, coloured by its palette,
rigged as a humanoid), posed with keyframes (arms raised and bent, a knee lifted, the head turned), baked and
rendered with Cycles at rest and posed from a three-quarter view, beside the drawing.

    blender -b --factory-startup --python scripts/drawing_pictures.py -- [-o docs/images] [--work out/drawing]
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), HERE, os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402
from mathutils import Quaternion, Vector  # noqa: E402

import volrig_addon  # noqa: E402
from volrig import drawing  # noqa: E402
from volrig_support import sketches  # noqa: E402
from volrig_addon import objects, staging  # noqa: E402
from blender_scenes import log, new_scene, ok, render_frames, sheet  # noqa: E402

#: the pose at frame 2: bone -> (world axis, radians): the left arm raised sideways and bent up, the right arm
#: reaching forward, the right knee lifted, the head turned (the figure faces -Y; its left is +X)
POSE = {"upper_arm.L": ((0, 1, 0), -1.3), "forearm.L": ((0, 1, 0), -0.9), "upper_arm.R": ((1, 0, 0), -0.9),
        "forearm.R": ((1, 0, 0), -0.8), "thigh.R": ((1, 0, 0), -1.0), "shin.R": ((1, 0, 0), 1.4),
        "head": ((0, 0, 1), 0.5)}


def pose(rig_obj):
    """Keys the rest pose at frame 1 and POSE at frame 2 (each rotation about a world axis, turned into the
    bone's rest frame; children are posed relative to their posed parent, so their axes are taken at rest)."""
    for frame, amount in ((1, 0.0), (2, 1.0)):
        for name, (axis, angle) in POSE.items():
            pb = rig_obj.pose.bones.get(name)
            if pb is None:
                continue
            rest = (rig_obj.matrix_world @ pb.bone.matrix_local).to_3x3().normalized()
            local = rest.inverted() @ Vector(axis)
            pb.rotation_mode = "QUATERNION"
            pb.rotation_quaternion = Quaternion(local.normalized(), amount * angle)
            pb.keyframe_insert("rotation_quaternion", frame=frame)


def main(argv):
    p = argparse.ArgumentParser(prog="drawing_pictures.py")
    p.add_argument("-o", "--out", default=os.path.join(REPO, "docs", "images"))
    p.add_argument("--work", default=os.path.join(REPO, "out", "drawing"))
    a = p.parse_args(argv)
    work = os.path.abspath(a.work)
    os.makedirs(work, exist_ok=True)
    volrig_addon.register()
    scene = new_scene(os.path.join(work, "drawing.blend"))
    png = os.path.join(work, "character.png")
    drawing.write_png(png, sketches.character())
    ok(bpy.ops.volrig.import_drawing(filepath=png, resolution=240, height=1.8), "import drawing")
    vol = bpy.context.active_object
    rig_obj = objects.members(vol)["RIG"]
    log(f"{vol.name}: {vol.volrig.rig_found}; bones {', '.join(b.name for b in rig_obj.data.bones)}")
    pose(rig_obj)
    scene.frame_start, scene.frame_end = 1, 2
    vol.volrig.bake_frames = "1,2"
    vol.volrig.density_scale = 150.0  # opaque: a solid figure, not a haze
    ok(bpy.ops.volrig.bake(), "bake")
    staging.stage(scene, vol, resolution=(360, 480), samples=32, azimuth=-35.0, margin=1.15)
    scene.objects["volrig sun"].rotation_euler = (0.6, 0.2, -0.9)
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.37, 0.4, 1.0)
    renders = render_frames(scene, [1, 2], work)
    out = os.path.join(os.path.abspath(a.out), "drawing.png")
    sheet([png] + renders, ["the drawing (PNG)", "inflated and rigged (Cycles)", "posed and baked (Cycles)"], out,
                  f"volrig: a drawing becomes a character (rigged as a {vol.volrig.rig_found.split(',')[0]})")
    log(f"wrote {out}")


main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])

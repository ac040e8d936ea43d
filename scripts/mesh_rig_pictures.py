"""docs/images/rig_mesh.png: a mesh rigged by the add-on's Rig Mesh and posed by Blender's own Armature modifier.
The shared knight (../shared/data/meshes/decimated-knight.off, +Y up: turned to +Z) rigged by Rig Mesh, coloured by
its skin weights (each bone a colour, each vertex the weighted mix), rendered with Cycles (no denoising) from a
three-quarter view (front right): at rest, posed (left elbow 90 degrees, left knee 60 degrees, head turned) and posed with the
left forearm and the right thigh made thicker through their volrig_thickness (the thickness shape keys).

    blender -b --factory-startup --python scripts/mesh_rig_pictures.py -- [-o docs/images] [--work out/rig_mesh]
"""
import argparse
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), HERE, os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402

import volrig  # noqa: E402
import volrig_addon  # noqa: E402
from volrig_addon import mesh_rig  # noqa: E402
from volrig_support import data_root  # noqa: E402
from blender_scenes import log, ok, quiet_stdout, sheet  # noqa: E402

KNIGHT = str(data_root() / "meshes" / "decimated-knight.off")
#: bone -> (rotation about the bone's own x axis, degrees): the knight faces -Y, so -x bends an elbow forwards
POSE = {"forearm.L": -90.0, "shin.L": 60.0, "upper_arm.R": -30.0}
THICKER = {"forearm.L": 1.8, "thigh.R": 1.6}


def knight():
    v, f = volrig.read_mesh(KNIGHT)
    v = np.asarray(v, float)
    return mesh_rig.new_mesh_object(bpy.context, "knight", np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1), f,
                                    smooth=True)


def weight_colours(obj, arm):
    """A point colour attribute ``volrig weights``: each bone a colour (golden-ratio hues), each vertex the mix of
    its bones' colours by its vertex-group weights; and a material showing it."""
    import colorsys
    names = [b.name for b in arm.data.bones]
    w = mesh_rig.read_weights(obj, names).toarray()
    hues = (np.arange(len(names)) * 0.618034) % 1.0
    palette = np.array([colorsys.hsv_to_rgb(h, 0.9, 0.85) for h in hues]) ** 2.2  # (sRGB to linear)
    rgb = w @ palette
    attr = obj.data.attributes.new("volrig weights", "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", np.concatenate([rgb, np.ones((len(rgb), 1))], axis=1).astype(np.float32).ravel())
    mat = bpy.data.materials.new("weights")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    colour = nodes.new("ShaderNodeAttribute")
    colour.attribute_name = "volrig weights"
    bsdf = nodes["Principled BSDF"]
    mat.node_tree.links.new(colour.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.6
    obj.data.materials.append(mat)


def stage(scene, obj):
    """Camera (perspective, three-quarter from the front left, a little above), sun, grey world, Cycles."""
    corners = np.array([obj.matrix_world @ Vector(c) for c in obj.bound_box])
    lo, hi = corners.min(0), corners.max(0)
    centre = Vector((lo + hi) / 2)
    size = float((hi - lo).max())
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(cam)
    cam.data.lens = 60
    a = math.radians(35.0)  # from the front right: the knight's left arm (+X) nearest
    cam.location = centre + 2.2 * size * Vector((math.sin(a), -math.cos(a), 0.2))
    cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 4.0
    sun.rotation_euler = (0.7, 0.2, -0.6)
    scene.collection.objects.link(sun)
    if scene.world is None:
        scene.world = bpy.data.worlds.new("world")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.37, 0.4, 1.0)
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 48
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = 360, 480
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"  # the weight colours as they are (Filmic pales them)


def render(scene, path):
    scene.render.filepath = path
    with quiet_stdout():
        bpy.ops.render.render(write_still=True)
    return path


def set_pose(arm, amount):
    for name, degrees in POSE.items():
        pb = arm.pose.bones[name]
        pb.rotation_mode = "XYZ"
        pb.rotation_euler = (math.radians(amount * degrees), 0.0, 0.0)
    pb = arm.pose.bones["head"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler = (0.0, math.radians(amount * 35.0), 0.0)  # about the head bone's own axis: turned


def main(argv):
    p = argparse.ArgumentParser(prog="mesh_rig_pictures.py")
    p.add_argument("-o", "--out", default=os.path.join(REPO, "docs", "images"))
    p.add_argument("--work", default=os.path.join(REPO, "out", "rig_mesh"))
    a = p.parse_args(argv)
    work = os.path.abspath(a.work)
    os.makedirs(work, exist_ok=True)
    volrig_addon.register()
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    obj = knight()
    ok(bpy.ops.volrig.rig_mesh(), "rig mesh")
    arm = bpy.context.active_object
    log(f"{obj.name}: {obj['volrig_rig_found']}; {len(arm.data.bones)} bones")
    arm.hide_render = True
    weight_colours(obj, arm)
    stage(scene, obj)
    renders = [render(scene, os.path.join(work, "rest.png"))]
    set_pose(arm, 1.0)
    arm.update_tag()
    renders.append(render(scene, os.path.join(work, "posed.png")))
    for name, factor in THICKER.items():
        arm.pose.bones[name]["volrig_thickness"] = factor
    arm.update_tag()
    renders.append(render(scene, os.path.join(work, "thicker.png")))
    out = os.path.join(os.path.abspath(a.out), "rig_mesh.png")
    sheet(renders, ["skin weights (Rig Mesh)", "posed (Armature modifier)",
                    "thicker forearm.L, thigh.R"], out,
          f"volrig: a mesh rigged and skinned through its volume ({obj['volrig_rig_found'].split(',')[0]}, "
          f"{len(arm.data.bones)} bones)")
    log(f"wrote {out}")


main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
sys.stdout.flush()
os._exit(0)

"""A quick stage for a volrig volume: an orthographic camera looking at its front (along +y, as the phantom and
most scans face -y), a sun and a dim world, and Cycles on the CPU at a low resolution. For previews, the demo and
tests; a real scene sets up its own."""
import bpy
import numpy as np
from mathutils import Matrix, Vector

from . import compat, engines


def volume_box(volume_obj):
    """World-space (min, max) corners of the imported grid."""
    s = volume_obj.volrig
    lo = np.asarray(s.origin, dtype=np.float64)
    hi = lo + (np.asarray(s.dims) - 1) * np.asarray(s.spacing)
    corners = [volume_obj.matrix_world @ Vector((x, y, z)) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
               for z in (lo[2], hi[2])]
    c = np.array([tuple(v) for v in corners])
    return c.min(axis=0), c.max(axis=0)


def stage(scene, volume_obj, resolution=(240, 320), samples=16, margin=1.15, azimuth=0.0):
    """Camera, light and render settings framing ``volume_obj`` from the front (``azimuth`` degrees turns the
    camera about the vertical axis towards +x); returns the camera object."""
    lo, hi = volume_box(volume_obj)
    centre = (lo + hi) / 2
    a = np.radians(azimuth)
    right = np.array([np.cos(a), np.sin(a), 0.0])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    size = hi - lo
    size[0] = np.ptp(corners @ right)  # the width the camera sees
    cam = scene.objects.get("volrig camera")
    if cam is None:
        cam = bpy.data.objects.new("volrig camera", bpy.data.cameras.new("volrig camera"))
        scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    aspect = resolution[0] / resolution[1]
    # ortho_scale spans the image's longer side
    if aspect < 1:
        cam.data.ortho_scale = margin * max(size[2], size[0] / aspect)
    else:
        cam.data.ortho_scale = margin * max(size[0], size[2] * aspect)
    distance = 2.0 * float(size.max())
    cam.data.clip_start = 0.01 * distance  # (Blender's 0.1 m would clip a small scan, a tooth in mm, away)
    cam.data.clip_end = 10 * float(size.max()) + 100
    cam.matrix_world = Matrix.Translation(Vector(centre + distance * np.array([np.sin(a), -np.cos(a), 0.0]))) @ \
        Matrix.Rotation(a, 4, "Z") @ Matrix.Rotation(np.pi / 2, 4, "X")
    scene.camera = cam
    sun = scene.objects.get("volrig sun")
    if sun is None:
        sun = bpy.data.objects.new("volrig sun", bpy.data.lights.new("volrig sun", "SUN"))
        scene.collection.objects.link(sun)
    sun.data.energy = 4.0
    sun.rotation_euler = (0.7, 0.3, -0.5)
    world_background(scene, (0.02, 0.02, 0.025))
    r = scene.render
    r.resolution_x, r.resolution_y = resolution
    r.resolution_percentage = 100
    r.image_settings.file_format = "PNG"
    engines.use(scene, samples)  # Cycles on the CPU, or EEVEE where this Cycles renders no grids
    return cam


def world_background(scene, color) -> None:
    """The scene's world (made when missing) a plain background of ``color`` (r, g, b) at strength 1."""
    if scene.world is None:
        scene.world = bpy.data.worlds.new("volrig world")
    compat.use_nodes(scene.world)
    bg = scene.world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (*color, 1.0)
        bg.inputs["Strength"].default_value = 1.0

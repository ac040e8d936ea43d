"""Which render engine shows volrig's grids in this Blender.

Cycles renders VDB volumes through NanoVDB. A Blender built without it (Debian's 5.2, whose OpenVDB 13 ships no
NanoVDB headers) renders every volume grid as empty space: black frames and no word why. So the first render
that needs to know probes once per Blender session (:func:`cycles_renders_grids`): a 4 x 4 voxel cube of density
1, a Principled Volume, an orthographic camera, a 6 x 6 pixel Cycles render of one sample into a scratch scene;
its centre pixel's alpha tells. When Cycles cannot, volrig renders with EEVEE and says so (:data:`NO_GRIDS`) in
the Look panel, the status bar and on the command line. EEVEE needs an OpenGL context: headless (``blender -b``),
Blender 4.2 and newer get one through EGL (Mesa's llvmpipe on a machine without a GPU; Debian: libegl1,
libegl-mesa0, libgl1-mesa-dri), so the demo, the showcase and ``volrig flythrough --render`` need no X server.

``VOLRIG_CYCLES_GRIDS=0`` (or ``1``) skips the probe and takes that answer, e.g. to test the fallback with a
Cycles that can."""
import os
import tempfile

import bpy
import numpy as np

import volrig

NO_GRIDS = ("this Blender's Cycles renders no VDB volumes (built without NanoVDB): rendering with EEVEE; "
            "use a blender.org build for Cycles")

_answer = None  # the probe's result, once per Blender session
_told = False


def cycles_renders_grids() -> bool:
    """True when this Blender's Cycles renders a VDB grid (probed once per session, then cached)."""
    global _answer
    if _answer is None:
        forced = os.environ.get("VOLRIG_CYCLES_GRIDS", "")
        _answer = forced == "1" if forced in ("0", "1") else _probe()
    return _answer


def known() -> bool:
    """Whether the probe has run (panels show its answer; they must not render to find out)."""
    return _answer is not None or os.environ.get("VOLRIG_CYCLES_GRIDS", "") in ("0", "1")


def eevee() -> str:
    """This Blender's EEVEE engine identifier (BLENDER_EEVEE in 3.x and 5.x, BLENDER_EEVEE_NEXT in 4.2 .. 4.5)."""
    items = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in items else "BLENDER_EEVEE"


def volume_engine() -> str:
    """The engine that renders volrig's volumes here: Cycles when it can, else EEVEE."""
    return "CYCLES" if cycles_renders_grids() else eevee()


def use(scene, samples: int = 16) -> str:
    """Sets ``scene`` to render volumes with :func:`volume_engine` at ``samples`` samples (Cycles on the CPU, no
    denoiser: Debian's Blender has no OpenImageDenoise; EEVEE with fine froxels and no shadow maps);
    says once per session why when it is EEVEE. Returns the engine."""
    engine = volume_engine()
    scene.render.engine = engine
    scene.cycles.device = "CPU"  # (set with EEVEE too: a user switching to Cycles gets a scene that renders)
    scene.cycles.samples = int(samples)
    scene.cycles.use_denoising = False
    scene.cycles.volume_bounces = 0
    if engine != "CYCLES":
        tell()
        ee = scene.eevee
        ee.taa_render_samples = max(int(samples), 1)
        ee.volumetric_tile_size = "2"  # froxels of 2 pixels: thin limbs keep their edges
        ee.volumetric_samples = 128
        # A scan's tissue is dense: light shadow maps, read per froxel, shadow a volume's lit surface by itself and
        # the figure turns almost black. Without them EEVEE's colours are the Cycles render's.
        for name in ("use_shadows", "use_volumetric_shadows"):
            if hasattr(ee, name):
                setattr(ee, name, False)
    return engine


def tell() -> None:
    """Prints :data:`NO_GRIDS` once per session and shows it in the status bar where there is one, for half a minute
    (the status bar's own hints come back after; the Look panel keeps saying it)."""
    global _told
    if not _told:
        print(f"volrig: {NO_GRIDS}")
        _told = True
    if _status(f"volrig: {NO_GRIDS}") and not bpy.app.timers.is_registered(_clear_status):
        bpy.app.timers.register(_clear_status, first_interval=30.0)


def _status(text) -> bool:
    """Sets (or, with None, clears) every window's status-bar text; False when there is no window."""
    wm = bpy.context.window_manager
    windows = [w for w in (wm.windows if wm is not None else []) if w.workspace is not None]
    for window in windows:
        window.workspace.status_text_set(text)
    return bool(windows)


def _clear_status():
    _status(None)
    return None  # once


#: Grids one volume material can read in EEVEE: a material reading more renders nothing at all. Measured in Debian's
#: Blender 5.2 on Mesa's llvmpipe: 14 render, 15 render blank, though the GPU module reports 32 fragment texture
#: units (so the bound is not the GPU's; not measured on other GPUs).
EEVEE_GRIDS = 14

_warned = {}  # material name -> the grid count it was warned about


def grids_read(mat) -> int:
    """The distinct grids a material's Attribute nodes read (the ones whose output is used)."""
    if mat is None or mat.node_tree is None:
        return 0
    return len({n.attribute_name for n in mat.node_tree.nodes
                if n.bl_idname == "ShaderNodeAttribute" and any(o.is_linked for o in n.outputs)})


def check_material(mat) -> str:
    """The message when ``mat`` reads more grids than EEVEE can and volrig renders with EEVEE here (once the probe
    has answered), printed once per material and count; "" otherwise."""
    if not known() or cycles_renders_grids():
        return ""
    count, limit = grids_read(mat), EEVEE_GRIDS
    if count <= limit:
        return ""
    message = (f"{mat.name} reads {count} grids; EEVEE reads at most {limit} in one volume material and renders "
               "nothing for it: hide some tissues or parts, or use a Blender whose Cycles renders VDB volumes")
    if _warned.get(mat.name) != count:
        print(f"volrig: {message}")
        _warned[mat.name] = count
    return message


def _probe() -> bool:
    """Renders a tiny volume in Cycles in a scratch scene; True when it shows."""
    made = []
    with tempfile.TemporaryDirectory(prefix="volrig_probe_") as tmp:
        try:
            path = os.path.join(tmp, "probe.vdb")
            volrig.Volume(np.ones((4, 4, 4), np.float32)).save(path)
            scene = bpy.data.scenes.new("volrig probe")
            made.append(scene)
            data = bpy.data.volumes.new("volrig probe")
            made.append(data)
            data.filepath = path
            obj = bpy.data.objects.new("volrig probe", data)
            made.append(obj)
            scene.collection.objects.link(obj)
            mat = bpy.data.materials.new("volrig probe")
            made.append(mat)
            _density_material(mat)
            data.materials.append(mat)
            cam = bpy.data.objects.new("volrig probe camera", bpy.data.cameras.new("volrig probe camera"))
            made += [cam, cam.data]
            scene.collection.objects.link(cam)
            cam.data.type = "ORTHO"
            cam.data.ortho_scale = 2.0
            cam.location = (2.0, 2.0, 20.0)  # the cube spans 0 .. 4 voxels = 0 .. 4 units; looking down -z
            scene.camera = cam
            r = scene.render
            r.engine = "CYCLES"
            r.resolution_x = r.resolution_y = 6
            r.resolution_percentage = 100
            r.film_transparent = True
            r.image_settings.file_format = "PNG"
            r.image_settings.color_mode = "RGBA"
            r.filepath = os.path.join(tmp, "probe.png")
            scene.cycles.device = "CPU"
            scene.cycles.samples = 1
            scene.cycles.use_denoising = False
            bpy.ops.render.render(write_still=True, scene=scene.name)
            img = bpy.data.images.load(r.filepath)
            try:
                alpha = np.array(img.pixels[:], np.float32).reshape(-1, 4)[:, 3]
            finally:
                bpy.data.images.remove(img)
            return bool(alpha.max() > 0.5)
        except Exception as e:  # a probe that cannot run says nothing about grids: keep Cycles
            print(f"volrig: could not test whether Cycles renders volumes ({e}); using Cycles")
            return True
        finally:
            _remove(made)


def _density_material(mat) -> None:
    from . import compat
    compat.use_nodes(mat)
    nodes = mat.node_tree.nodes
    nodes.clear()
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Density"].default_value = 50.0
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(vol.outputs[0], out.inputs["Volume"])


def _remove(made) -> None:
    """Removes the probe's data-blocks: objects first, then their data, the material and the scene."""
    order = (bpy.types.Object, bpy.types.Volume, bpy.types.Camera, bpy.types.Material, bpy.types.Scene)
    collections = (bpy.data.objects, bpy.data.volumes, bpy.data.cameras, bpy.data.materials, bpy.data.scenes)
    for kind, coll in zip(order, collections):
        for block in made:
            try:
                if isinstance(block, kind):
                    coll.remove(block)
            except ReferenceError:  # already gone with another
                pass

"""Scenes built with the volrig add-on in headless Blender: the README's demo and the sample scenes.

    blender -b --factory-startup --python scripts/blender_scenes.py -- demo [--out out/demo] [--frames 6]
    blender -b --factory-startup --python scripts/blender_scenes.py -- samples [--out blend_samples]

demo:    the humanoid phantom (1.8 m tall) imported, skeletonized, auto-rigged, walking (keyframes), a few frames
         baked and rendered with Cycles on the CPU (EEVEE where this Cycles renders no VDB grids: engines.py) into
         <out>/frame_NNNN.png plus <out>/contact_sheet.png; the scene
         is kept as <out>/walk.blend with its cache folder <out>/walk_volrig/.
samples: <out>/phantom_walk.blend (the phantom walking, 24 frames baked) and, when ../shared/data/frogtissue is
         present, <out>/frog_posed.blend (the frog's label map rigged and posed with keyframes, 3 frames baked).
Everything goes through the add-on's operators, as a user would click them.
"""
import argparse
import contextlib
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import volrig  # noqa: E402
import volrig_addon  # noqa: E402
from volrig_addon import bake, objects, staging  # noqa: E402
from volrig_support import data_root  # noqa: E402


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def ok(result, what):
    if result != {"FINISHED"}:
        raise RuntimeError(f"{what} did not finish: {result}")


def new_scene(blend_path):
    """An empty scene saved at ``blend_path`` first, so the add-on's cache folder goes beside it."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    os.makedirs(os.path.dirname(os.path.abspath(blend_path)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(blend_path))
    return bpy.context.scene


def rigged_volume(path, name, thinness=None, points=None, unit="MM", **settings):
    """Import ``path``, apply ``settings`` to the volume's volrig properties, skeletonize, pick the thinness (or
    the thinness giving about ``points`` points) and rig."""
    ok(bpy.ops.volrig.import_volume(filepath=path, unit=unit, name=name), "import")
    vol = bpy.context.active_object
    for key, value in settings.items():
        setattr(vol.volrig, key, value)
    ok(bpy.ops.volrig.skeletonize(), "skeletonize")
    if points is not None:
        from volrig_addon import scans
        sk = scans.skeleton(vol, compute=False)
        thinness = volrig.pipeline.voxels_from_thinness(sk.tp_for_count(points), vol.volrig.metric,
                                                        vol.volrig.spacing)
    vol.volrig.thinness = thinness
    log(f"{name}: {vol.volrig.point_count:,} skeleton points at thinness {vol.volrig.thinness:.3f} voxels")
    ok(bpy.ops.volrig.rig(), "rig")
    rig_obj = objects.members(vol)["RIG"]
    log(f"{name}: rig of {len(rig_obj.data.bones)} bones: {', '.join(b.name for b in rig_obj.data.bones)}")
    return vol


def phantom_walk(blend_path, scale, frames, stride=24):
    """The phantom (1.8 m) walking: ``frames`` keyframed frames; returns the Volume object."""
    scene = new_scene(blend_path)
    folder = os.path.dirname(os.path.abspath(blend_path))
    ph = volrig.phantom.humanoid(scale=scale, spacing=1800.0 / (940 * scale))  # mm per voxel, 1.8 m tall
    source = os.path.join(folder, "phantom.nrrd")
    ph.volume.save(source)
    vol = rigged_volume(source, "phantom", thinness=0.35, low=1.0, bind_mode="smooth")
    ok(bpy.ops.volrig.walk_cycle(frame_start=1, frames=frames, period=stride), "walk")
    vol.volrig.preset = "SOFT_TISSUE"
    vol.volrig.highlight_bone = "thigh.L"
    staging.stage(scene, vol, resolution=(240, 320), samples=16, azimuth=60.0)
    return vol


def frog_posed(blend_path, data):
    """The frog's label map rigged and posed: three keyframed frames bending its chains."""
    scene = new_scene(blend_path)
    vol = rigged_volume(data, "frog", points=12000, largest=True, bind_mode="smooth")
    rig_obj = objects.members(vol)["RIG"]
    leaves = [b for b in rig_obj.pose.bones if not b.children][:4]
    for frame, angle in ((1, 0.0), (2, 0.35), (3, 0.7)):
        for i, pb in enumerate(leaves):
            pb.rotation_mode = "XYZ"
            pb.rotation_euler = (angle * (1 if i % 2 else -1), 0.0, 0.0)
            pb.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_start, scene.frame_end = 1, 3
    staging.stage(scene, vol, resolution=(320, 320), samples=16)
    return vol


@contextlib.contextmanager
def quiet_stdout():
    """Blender's own stdout (Cycles' per-tile and per-sample log, "Fra:1 Mem:..." lines, written by C code, so
    at the file-descriptor level) goes to /dev/null inside; volrig's lines come before and after."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def engine_name(scene):
    """The engine and its samples, as a log line says them."""
    if scene.render.engine == "CYCLES":
        return f"Cycles, {scene.cycles.samples} samples"
    return f"EEVEE, {scene.eevee.taa_render_samples} samples"


def render_frames(scene, frames, out_dir):
    paths = []
    for k, f in enumerate(frames):
        scene.frame_set(f)
        scene.render.filepath = os.path.join(out_dir, f"frame_{f:04d}.png")
        started = time.perf_counter()
        with quiet_stdout():
            bpy.ops.render.render(write_still=True)
        paths.append(scene.render.filepath)
        log(f"rendered {k + 1}/{len(frames)}: frame {f}, {scene.render.resolution_x} x {scene.render.resolution_y}, "
            f"{engine_name(scene)}, {time.perf_counter() - started:.1f} s -> {scene.render.filepath}")
    return paths


def contact_sheet(paths, frames, out_path, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(paths), figsize=(2.2 * len(paths), 3.4))
    for ax, p, f in zip(np.atleast_1d(axes), paths, frames):
        ax.imshow(mpimg.imread(p))
        ax.set_title(f if isinstance(f, str) else f"frame {f}", fontsize=9)  # a frame number or a caption
        ax.axis("off")
    fig.suptitle(title, fontsize=10)
    fig.savefig(out_path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def sheet(paths, titles, out_path, title):
    """The images at ``paths`` side by side, each under its title, ``title`` above (one PNG at ``out_path``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(paths), figsize=(3.0 * len(paths), 4.2))
    for ax, path, t in zip(np.atleast_1d(axes), paths, titles):
        ax.imshow(mpimg.imread(path))
        ax.set_title(t, fontsize=10)
        ax.axis("off")
    fig.suptitle(title, fontsize=11)
    fig.savefig(out_path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def demo(out, scale, count):
    t0 = time.time()
    blend = os.path.join(os.path.abspath(out), "walk.blend")
    vol = phantom_walk(blend, scale, frames=24)
    scene = bpy.context.scene
    frames = [1 + round(i * 24 / count) for i in range(count)]
    vol.volrig.bake_frames = ",".join(str(f) for f in frames)
    t = time.time()
    ok(bpy.ops.volrig.bake(), "bake")
    log(f"baked {len(frames)} frames in {time.time() - t:.1f} s into {bake.frames_dir(vol)}")
    bpy.ops.wm.save_mainfile()
    paths = render_frames(scene, frames, os.path.abspath(out))
    sheet = os.path.join(os.path.abspath(out), "contact_sheet.png")
    contact_sheet(paths, frames, sheet, f"volrig: the phantom walking, baked and rendered in "
                                        f"{engine_name(scene).split(',')[0]} (Blender {bpy.app.version_string}) "
                                        f"(left thigh glowing); {len(objects.members(vol)['SPHERES'].data.vertices):,}"
                                        f" spheres")
    log(f"wrote {sheet} and {blend}; demo took {time.time() - t0:.0f} s")


def samples(out):
    t0 = time.time()
    out = os.path.abspath(out)
    vol = phantom_walk(os.path.join(out, "phantom_walk.blend"), 0.4, frames=24)
    ok(bpy.ops.volrig.bake(), "bake")
    bpy.ops.wm.save_mainfile()
    log(f"wrote {bpy.data.filepath} ({vol.volrig.baked_start}..{vol.volrig.baked_end} baked)")
    frog = str(data_root() / "frogtissue" / "frogtissue.mhd")
    if os.path.exists(frog):
        vol = frog_posed(os.path.join(out, "frog_posed.blend"), os.path.normpath(frog))
        ok(bpy.ops.volrig.bake(), "bake")
        bpy.ops.wm.save_mainfile()
        log(f"wrote {bpy.data.filepath}")
    else:
        log(f"skipped the frog: {os.path.normpath(frog)} is absent")
    log(f"samples took {time.time() - t0:.0f} s")


def main(argv):
    p = argparse.ArgumentParser(prog="blender_scenes.py")
    sub = p.add_subparsers(dest="what", required=True)
    d = sub.add_parser("demo")
    d.add_argument("--out", default="out/demo")
    d.add_argument("--scale", type=float, default=0.4, help="phantom grid scale (1.0 = 290 x 169 x 940)")
    d.add_argument("--frames", type=int, default=6, help="frames to bake and render")
    s = sub.add_parser("samples")
    s.add_argument("--out", default="blend_samples")
    args = p.parse_args(argv)
    volrig_addon.register()
    if args.what == "demo":
        demo(args.out, args.scale, args.frames)
    else:
        samples(args.out)


def run_and_exit(main):
    """Runs ``main`` with the arguments after Blender's ``--`` and exits Blender: 0, or 1 with the traceback."""
    try:
        main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
        code = 0
    except Exception:
        import traceback
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run_and_exit(main)

"""The animated Visible Human (issue 21's showcase): a labelled scan rigged automatically, driven by a motion-capture
walk, baked with its tissue grid (each voxel's class) and rendered in Cycles with per-tissue looks (skin and muscle faint over the moving
skeleton and organs, then the skeleton and organs alone). Headless; point it at any labelled scan with its table of
tissue codes:

    blender -b --factory-startup --python scripts/showcase.py -- \\
        [--labels ../shared/data/visible-human/austinman_4mm_labels.nii.gz] \\
        [--tissues ../shared/data/visible-human/austinman_tissues.tsv] [--clip ../shared/data/bvh/131_01.bvh] \\
        [--count 4] [--samples 16] [--height 640] [--hide fat] [--opacity skin=0.015,muscle=0.012] \\
        [--peel skin,muscle,cartilage] [--view 1 -0.35 0.1] [--out docs/images/showcase_vhm.png] \\
        [--mm 4|2|1] [--width W] [--full-cycle] [--bvh-frames N ...] [--step-rate 2] \\
        [--video out.mp4 [--fps 24] [--crf 28] [--loops 1] [--sheet 12] [--frames DIR]]

The scan is any label map volrig reads (NIfTI, NRRD, MetaImage, DICOM, TIFF) whose non-zero codes are the body
(codes the table calls external air are left out); the table is TSV or CSV (code, name). Tissue classes come from
``volrig.TISSUE_CLASSES`` (edit it, or the material's Value and RGB nodes, for other looks); --hide leaves classes
out of the render, --opacity overrides classes' opacities (the defaults make skin, muscle and tendons faint) and
--peel adds a second row without more classes (default: skin, muscle and tendons: the skeleton and organs walking);
--view says where the camera looks from. The body is rigged as a humanoid with +z up (--kind, --up to change), the
clip retargeted in place, ``--count`` frames from the pose with one foot farthest ahead to the pose with the other
(searched in the clip's first ``--span`` BVH frames) baked (linear, nearest sampling) into a temporary folder and
rendered, and a contact sheet written to --out. --full-cycle spans a whole walk cycle instead (two steps, from one
foot's farthest reach back to it, looping); --mm picks the Visible Human's 4, 2 or 1 mm labels. --video renders
every frame in the first look and encodes them as H.264 with Debian's ffmpeg, with a contact sheet of --sheet of
them (docs/tissues.md, "The walk as a video"). Frames are baked, rendered and deleted one at a time.

The Visible Human data are not part of volrig (licence: CC BY-NC-ND 3.0): see ../shared/data/visible-human/README.md
for where they come from (AustinMan v2.6, UT Austin, from the NLM Visible Human Project).
"""
import argparse
import glob
import os
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "scripts"),
                os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import volrig  # noqa: E402
from volrig import pipeline  # noqa: E402
from blender_scenes import log, quiet_stdout, run_and_exit  # noqa: E402
import showcase_plan as plan  # noqa: E402
from volrig_addon import compat, engines, materials  # noqa: E402
from volrig_support import data_root  # noqa: E402

DATA = str(data_root())
OUT = os.path.join(REPO, "docs", "images", "showcase_vhm.png")


def looks_of(args, tissues):
    """The tissues with --hide and --opacity applied, and the set hidden; SystemExit naming an unknown class."""
    names = {t.name for t in tissues}
    hidden = {h.strip() for h in args.hide.split(",") if h.strip()}
    peeled = {h.strip() for h in args.peel.split(",") if h.strip()}
    opacity = {}
    for item in filter(None, (x.strip() for x in args.opacity.split(","))):
        name, _, value = item.partition("=")
        opacity[name] = float(value)
    unknown = (hidden | peeled | set(opacity)) - names
    if unknown:
        raise SystemExit(f"showcase: {', '.join(sorted(unknown))}: no such tissue class; classes: "
                         + ", ".join(t.name for t in tissues))
    tissues = [t._replace(visible=t.name not in hidden, opacity=opacity.get(t.name, t.opacity)) for t in tissues]
    return volrig.tissues.index_order(tissues), hidden, peeled, opacity  # (the class indices of these looks)


def stride_frames(rig, motion, args, up):
    """``args.count`` BVH frames (0-based) of the walk within the clip's first ``args.span`` frames: from the pose
    with one foot farthest ahead to the pose with the other (half a stride, the walk's clearest motion), or with
    ``args.cycle`` a whole cycle (two steps, looping; ``showcase_plan.walk_frames``). Rigs without Rigify feet (or
    a clip without steps) take frames spread over the span."""
    span = min(args.span, motion.frame_count)
    fallback = plan.spread(span, args.count)
    if "foot.L" not in rig.names or "foot.R" not in rig.names:
        return fallback
    candidates = list(range(0, span, 2))
    _, M = pipeline.mocap_poses(rig, motion, candidates, up_axis=args.clip_up)
    feet = [rig.index("foot.L"), rig.index("foot.R")]
    heads = rig.heads()
    at = [np.einsum("fij,j->fi", M[:, b], np.r_[heads[b], 1.0])[:, :3] for b in feet]
    side = heads[feet[0]] - heads[feet[1]]
    forward = np.cross(up, side)
    if np.linalg.norm(forward) < 1e-9:
        return fallback
    ahead = (at[0] - at[1]) @ (forward / np.linalg.norm(forward))
    if ahead.max() - ahead.min() < 0.05 * np.linalg.norm(side):
        return fallback
    return plan.walk_frames(ahead, candidates, args.count, cycle=args.cycle) or fallback


def rig_and_plan(args, work, labels, table, tissues):
    """Rig the scan and drive it with the clip; returns (the bake into ``work``, each frame's matrices, BVH
    frames). The frames are baked one at a time as they are rendered (``bake_one``): a 1 mm frame holds about
    1.4 GB while it is baked and its file about 150 MB, so none waits for the others."""
    t = time.perf_counter()
    up = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1), "-z": (0, 0, -1)}[args.up]
    body, r = plan.rig_labels(labels, table, tissues, args.thinness, args.kind, up, args.rigid_bone)
    log(f"rigged {os.path.basename(args.labels)}: {int(body.array.sum()):,} body voxels, {len(r.points):,} spheres, "
        f"{r.rig.kind} ({len(r.rig)} bones) in {time.perf_counter() - t:.1f} s; tissues: " + ", ".join(x.name for x in tissues))
    motion = volrig.read_bvh(args.clip)
    frames = ([f - 1 for f in args.bvh_frames] if args.bvh_frames
              else stride_frames(r.rig, motion, args, np.asarray(up, float)))
    _, matrices = pipeline.mocap_poses(r.rig, motion, frames, up_axis=args.clip_up)
    bake = pipeline.FolderBake(labels, r.points, r.binding, work, "body", mode="linear", sampling="nearest",
                               tissues=tissues)
    log(f"{len(frames)} frames: BVH frames {frames[0] + 1}-{frames[-1] + 1}"
        + (" (a whole cycle)" if args.cycle else ""))
    return bake, matrices, frames


def bake_one(bake, k, matrices, frames):
    """Frame ``k`` (0-based) baked and its file written; returns (its path, seconds)."""
    started = time.perf_counter()
    stats = bake.bake(k + 1, matrices[k])
    bake.finish()  # (the file written before it is rendered; the next bake starts a writer again)
    took = time.perf_counter() - started
    log(f"baked {k + 1}/{len(frames)} (BVH frame {frames[k] + 1}): {stats['covered']:,} voxels, {took:.1f} s")
    return bake.path(k + 1), took


def scene_for(labels, height, view, width=None, step_rate=2.0):
    """An empty scene in Cycles with a camera three-quarters from the front and a soft key light, framing the
    scan's box's height (world units: the scan's, shown at 1/1000: millimetres as metres); ``width`` pixels wide
    (default: three quarters of the height)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    engines.use(scene)  # Cycles on the CPU, or EEVEE where this Cycles renders no grids
    scene.render.film_transparent = False
    scene.render.resolution_y = height
    scene.render.resolution_x = int(height * 0.75) if width is None else int(width)  # (a leg swung forward)
    scene.cycles.volume_step_rate = float(step_rate)
    scene.cycles.volume_max_steps = 512
    world = bpy.data.worlds.new("showcase")
    compat.use_nodes(world)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.02, 0.025, 0.03, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = world
    box = np.array(labels.origin) + np.array(labels.spacing) * (np.array(labels.array.shape[::-1]) - 1)
    lo, hi = np.minimum(labels.origin, box) / 1000.0, np.maximum(labels.origin, box) / 1000.0
    centre, size = (lo + hi) / 2, hi - lo
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = float(size[2]) * 1.08
    cam.data.sensor_fit = "VERTICAL"  # (the scale is the height's, in a wide frame too)
    scene.collection.objects.link(cam)
    scene.camera = cam
    direction = np.asarray(view, dtype=float)
    cam.location = tuple(centre + direction / np.linalg.norm(direction) * float(size.max()) * 2.0)
    target = bpy.data.objects.new("target", None)
    target.location = tuple(centre)
    scene.collection.objects.link(target)
    aim = cam.constraints.new("TRACK_TO")
    aim.target, aim.track_axis, aim.up_axis = target, "TRACK_NEGATIVE_Z", "UP_Y"
    for name, energy, angles in (("key", 4.0, (50.0, 10.0, 30.0)), ("fill", 1.5, (70.0, -20.0, -120.0))):
        light = bpy.data.objects.new(name, bpy.data.lights.new(name, "SUN"))
        light.data.energy = energy
        light.rotation_euler = tuple(np.radians(angles))
        scene.collection.objects.link(light)
    return scene


def show(scene, path, mat, name=None):
    """The Volume object of one baked frame, at 1/1000 scale, with the tissue material ``mat``, the previous one
    removed; ``name``: the object's (default: the file's; Cycles draws its noise from it)."""
    for ob in [o for o in scene.objects if o.type == "VOLUME"]:
        data = ob.data
        bpy.data.objects.remove(ob)
        bpy.data.volumes.remove(data)  # (its grids leave memory: a 1 mm frame's are large)
    data = bpy.data.volumes.new(name or os.path.basename(path))
    data.filepath = path
    ob = bpy.data.objects.new(data.name, data)
    ob.scale = (0.001, 0.001, 0.001)
    data.materials.append(mat)
    scene.collection.objects.link(ob)


def parse_args(argv):
    """The command line (module docstring), --labels defaulting to the Visible Human at --mm."""
    ap = argparse.ArgumentParser(prog="showcase.py")
    ap.add_argument("--mm", type=int, choices=plan.MM, default=4,
                    help="the Visible Human labels' resolution in mm (default: 4); --labels wins over it")
    ap.add_argument("--labels", default=None, help="a label map (default: the Visible Human's at --mm)")
    ap.add_argument("--tissues", default=os.path.join(DATA, "visible-human", "austinman_tissues.tsv"))
    ap.add_argument("--clip", default=os.path.join(DATA, "bvh", "131_01.bvh"))
    ap.add_argument("--clip-up", choices=["y", "z"], default="y", help="the BVH's up axis")
    ap.add_argument("--span", type=int, default=300,
                    help="BVH frames searched for half a stride (one foot farthest ahead, then the other); the "
                         "rendered frames go from the one to the other (default: 300)")
    ap.add_argument("--count", type=int, default=4, help="frames to bake and render")
    ap.add_argument("--bvh-frames", type=int, nargs="+", default=None, metavar="N",
                    help="these BVH frames (1-based) instead of --count frames of the walk (e.g. 183: a pose to look at)")
    ap.add_argument("--full-cycle", dest="cycle", action="store_true",
                    help="the frames span a whole walk cycle (two steps, from one foot's turn back to it, the last "
                         "left out so the frames loop) instead of half a stride")
    ap.add_argument("--thinness", type=float, default=0.5, help="thinness in voxels")
    ap.add_argument("--kind", choices=volrig.rig.KINDS, default="humanoid")
    ap.add_argument("--no-rigid-bone", dest="rigid_bone", action="store_false",
                    help="let the bones bend with the flesh (default: the tissue table's bone is rigid tissue)")
    ap.add_argument("--up", choices=["x", "y", "z", "-z"], default="z", help="the body's up axis in the scan")
    ap.add_argument("--hide", default="fat", help="tissue classes to leave out, comma-separated (default: fat)")
    ap.add_argument("--opacity", default="skin=0.015,muscle=0.012,cartilage=0.01",
                    help="opacities replacing the preset's, class=value,... (default: skin, muscle and tendons faint)")
    ap.add_argument("--peel", default="skin,muscle,cartilage",
                    help="a second row without these classes too (default: the skeleton and organs); empty: none; "
                         "not with --video")
    ap.add_argument("--view", type=float, nargs=3, default=(1.0, -0.35, 0.1),
                    help="direction from the body to the camera (x, y, z in the scan; default: its left side)")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--height", type=int, default=640, help="image height in pixels")
    ap.add_argument("--width", type=int, default=None, help="image width in pixels (default: 3/4 of the height)")
    ap.add_argument("--step-rate", type=float, default=2.0,
                    help="Cycles' volume step rate (steps of this many voxels; default 2; larger is faster)")
    ap.add_argument("--strength", type=float, default=0.06, help="density per world unit at opacity 1")
    ap.add_argument("--video", default=None, metavar="PATH.mp4",
                    help="render every frame in the first look, encode them as H.264 (ffmpeg) into PATH.mp4 and "
                         "write a contact sheet of --sheet of them to --out (default: PATH_sheet.png)")
    ap.add_argument("--fps", type=float, default=24, help="the video's frames a second (default: 24)")
    ap.add_argument("--crf", type=int, default=28, help="the video's x264 CRF (default: 28; larger is smaller)")
    ap.add_argument("--loops", type=int, default=1, help="times the video plays the frames (default: 1)")
    ap.add_argument("--sheet", type=int, default=12, help="frames on a video's contact sheet (default: 12)")
    ap.add_argument("--frames", default=None, metavar="DIR",
                    help="keep the video's rendered frames in DIR (frame_001.png, ...; default: a temporary folder)")
    ap.add_argument("--out", default=None, help=f"the contact sheet (default: {os.path.relpath(OUT, REPO)})")
    args = ap.parse_args(argv)
    if args.labels is None:
        args.labels = plan.labels_for(args.mm, DATA)
    return args


def main(argv):
    args = parse_args(argv)
    for what, path in (("labels", args.labels), ("tissues", args.tissues), ("clip", args.clip)):
        if not os.path.exists(path):
            raise SystemExit(f"showcase: {what} file {path} not found (the Visible Human and CMU clips live in "
                             f"../shared/data; see its README for where they come from), or pass --{what}")
    ffmpeg = plan.ffmpeg_path() if args.video else None  # (before the work: a missing ffmpeg fails at once)
    if args.video:
        plan.ffmpeg_command("frame_%03d.png", "x.mp4", args.fps, args.crf, args.loops)  # (checks --loops)
    if args.out is None:
        args.out = OUT if not args.video else os.path.splitext(args.video)[0] + "_sheet.png"
    t0 = time.perf_counter()
    work = tempfile.mkdtemp(prefix="volrig_showcase_")
    try:
        labels = volrig.load(args.labels)
        table = volrig.read_tissue_table(args.tissues)
        found = volrig.tissue_classes(table, present=np.unique(labels.array))
        if not found:
            raise SystemExit(f"showcase: none of {args.tissues}'s codes is in {args.labels}")
        tissues, hidden, peeled, opacity = looks_of(args, found)  # (before the work: a typo fails at once)
        log(f"read {os.path.basename(args.labels)}: {' x '.join(map(str, labels.array.shape[::-1]))} voxels of "
            f"{labels.spacing[0]:g} mm, {time.perf_counter() - t0:.1f} s")
        bake, matrices, frames = rig_and_plan(args, work, labels, table, tissues)
        scene = scene_for(labels, args.height, args.view, args.width, args.step_rate)
        engines.use(scene, args.samples)
        faint = ", ".join(sorted(opacity)) + " faint" if opacity else "as the preset"
        looks = [(faint + (f"; {', '.join(sorted(hidden))} hidden" if hidden else ""), tissues)]
        if peeled and not args.video:
            looks.append((", ".join(sorted(peeled | hidden)) + " hidden",
                          [t._replace(visible=t.visible and t.name not in peeled) for t in tissues]))
        mats = [materials.tissue_material("showcase", look, strength=args.strength)  # (one grid: EEVEE too)
                for _, look in looks]
        shots = os.path.abspath(args.frames) if args.frames and args.video else work
        os.makedirs(shots, exist_ok=True)
        for old in glob.glob(os.path.join(shots, "frame_[0-9][0-9][0-9].png")):
            os.remove(old)  # (a longer run's frames in --frames would go into the video)
        rows = [[] for _ in looks]
        baking = rendering = 0.0
        started_frames = time.perf_counter()
        for k in range(len(frames)):
            path, took = bake_one(bake, k, matrices, frames)
            baking += took
            for r, ((caption, _), mat) in enumerate(zip(looks, mats)):
                show(scene, path, mat, os.path.basename(path) + (f".{r:03d}" if r else ""))  # (as one volume
                # per look and frame kept would be named: the same noise as when they were)
                name = f"frame_{k + 1:03d}.png" if args.video else f"render_{r}_{k + 1:02d}.png"
                scene.render.filepath = os.path.join(shots, name)
                started = time.perf_counter()
                with quiet_stdout():
                    bpy.ops.render.render(write_still=True)
                took = time.perf_counter() - started
                rendering += took
                rows[r].append((scene.render.filepath, f"BVH frame {frames[k] + 1}"))
                done = time.perf_counter() - started_frames
                log(f"rendered {k + 1}/{len(frames)} ({caption}) in {took:.1f} s; {done:.0f} s so far, about "
                    f"{done / (k + 1) * (len(frames) - k - 1):.0f} s to go")
            for ob in [o for o in scene.objects if o.type == "VOLUME"]:  # (Blender lets the file go)
                data = ob.data
                bpy.data.objects.remove(ob)
                bpy.data.volumes.remove(data)
            os.remove(path)  # (a 1 mm frame's file is about 150 MB)
        n = max(len(frames), 1)
        log(f"{len(frames)} frames: bake {baking / n:.1f} s a frame, render {rendering / n:.1f} s a frame "
            f"({args.samples} samples, {scene.render.resolution_x} x {scene.render.resolution_y})")
        engine = "Cycles" if scene.render.engine == "CYCLES" else "EEVEE"
        title = (f"{os.path.basename(args.labels)} walking ({os.path.basename(args.clip)}), rigged by volrig, baked "
                 f"and rendered in {engine} with per-tissue looks")
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        if args.video:
            os.makedirs(os.path.dirname(os.path.abspath(args.video)), exist_ok=True)
            command = plan.ffmpeg_command(os.path.join(shots, "frame_%03d.png"), args.video, args.fps, args.crf,
                                          args.loops, ffmpeg=ffmpeg)
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"showcase: ffmpeg failed ({' '.join(command)}):\n{done.stderr}")
            log(f"wrote {args.video}: {os.path.getsize(args.video) / 1e6:.2f} MB, {len(frames) * args.loops} frames "
                f"at {args.fps:g} fps")
            pick = [rows[0][i] for i in plan.sheet_subset(len(frames), args.sheet)]
            plan.video_sheet(pick, args.out, f"{os.path.basename(args.labels)} walking ({os.path.basename(args.clip)}; "
                             f"{engine}, {looks[0][0]}):\n{len(pick)} of the video's {len(frames)} frames")
        else:
            plan.grid(rows, [caption for caption, _ in looks], args.out, title)
        log(f"wrote {args.out} in {time.perf_counter() - t0:.0f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)


run_and_exit(main)

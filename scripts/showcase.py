"""The animated Visible Human (issue 21's showcase): a labelled scan rigged automatically, driven by a motion-capture
walk, baked with its tissue grid (each voxel's class) and rendered in Cycles with per-tissue looks (skin and muscle faint over the moving
skeleton and organs, then the skeleton and organs alone). Headless; point it at any labelled scan with its table of
tissue codes:

    blender -b --factory-startup --python scripts/showcase.py -- \\
        [--labels ../shared/data/visible-human/austinman_4mm_labels.nii.gz] \\
        [--tissues ../shared/data/visible-human/austinman_tissues.tsv] [--clip ../shared/data/bvh/131_01.bvh] \\
        [--count 4] [--samples 16] [--height 640] [--hide fat] [--opacity skin=0.015,muscle=0.012] \\
        [--peel skin,muscle,cartilage] [--view 1 -0.35 0.1] [--out docs/images/showcase_vhm.png]

The scan is any label map volrig reads (NIfTI, NRRD, MetaImage, DICOM, TIFF) whose non-zero codes are the body
(codes the table calls external air are left out); the table is TSV or CSV (code, name). Tissue classes come from
``volrig.TISSUE_CLASSES`` (edit it, or the material's Value and RGB nodes, for other looks); --hide leaves classes
out of the render, --opacity overrides classes' opacities (the defaults make skin, muscle and tendons faint) and
--peel adds a second row without more classes (default: skin, muscle and tendons: the skeleton and organs walking);
--view says where the camera looks from. The body is rigged as a humanoid with +z up (--kind, --up to change), the
clip retargeted in place, ``--count`` frames from the pose with one foot farthest ahead to the pose with the other
(searched in the clip's first ``--span`` BVH frames) baked (linear, nearest sampling) into a temporary folder and
rendered, and a contact sheet written to --out.

The Visible Human data are not part of volrig (licence: CC BY-NC-ND 3.0): see ../shared/data/visible-human/README.md
for where they come from (AustinMan v2.6, UT Austin, from the NLM Visible Human Project).
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
import numpy as np  # noqa: E402

import volrig  # noqa: E402
from volrig import pipeline  # noqa: E402
from blender_scenes import log, quiet_stdout, run_and_exit  # noqa: E402
from volrig_addon import compat, engines, materials  # noqa: E402
from volrig_support import data_root  # noqa: E402

DATA = str(data_root())
OUT = os.path.join(REPO, "docs", "images", "showcase_vhm.png")


def body_of(labels: volrig.Volume, table) -> volrig.Volume:
    """The body: every voxel whose code is not outside (0, or named like external air by the table)."""
    outside = np.isin(labels.array, volrig.tissues.outside_codes(table))
    return volrig.Volume(~outside, labels.spacing, labels.origin)


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
    """``args.count`` BVH frames (0-based) from the pose with one foot farthest ahead to the pose with the other
    farthest ahead, within the clip's first ``args.span`` frames: half a stride, the walk's clearest motion. Rigs
    without Rigify feet (or a clip without steps) take frames spread over the span."""
    span = min(args.span, motion.frame_count)
    spread = [round(k * (span - 1) / max(args.count, 1)) for k in range(args.count)]
    if "foot.L" not in rig.names or "foot.R" not in rig.names:
        return spread
    candidates = list(range(0, span, 2))
    _, M = pipeline.mocap_poses(rig, motion, candidates, up_axis=args.clip_up)
    feet = [rig.index("foot.L"), rig.index("foot.R")]
    heads = rig.heads()
    at = [np.einsum("fij,j->fi", M[:, b], np.r_[heads[b], 1.0])[:, :3] for b in feet]
    side = heads[feet[0]] - heads[feet[1]]
    forward = np.cross(up, side)
    if np.linalg.norm(forward) < 1e-9:
        return spread
    ahead = (at[0] - at[1]) @ (forward / np.linalg.norm(forward))
    a, b = sorted((int(np.argmin(ahead)), int(np.argmax(ahead))))
    if ahead.max() - ahead.min() < 0.05 * np.linalg.norm(side) or b == a:
        return spread
    return [candidates[a] + round(k * (candidates[b] - candidates[a]) / max(args.count - 1, 1))
            for k in range(args.count)]


def rig_and_bake(args, work, labels, table, tissues):
    """Rig the scan, drive it with the clip and bake ``args.count`` frames; returns (frame files, BVH frames)."""
    t = time.perf_counter()
    body = body_of(labels, table)
    sk = pipeline.skeleton_of(body)
    points = pipeline.skeleton_points(sk, thinness=pipeline.thinness_from_voxels(args.thinness, sk.metric,
                                                                                  body.spacing))
    up = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1), "-z": (0, 0, -1)}[args.up]
    bone = [t for t in tissues if t.name == "bone"] if args.rigid_bone else []
    rigid = volrig.rigid_tissue(labels, labels=bone[0].codes) if bone else None  # the rigid layer (issue 18)
    r = pipeline.rig_skeleton(points, body, kind=args.kind, up=up, rigid=rigid)
    log(f"rigged {os.path.basename(args.labels)}: {int(body.array.sum()):,} body voxels, {len(points):,} "
        f"spheres, {r.rig.kind} ({len(r.rig)} bones) in {time.perf_counter() - t:.1f} s; tissues: "
        + ", ".join(x.name for x in tissues))
    motion = volrig.read_bvh(args.clip)
    frames = stride_frames(r.rig, motion, args, np.asarray(up, float))
    _, matrices = pipeline.mocap_poses(r.rig, motion, frames, up_axis=args.clip_up)
    bake = pipeline.FolderBake(labels, r.points, r.binding, work, "body", mode="linear", sampling="nearest",
                               tissues=tissues)
    try:
        for k, m in enumerate(matrices):
            started = time.perf_counter()
            stats = bake.bake(k + 1, m)
            log(f"baked {k + 1}/{len(frames)} (BVH frame {frames[k] + 1}): {stats['covered']:,} voxels, "
                f"{time.perf_counter() - started:.1f} s")
    finally:
        bake.finish()
    return [bake.path(k + 1) for k in range(len(frames))], frames


def scene_for(labels, height, view):
    """An empty scene in Cycles with a camera three-quarters from the front and a soft key light, framing the
    scan's box (world units: the scan's, shown at 1/1000: millimetres as metres)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    engines.use(scene)  # Cycles on the CPU, or EEVEE where this Cycles renders no grids
    scene.render.film_transparent = False
    scene.render.resolution_y = height
    scene.render.resolution_x = int(height * 0.75)  # (room for a leg swung forward)
    scene.cycles.volume_step_rate = 2.0
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


def show(scene, path, mat):
    """The Volume object of one baked frame, at 1/1000 scale, with the tissue material ``mat``, the previous one
    removed."""
    for ob in [o for o in scene.objects if o.type == "VOLUME"]:
        bpy.data.objects.remove(ob)
    data = bpy.data.volumes.new(os.path.basename(path))
    data.filepath = path
    ob = bpy.data.objects.new(data.name, data)
    ob.scale = (0.001, 0.001, 0.001)
    data.materials.append(mat)
    scene.collection.objects.link(ob)


def grid(rows, labels, out, title):
    """Rows of (image, caption) as one PNG, each row's label at its left."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    n = max(len(r) for r in rows)
    fig, axes = plt.subplots(len(rows), n, figsize=(2.4 * n, 4.2 * len(rows)), squeeze=False)
    for r, (row, label) in enumerate(zip(rows, labels)):
        for c in range(n):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            for side in ax.spines.values():
                side.set_visible(False)
            if c < len(row):
                ax.imshow(mpimg.imread(row[c][0]))
                ax.set_title(row[c][1], fontsize=9)
        axes[r][0].set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.savefig(out, dpi=100, bbox_inches="tight")
    plt.close(fig)


def main(argv):
    ap = argparse.ArgumentParser(prog="showcase.py")
    ap.add_argument("--labels", default=os.path.join(DATA, "visible-human", "austinman_4mm_labels.nii.gz"))
    ap.add_argument("--tissues", default=os.path.join(DATA, "visible-human", "austinman_tissues.tsv"))
    ap.add_argument("--clip", default=os.path.join(DATA, "bvh", "131_01.bvh"))
    ap.add_argument("--clip-up", choices=["y", "z"], default="y", help="the BVH's up axis")
    ap.add_argument("--span", type=int, default=300,
                    help="BVH frames searched for half a stride (one foot farthest ahead, then the other); the "
                         "rendered frames go from the one to the other (default: 300)")
    ap.add_argument("--count", type=int, default=4, help="frames to bake and render")
    ap.add_argument("--thinness", type=float, default=0.5, help="thinness in voxels")
    ap.add_argument("--kind", choices=volrig.rig.KINDS, default="humanoid")
    ap.add_argument("--no-rigid-bone", dest="rigid_bone", action="store_false",
                    help="let the bones bend with the flesh (default: the tissue table's bone is rigid tissue)")
    ap.add_argument("--up", choices=["x", "y", "z", "-z"], default="z", help="the body's up axis in the scan")
    ap.add_argument("--hide", default="fat", help="tissue classes to leave out, comma-separated (default: fat)")
    ap.add_argument("--opacity", default="skin=0.015,muscle=0.012,cartilage=0.01",
                    help="opacities replacing the preset's, class=value,... (default: skin, muscle and tendons faint)")
    ap.add_argument("--peel", default="skin,muscle,cartilage",
                    help="a second row without these classes too (default: the skeleton and organs); empty: none")
    ap.add_argument("--view", type=float, nargs=3, default=(1.0, -0.35, 0.1),
                    help="direction from the body to the camera (x, y, z in the scan; default: its left side)")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--height", type=int, default=640, help="image height in pixels")
    ap.add_argument("--strength", type=float, default=0.06, help="density per world unit at opacity 1")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args(argv)
    for what, path in (("labels", args.labels), ("tissues", args.tissues), ("clip", args.clip)):
        if not os.path.exists(path):
            raise SystemExit(f"showcase: {what} file {path} not found (the Visible Human and CMU clips live in "
                             f"../shared/data; see its README for where they come from), or pass --{what}")
    t0 = time.perf_counter()
    work = tempfile.mkdtemp(prefix="volrig_showcase_")
    try:
        labels = volrig.load(args.labels)
        table = volrig.read_tissue_table(args.tissues)
        found = volrig.tissue_classes(table, present=np.unique(labels.array))
        if not found:
            raise SystemExit(f"showcase: none of {args.tissues}'s codes is in {args.labels}")
        tissues, hidden, peeled, opacity = looks_of(args, found)  # (before the work: a typo fails at once)
        files, frames = rig_and_bake(args, work, labels, table, tissues)
        scene = scene_for(labels, args.height, args.view)
        engines.use(scene, args.samples)
        faint = ", ".join(sorted(opacity)) + " faint" if opacity else "as the preset"
        looks = [(faint + (f"; {', '.join(sorted(hidden))} hidden" if hidden else ""), tissues)]
        if peeled:
            looks.append((", ".join(sorted(peeled | hidden)) + " hidden",
                          [t._replace(visible=t.visible and t.name not in peeled) for t in tissues]))
        rows = []
        for caption, look in looks:
            mat = materials.tissue_material("showcase", look, strength=args.strength)  # (one grid: EEVEE too)
            row = []
            for k, path in enumerate(files):
                show(scene, path, mat)
                scene.render.filepath = os.path.join(work, f"render_{len(rows)}_{k + 1:02d}.png")
                started = time.perf_counter()
                with quiet_stdout():
                    bpy.ops.render.render(write_still=True)
                row.append((scene.render.filepath, f"BVH frame {frames[k] + 1}"))
                log(f"rendered {k + 1}/{len(files)} ({caption}) in {time.perf_counter() - started:.1f} s")
            rows.append(row)
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        grid(rows, [caption for caption, _ in looks], args.out,
             f"{os.path.basename(args.labels)} walking ({os.path.basename(args.clip)}), rigged by volrig, baked "
             f"and rendered in {'Cycles' if scene.render.engine == 'CYCLES' else 'EEVEE'} with per-tissue looks")
        log(f"wrote {args.out} in {time.perf_counter() - t0:.0f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)


run_and_exit(main)

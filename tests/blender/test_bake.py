"""Baking the posed phantom into a VDB sequence, rendering it (Cycles, or EEVEE where this Cycles renders no grids),
and baking a saved .blend headless."""
import os
import subprocess

import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from mathutils import Euler

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _cli_env():
    """``python -m volrig`` finding the add-on as an importable package (as an installed one would be)."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(os.path.join(REPO, d) for d in ("python", "addon")))


def _members(vol):
    from volrig_addon.objects import members
    return members(vol)


def _active_voxels(path, grid):
    return next(g["active_voxels"] for g in volrig._volrig.vdb_grids(path) if g["name"] == grid)


def _pose_forearm(rig_obj, frames_angles):
    """Keyframes forearm.L at the given {frame: angle about its local X (radians)}."""
    pb = rig_obj.pose.bones["forearm.L"]
    pb.rotation_mode = "XYZ"
    for frame, angle in frames_angles.items():
        pb.rotation_euler = Euler((angle, 0.0, 0.0))
        pb.keyframe_insert("rotation_euler", frame=frame)


@pytest.fixture
def posed(rigged):
    vol = rigged
    rig_obj = _members(vol)["RIG"]
    _pose_forearm(rig_obj, {1: 0.0, 2: 0.6, 3: 1.2})
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 3
    return vol


def test_bake_writes_one_vdb_per_frame_and_plays_them(posed):
    from volrig_addon import bake, scans
    vol = posed
    scene = bpy.context.scene
    run_op(bpy.ops.volrig.bake)  # in the background: blocking execute
    files = [bake.frame_path(vol, f) for f in (1, 2, 3)]
    assert all(os.path.exists(f) for f in files)
    # the rest reconstruction's voxels, with the binding as the vertex groups hold it
    saved = volrig.load_rig(scans.rig_path(vol))
    rest = volrig.Deformer(scans.source(vol), saved.points, saved.binding).frame(
        np.repeat(np.eye(4)[None], len(saved.rig), axis=0), mode="linear")
    rest_count = int(np.count_nonzero(rest.bone.array))
    assert rest_count > 0.95 * np.count_nonzero(scans.mask(vol).array)
    counts = [_active_voxels(f, "bone") for f in files]
    assert counts[0] == rest_count  # frame 1 is the rest pose
    for c in counts:
        assert abs(c - rest_count) <= 0.01 * rest_count
    grids = {g["name"] for g in volrig._volrig.vdb_grids(files[1])}
    assert grids == {"density", "bone"}  # per-part looks off (the default): no part grids (test_looks.py)
    # frame 2 differs from the rest where the forearm moved
    f2 = volrig.load(files[1], grid="bone")
    assert f2.array.shape != rest.bone.array.shape or not np.array_equal(f2.array, rest.bone.array)
    # the Volume object plays the files: sequence over the scene range, file number = scene frame
    data = vol.data
    assert data.is_sequence and data.frame_start == 1 and data.frame_duration == 3
    assert bpy.path.abspath(data.filepath) == files[0]
    for f in (1, 2, 3):
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        ev = vol.evaluated_get(dg).data
        ev.grids.load()
        assert ev.grids.frame == f and os.path.samefile(ev.grids.frame_filepath, files[f - 1])
    # nothing changed: a second bake writes nothing; a new pose re-bakes that frame only
    baker = bake.Baker(vol, "linear")
    assert [baker.bake_frame(scene, f) for f in (1, 2, 3)] == [False, False, False]
    _pose_forearm(_members(vol)["RIG"], {3: -0.5})
    baker = bake.Baker(vol, "linear")
    assert [baker.bake_frame(scene, f) for f in (1, 2, 3)] == [False, False, True]
    baker.finish()
    # the volume's Lattice Tables setting: a bake builds none unless asked, then at once when it is long enough
    assert baker.folder.deformer.lattice_after == -1
    vol.volrig.lattice_tables = True
    try:
        assert bake.Baker(vol, "linear", frames=100).folder.deformer.lattice_after == 0
        assert bake.Baker(vol, "linear", frames=3).folder.deformer.lattice_after == -1
    finally:
        vol.volrig.lattice_tables = False


def test_a_frame_stops_inside_its_computation(posed):
    # What Esc does to the interactive bake: the frame computes on a worker thread (FrameWork) and its progress
    # callback, called many times within the frame, returns False; the frame stops there and writes nothing.
    from volrig_addon import bake
    from volrig_addon.bake import FrameWork
    vol = posed
    scene = bpy.context.scene
    baker = bake.Baker(vol, "linear")
    matrices = baker.pose(scene, 2, force=True)
    seen = []
    baker.compute(2, matrices, progress=lambda f: seen.append(f) or True)
    baker.finish()
    assert len(seen) >= 5 and seen[-1] == pytest.approx(1.0)  # reports all through the frame
    path = bake.frame_path(vol, 2)
    os.remove(path)
    stopped = []

    def stop_midway(f):
        stopped.append(f)
        return len(stopped) < 3
    with pytest.raises(volrig.Cancelled):
        baker.compute(2, matrices, progress=stop_midway)
    baker.finish()
    assert len(stopped) == 3 and stopped[-1] < 1.0 and not os.path.exists(path)
    # the worker-thread path the modal operator uses: the frame computed while this thread waits
    work = FrameWork(baker, 2, matrices)
    work.result()
    baker.finish()
    assert work.done() and work.fraction == pytest.approx(1.0) and os.path.exists(path)
    work = FrameWork(baker, 3, baker.pose(scene, 3, force=True))
    work.stop()
    if work._error is not None:  # stopped inside the frame (it may also have finished first)
        assert isinstance(work._error, volrig.Cancelled)
    baker.finish()


def test_keep_volume_goes_to_the_bake_and_off_rebakes(posed):
    """*Keep Volume at Bends* (on by default) is the bake's; turned off, every baked frame is out of date and the
    frame is the plain blend's."""
    from volrig_addon import bake
    vol = posed
    scene = bpy.context.scene
    assert vol.volrig.keep_volume
    baker = bake.Baker(vol, "linear")
    assert baker.folder.keep_volume
    baker.bake_frame(scene, 3, force=True)
    baker.finish()
    assert not bake.Baker(vol, "linear").bake_frame(scene, 3)
    vol.volrig.keep_volume = False
    try:
        baker = bake.Baker(vol, "linear")
        assert not baker.folder.keep_volume
        assert baker.bake_frame(scene, 3)
        baker.finish()
    finally:
        vol.volrig.keep_volume = True


def test_painted_weights_change_the_bake(posed):
    """Moving the forearm's spheres to the upper arm's group (weight painting) keeps them still when the forearm
    bends."""
    from volrig_addon import bake, objects
    vol = posed
    scene = bpy.context.scene
    spheres = _members(vol)["SPHERES"]
    baker = bake.Baker(vol, "linear")
    baker.bake_frame(scene, 3)
    baker.finish()  # the file is written while the next frame would compute
    bent = volrig.load(bake.frame_path(vol, 3), grid="bone")
    forearm = baker.names.index("forearm.L") + 1
    assert np.count_nonzero(bent.array == forearm) > 100
    groups = objects.vertex_groups(spheres)
    idx, _ = groups["forearm.L"]
    spheres.vertex_groups["forearm.L"].remove(idx.tolist())
    spheres.vertex_groups["upper_arm.L"].add(idx.tolist(), 1.0, "REPLACE")
    baker = bake.Baker(vol, "linear")
    assert baker.bake_frame(scene, 3)  # the weights changed, so the frame is out of date
    baker.finish()
    painted = volrig.load(bake.frame_path(vol, 3), grid="bone")
    assert np.count_nonzero(painted.array == forearm) == 0


def _render(scene, frame, path):
    from silhouettes import read_png
    scene.frame_set(frame)
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return read_png(path)[..., :3]


def test_render_of_baked_frames(posed, tmp_path):
    """The baked frames render in the engine this Blender can use (Cycles, or EEVEE where Cycles renders no
    grids): the figure's silhouette is the Blender 3.4 Cycles one, and the bent forearm shows."""
    from silhouettes import PASS, compare, silhouette
    from volrig_addon import engines, staging
    vol = posed
    scene = bpy.context.scene
    run_op(bpy.ops.volrig.bake)
    assert min(vol.dimensions) > 0  # bounds of the frame shown (empty ones: EEVEE culls the volume)
    staging.stage(scene, vol, resolution=(96, 128), samples=8)
    assert scene.render.engine == engines.volume_engine()
    rest = _render(scene, 1, str(tmp_path / "f1.png"))
    bent = _render(scene, 3, str(tmp_path / "f3.png"))
    covered = silhouette(rest)
    assert 0.03 < covered.mean() < 0.8  # not blank, not all figure
    assert compare("baked_frame_1", tmp_path / "f1.png") > PASS
    assert compare("baked_frame_3", tmp_path / "f3.png") > PASS
    diff = silhouette(bent) != covered
    assert diff.mean() > 0.003  # the forearm moved
    # the difference sits on the left forearm's side of the picture (the figure's left is on +x, the camera
    # looks along +y from the front, so it appears on the right half), the head and legs agree
    cols = np.nonzero(diff)[1]
    rows = np.nonzero(diff)[0]
    assert np.mean(cols > rest.shape[1] / 2) > 0.8
    assert np.mean(rows < 0.2 * rest.shape[0]) < 0.1  # (rows run top down) not the head


def test_saved_blend_bakes_headless_with_the_same_result(posed, tmp_path):
    from volrig_addon import bake
    vol = posed
    run_op(bpy.ops.volrig.bake)
    interactive = {f: volrig.load(bake.frame_path(vol, f)) for f in (1, 2, 3)}
    blend = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    for f in (1, 2, 3):
        os.remove(bake.frame_path(vol, f))
    env = _cli_env()
    out = subprocess.run(["/usr/bin/python3", "-m", "volrig", "bake", blend, "--frames", "1-3"], env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    for f in (1, 2, 3):
        again = volrig.load(bake.frame_path(vol, f))
        assert again.origin == interactive[f].origin
        np.testing.assert_array_equal(again.array, interactive[f].array)


def test_headless_bake_reports_user_errors(empty_scene, tmp_path):
    blend = str(tmp_path / "plain.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    env = _cli_env()
    run = ["/usr/bin/python3", "-m", "volrig", "bake"]
    out = subprocess.run(run + [blend], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "holds no volrig volume" in out.stderr, out.stderr[-2000:]
    out = subprocess.run(run + [str(tmp_path / "none.blend")], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "none.blend: no such file" in out.stderr
    out = subprocess.run(run + [blend, "--frames", "5-x"], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "'5-x' is not a frame" in out.stderr, out.stderr[-2000:]
    # the add-on is found as a package, not beside the volrig package: without it on PYTHONPATH and with no add-on
    # installed in Blender, a clear error; --addon names it (here the checkout's folder)
    bare = dict(os.environ, PYTHONPATH=os.path.join(REPO, "python"), BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"))
    out = subprocess.run(run + [blend], env=bare, capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "volrig add-on is not installed" in out.stderr, out.stderr[-2000:]
    out = subprocess.run(run + [blend, "--addon", os.path.join(REPO, "addon")], env=bare, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 2 and "holds no volrig volume" in out.stderr, out.stderr[-2000:]

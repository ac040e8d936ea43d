"""Fly Through, Straighten and Animate Straightening (issue 20) inside headless Blender, on a synthetic bent tube
and on the shared airway tree (skipped when ../shared/data is absent)."""
import os

import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op
from volrig_support import data_root

AIRWAY = str(data_root() / "airway" / "Patient1_bronchialTree.nii.gz")
BEND, RADIUS = 20.0, 4.0  # the tube: a 270-degree arc of radius BEND about the z axis, tube radius RADIUS (mm)


def _members(vol):
    from volrig_addon.objects import members
    return members(vol)


def _arc(n=20000):
    t = np.linspace(0, 1.5 * np.pi, n)
    return np.stack([BEND * np.cos(t), BEND * np.sin(t), 0 * t], 1)


@pytest.fixture(scope="module")
def tube_file(tmp_path_factory):
    """A 270-degree bent tube (uint8 mask, 1 mm voxels) as NRRD, and its analytic centerline."""
    from scipy.spatial import cKDTree
    c = _arc()
    lo = c.min(0) - RADIUS - 3
    dims = np.ceil((c.max(0) + RADIUS + 3 - lo)).astype(int) + 1
    z, y, x = np.meshgrid(*[lo[a] + np.arange(dims[a]) for a in (2, 1, 0)], indexing="ij")
    q = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    d, i = cKDTree(c).query(q)
    inside = (d <= RADIUS) & (i > 0) & (i < len(c) - 1)
    path = tmp_path_factory.mktemp("tube") / "tube.nrrd"
    volrig.Volume(inside.reshape(z.shape).astype(np.uint8), (1.0, 1.0, 1.0), tuple(lo)).save(str(path))
    return str(path), c


@pytest.fixture
def tube(empty_scene, tube_file):
    path, c = tube_file
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    vol.volrig.segment_by, vol.volrig.low, vol.volrig.high = "RANGE", 1, 1e9
    return vol, c


def _near(points, curve):
    from scipy.spatial import cKDTree
    return cKDTree(curve).query(points)[0]


def _camera_world(cam, scene, frame):
    scene.frame_set(frame)
    m = cam.matrix_world
    return np.array(m.translation), -np.array(m.to_3x3().col[2]), np.array(m.to_3x3().col[1])


def test_fly_through_builds_path_camera_light_and_lumen(tube):
    vol, c = tube
    scene = bpy.context.scene
    vol.volrig.frames_per_mm = 0.5
    run_op(bpy.ops.volrig.fly_through)
    parts = _members(vol)
    path, cam, light, lumen = parts["PATH"], parts["CAMERA"], parts["LIGHT"], parts["LUMEN"]
    # the curve: a 3-D Bezier spline on the centerline, in the volume's units (a child of the volume)
    assert path.type == "CURVE" and path.data.dimensions == "3D" and path.parent == vol
    spline = path.data.splines[0]
    assert spline.type == "BEZIER" and len(spline.bezier_points) > 10
    co = np.array([tuple(p.co) for p in spline.bezier_points])
    assert _near(co, c).max() < 1.0
    # the camera: the scene's, keyed over the scene's range, inside the lumen on the centerline, looking ahead
    assert cam.type == "CAMERA" and scene.camera == cam and cam.animation_data.action is not None
    length = 1.5 * np.pi * BEND
    frames = scene.frame_end - scene.frame_start + 1
    assert scene.frame_start == 1 and abs(frames - 0.5 * (length - 2 * RADIUS)) <= 3, frames
    along = []
    for f in np.linspace(scene.frame_start, scene.frame_end, 7).round().astype(int):
        p, view, up = _camera_world(cam, scene, int(f))
        mm = p / vol.volrig.unit_scale  # the volume's world is scaled by 0.001
        k = int(np.argmin(np.linalg.norm(c - mm, axis=1)))
        assert np.linalg.norm(c[k] - mm) < 1.0                    # on the centerline
        tangent = np.gradient(c, axis=0)[k]
        tangent /= np.linalg.norm(tangent)
        assert view @ tangent > 0.85                              # looking ahead (averaged over 10 mm)
        assert abs(view @ up) < 1e-4
        along.append(k)
    assert np.all(np.diff(along) > 0)  # forward, at a steady speed
    assert np.allclose(np.diff(along), np.diff(along).mean(), rtol=0.1, atol=100)
    # the headlight rides with the camera, inside the lumen
    assert light.type == "LIGHT" and light.data.type == "POINT" and light.parent == cam
    scene.frame_set(scene.frame_start + 5)
    lp = np.array(light.matrix_world.translation) / vol.volrig.unit_scale
    assert _near(lp[None], c)[0] < 0.5 * RADIUS
    assert light.data.energy > 0
    # the wall: a Volume object (child of the volume) showing a shell around the lumen; the scan in lumen view
    assert lumen.type == "VOLUME" and lumen.parent == vol
    wall = volrig.load(bpy.path.abspath(lumen.data.filepath))
    assert wall.array.max() == pytest.approx(1.0, abs=0.01)
    assert vol.volrig.preset == "LUMEN"
    assert len(lumen.data.materials) == 1
    # a saved scene renders with `blender -b file -a` as it is: Cycles with no denoiser (Debian's Blender has
    # none), or EEVEE where this Cycles renders no grids
    from volrig_addon import engines
    assert scene.render.engine == engines.volume_engine()
    assert engines.cycles_renders_grids() != (scene.render.engine != "CYCLES") and not scene.cycles.use_denoising
    # again: replaced, not duplicated
    names = {o.name for o in bpy.data.objects}
    run_op(bpy.ops.volrig.fly_through)
    assert {o.name for o in bpy.data.objects} == names


def test_fly_through_between_given_points_and_errors(tube):
    vol, c = tube
    s = vol.volrig
    s.fly_ends, s.fly_start, s.fly_end = "POINTS", tuple(c[5000]), tuple(c[15000])
    run_op(bpy.ops.volrig.fly_through)
    scene = bpy.context.scene
    cam = _members(vol)["CAMERA"]
    first, _, _ = _camera_world(cam, scene, scene.frame_start)
    last, _, _ = _camera_world(cam, scene, scene.frame_end)
    s_first = int(np.argmin(np.linalg.norm(c - first / s.unit_scale, axis=1)))
    s_last = int(np.argmin(np.linalg.norm(c - last / s.unit_scale, axis=1)))
    assert 5000 <= s_first < 5000 + 1500 and 15000 - 1500 < s_last <= 15000
    from test_addon import _Layout
    from volrig_addon import flythrough
    drawn = []
    flythrough.VOLRIG_PT_centerline.draw(type("PanelStub", (), {"layout": _Layout(drawn)})(), bpy.context)
    assert "fly_start" in drawn and "fly_end" in drawn and "volrig.fly_through" in drawn
    assert any(str(t).startswith("tube_camera: frames 1 .. ") for t in drawn)
    s.fly_start = (500.0, 0.0, 0.0)  # off the object: a report, not a traceback
    with pytest.raises(RuntimeError, match="not on the object"):
        bpy.ops.volrig.fly_through()


def test_straighten_adds_the_straight_volume_beside(tube):
    vol, c = tube
    run_op(bpy.ops.volrig.straighten)
    straight = bpy.context.active_object
    assert straight.name == "tube_straight" and straight.volrig.role == "VOLUME" and straight != vol
    s = straight.volrig
    length = 1.5 * np.pi * BEND
    assert abs(s.dims[2] * s.spacing[2] - length) < 0.05 * length  # z is arc length
    a = volrig.load(bpy.path.abspath(straight.data.filepath)).on_grid(s.origin, s.dims).array
    area = (a > 0.5).sum(axis=(1, 2))
    mid = area[len(area) // 4: -len(area) // 4]
    assert np.all(np.abs(np.sqrt(mid / np.pi) - RADIUS) < 1.0)   # the same radius all along
    from volrig_addon.staging import volume_box
    assert volume_box(straight)[0][0] > volume_box(vol)[1][0]     # beside the original, on its +x side


def test_straightening_rig_keys_a_chain_that_bakes_straight(tube):
    from volrig_addon import bake as baking
    vol, c = tube
    s = vol.volrig
    run_op(bpy.ops.volrig.skeletonize)
    s.thinness, s.straighten_bones, s.straighten_frames = 0.3, 10, 5
    run_op(bpy.ops.volrig.straightening_rig)
    scene = bpy.context.scene
    rig_obj = _members(vol)["RIG"]
    assert len(rig_obj.data.bones) == 10 and (scene.frame_start, scene.frame_end) == (1, 5)
    assert "SPHERES" in _members(vol) and vol.parent == rig_obj
    # the last frame: every joint on one straight line, the chain as long as the centerline
    scene.frame_set(5)
    heads = np.array([tuple(rig_obj.matrix_world @ pb.head) for pb in rig_obj.pose.bones]) / s.unit_scale
    tail = np.array(tuple(rig_obj.matrix_world @ rig_obj.pose.bones[-1].tail)) / s.unit_scale
    joints = np.r_[heads, tail[None]]
    axis = (joints[-1] - joints[0]) / np.linalg.norm(joints[-1] - joints[0])
    rel = joints - joints[0]
    assert np.linalg.norm(rel - (rel @ axis)[:, None] * axis, axis=1).max() < 0.01
    assert abs(np.linalg.norm(joints[-1] - joints[0]) - 1.5 * np.pi * BEND) < 0.05 * 1.5 * np.pi * BEND
    # the first frame is the rest: the joints on the arc
    scene.frame_set(1)
    rest = np.array([tuple(rig_obj.matrix_world @ pb.head) for pb in rig_obj.pose.bones]) / s.unit_scale
    assert _near(rest, c).max() < 1.0
    # Bake (the add-on's machinery) straightens the tube itself
    baking.bake(vol, scene, [5], "linear", force=True, report=lambda m: None)
    frame = volrig.load(baking.frame_path(vol, 5))
    mask = frame.like(frame.array > 0.5)
    line = volrig.centerline(mask)
    rel = line.points - joints[0]
    off = np.linalg.norm(rel - (rel @ axis)[:, None] * axis, axis=1)
    inner = off[int(RADIUS) + 1: -int(RADIUS) - 1]  # (the centerline's last radius at each end runs to the cap)
    assert inner.mean() < 0.6 and inner.max() < 1.0, (inner.mean(), inner.max())
    assert abs(line.length - 1.5 * np.pi * BEND) < 0.05 * 1.5 * np.pi * BEND


@pytest.mark.skipif(not os.path.exists(AIRWAY), reason=f"{AIRWAY} is absent (../shared/data)")
def test_airway_fly_through_renders_the_wall_from_inside(empty_scene, tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from volrig_addon import flythrough
    made = flythrough.build_from_file({"file": AIRWAY, "lo": 1, "output": str(tmp_path / "air.blend"),
                                       "frames_per_mm": 0.5, "render": str(tmp_path / "frames"), "frames": 3,
                                       "resolution": (64, 64), "samples": 4})
    assert os.path.exists(tmp_path / "air.blend") and len(made["renders"]) == 3
    # every camera position is inside the lumen, the flight longer than the trachea
    vol = bpy.data.objects["Patient1_bronchialTree"]
    mask = volrig.segment(volrig.load(AIRWAY), lo=1)
    ijk = np.round((made["flight"].positions - np.array(mask.origin)) / np.array(mask.spacing)).astype(int)
    assert mask.array[ijk[:, 2], ijk[:, 1], ijk[:, 0]].all()
    assert made["line"].length > 150
    assert vol.volrig.preset == "LUMEN"
    for path in made["renders"]:
        img = plt.imread(path)[..., :3].mean(axis=2)
        assert img.shape == (64, 64)
        # the wall fills the view, lit, not blown out; the lumen ahead is a darker hole: not a uniform image
        assert 0.1 < img.mean() < 0.8, (path, img.mean())
        assert img.std() > 0.05, (path, img.std())
        print(f"{os.path.basename(path)}: mean {img.mean():.3f}, std {img.std():.3f}")
        assert (img > 0.2).mean() > 0.5, path  # most of the view is the lit wall

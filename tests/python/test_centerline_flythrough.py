"""Fly-through helpers (volrig.centerline.flight_path, flight_frames, lumen_wall) on synthetic tubes, and
``volrig flythrough`` end to end in headless Blender (skipped when Blender is absent)."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import volrig
from volrig.centerline import flight_frames, flight_path, lumen_wall
from test_centerline import helix, segment, torus_segment, tube

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def bend():
    c = torus_segment(bend=20.0, angle=1.5 * np.pi)
    m = tube(c, 4.0)
    return c, m, volrig.centerline(m)


def test_flight_frames_move_steadily_and_look_ahead(bend):
    c, m, line = bend
    f = flight_frames(line, frames_per_mm=2.0, look_ahead=10.0)
    steps = np.linalg.norm(np.diff(f.positions, axis=0), axis=1)
    assert np.allclose(steps, 0.5, rtol=0.05)                         # 2 frames per mm
    assert np.allclose(np.diff(f.arc), 0.5)
    # starts and stops a radius inside the ends (in front of the caps)
    assert 2.5 < f.arc[0] < 5.0 and 2.5 < line.length - f.arc[-1] < 5.5
    assert abs(len(f) - 2 * (line.length - f.arc[0] - (line.length - f.arc[-1]))) <= 2
    # the view: the chord to the point 10 mm ahead, between the local tangent and the turn ahead
    t = np.gradient(c, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    k = np.argmin(np.linalg.norm(c[None] - f.positions[:, None], axis=2), axis=1)
    cos = np.einsum("ij,ij->i", f.directions, t[k])
    assert cos.min() > np.cos(np.radians(20))
    # 10 mm ahead on an arc of radius 20 the chord turns 14.3 degrees off the tangent (less where the window
    # reaches the end)
    full = f.arc + 10.0 < line.length
    assert np.abs(np.degrees(np.arccos(cos[full])) - 14.3).max() < 3.0
    assert np.allclose(np.linalg.norm(f.directions, axis=1), 1) and np.allclose(np.linalg.norm(f.ups, axis=1), 1)
    assert np.abs(np.einsum("ij,ij->i", f.directions, f.ups)).max() < 1e-9
    # no roll: along a flat arc in the xy plane the up stays +z
    assert np.allclose(f.ups, [0, 0, 1], atol=0.05)  # (the voxel centerline strays from z = 0 by a few hundredths)
    assert abs(np.median(f.radii) - 4.0) < 0.6 and f.radii.min() > 2.5
    with pytest.raises(volrig.VolrigError, match="frames per mm"):
        flight_frames(line, frames_per_mm=0)


def test_flight_up_does_not_flip_on_a_vertical_helix():
    c = helix(radius=15.0, pitch=60.0, turns=1.5)
    m = tube(c, 3.0)
    f = flight_frames(volrig.centerline(m), 1.0, 5.0)
    # the up turns smoothly (rotation-minimising): neighbouring frames' ups within a few degrees
    assert np.einsum("ij,ij->i", f.ups[1:], f.ups[:-1]).min() > np.cos(np.radians(10))


def test_flight_stops_where_the_lumen_narrows():
    c = segment([0, 0, 0], [80, 0, 0])
    r = np.where(c[:, 0] < 50, 5.0, 1.5)
    m = tube(c, r)
    line = volrig.centerline(m, start=(1, 0, 0), end=(79, 0, 0))
    f = flight_frames(line, 1.0, 10.0, min_radius=2.5)
    assert 45 < f.arc[-1] + f.positions[0][0] - f.arc[0] < 51, f.positions[-1]
    assert f.positions[-1][0] < 51


def test_flight_path_starts_at_the_thick_end():
    c = segment([0, 0, 0], [60, 0, 0])
    m = tube(c, np.linspace(6.0, 2.5, len(c)))
    line = flight_path(m)
    assert line.points[0][0] < 5 and line.points[-1][0] > 55
    back = flight_path(m, end=(1.0, 0.0, 0.0))  # only the end given: from the far end to it
    assert back.points[0][0] > 55 and back.points[-1][0] < 5


def test_lumen_wall_is_a_shell(bend):
    c, m, line = bend
    w = lumen_wall(m, thickness=3.0)
    assert w.array.dtype == np.float32 and 0 <= w.array.min() and w.array.max() <= 1.0
    # on the centerline: clear; 5.5 mm from it (1.5 outside the lumen): wall; 9 mm (5 outside): nothing
    sp, org = np.array(w.spacing), np.array(w.origin)

    def at(p):
        i = np.round((np.asarray(p) - org) / sp).astype(int)
        return w.array[i[2], i[1], i[0]]

    p = line.points[len(line) // 2]
    out = np.array([p[0], p[1], 0.0]) / np.linalg.norm(p[:2])
    assert at(p) == 0.0 and at(p + 5.5 * out) > 0.9 and at(p + 9.0 * out) == 0.0
    assert np.count_nonzero(w.array) < 4 * np.count_nonzero(m.array)  # a shell 3 voxels thick around r = 4


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender is not installed")
def test_cli_flythrough_saves_a_blend(tmp_path, bend):
    c, m, line = bend
    src = tmp_path / "tube.nrrd"
    volrig.Volume(m.array.astype(np.uint8), m.spacing, m.origin).save(str(src))
    out = tmp_path / "out" / "cam.blend"
    env = dict(os.environ, PYTHONPATH=os.path.join(REPO, "python"))
    run = [sys.executable, "-m", "volrig", "flythrough", str(src), "--lo", "1", "--frames-per-mm", "0.5",
           "--addon", os.path.join(REPO, "addon")]
    r = subprocess.run(run + ["-o", str(out)], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert out.exists() and (tmp_path / "out" / "cam_volrig").is_dir()
    assert "fly-through of" in r.stdout and not (tmp_path / "out" / "cam.blend1").exists()
    # user mistakes: exit 2 with a message, no traceback
    r = subprocess.run(run + ["--start", "500", "0", "0", "--end", "0", "20", "0", "-o", str(tmp_path / "x.blend")],
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "not on the object" in r.stderr, r.stderr[-2000:]
    r = subprocess.run(run + ["--start", "1", "2", "3", "-o", str(tmp_path / "x.blend")], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "--start and --end go together" in r.stderr

"""Import Tracked Series (issue 57): a time series' features tracked, played as a volume sequence coloured by track
(a colour per track that it keeps), the events as timeline markers; a folder without steps is reported."""
import os

import numpy as np
import pytest

from conftest import run_op

bpy = pytest.importorskip("bpy")


def ball(shape, centre, r):
    z, y, x = np.indices(shape)
    return (x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2 <= r * r


@pytest.fixture
def series_folder(tmp_path):
    """Three steps as VDB files (each cropped to its active voxels): B splits into a big and a small blob, A drifts,
    then A dissipates and C appears."""
    import volrig
    shape = (24, 24, 64)
    a = [ball(shape, (8 + t, 12, 12), 5) for t in range(2)]
    big = [ball(shape, (x, 12, 12), 7) for x in (38, 36, 37)]
    small = [ball(shape, (x, 12, 12), 5) for x in (47, 52, 51)]
    steps = [a[0] | big[0] | small[0], a[1] | big[1] | small[1], big[2] | small[2] | ball(shape, (21, 12, 12), 4)]
    folder = tmp_path / "sim"
    folder.mkdir()
    for i, s in enumerate(steps):
        volrig.write_vdb(str(folder / f"sim_{i:03d}.vdb"), {"density": s.astype(np.float32)})
    return folder


def test_a_tracked_series_plays_coloured_by_track_with_event_markers(empty_scene, series_folder):
    import volrig
    from volrig_addon import scans, track
    run_op(bpy.ops.volrig.import_tracks, filepath=str(series_folder / "sim_001.vdb"), lo=0.5, size=3.0)
    vol = bpy.context.active_object
    assert vol.type == "VOLUME" and vol.name.startswith("sim")
    data = vol.data
    assert data.is_sequence and data.frame_duration == 3 and data.frame_start == 1
    scene = bpy.context.scene
    assert (scene.frame_start, scene.frame_end) == (1, 3)
    marks = sorted((m.frame, m.name) for m in scene.timeline_markers)
    assert marks == [(2, "split [1]->[1, 3]"), (3, "creation []->[3]"), (3, "dissipation [2]->[]")]
    # each step's file: the track colour numbers, B's id (1) kept by its big branch, the small one new (3)
    cache = scans.cache_dir(vol)
    frames = [volrig.load(os.path.join(cache, f"tracks_{f:04d}.vdb")) for f in (1, 2, 3)]
    assert [sorted(np.unique(f.array).tolist()) for f in frames] == [[0, 1, 2], [0, 1, 2, 3], [0, 1, 3, 4]]
    # the label look through the object's own palette of track colours, distinct colours for numbers 1..4
    ramp = data.materials[0].node_tree.nodes["volrig ramp"].color_ramp
    colours = np.array([e.color[:3] for e in ramp.elements[1:5]])
    assert np.allclose(colours, track.track_palette()[:4], atol=1e-4)
    assert min(np.abs(colours[i] - colours[j]).max() for i in range(4) for j in range(i)) > 0.1
    assert os.path.isfile(os.path.join(cache, "tracks.json"))
    # the longest side is 3 Blender units (to a voxel: Blender 5.x's bounds take in one more)
    bpy.context.view_layer.update()
    corners = np.array([vol.matrix_world @ __import__("mathutils").Vector(c) for c in vol.bound_box])
    assert np.ptp(corners, axis=0).max() == pytest.approx(3.0, rel=0.05)


def test_a_folder_without_steps_is_reported(empty_scene, tmp_path):
    (tmp_path / "notes.txt").write_text("no volumes here")
    n = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match="no volume files"):
        bpy.ops.volrig.import_tracks(filepath=str(tmp_path / "notes.txt"))
    assert len(bpy.data.objects) == n

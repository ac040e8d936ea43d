"""Feature tracking (thesis 9.1): features numbered as scipy.ndimage.label numbers them; events and track ids of a
synthetic series whose history is known, at thinness 0 (whole features) and from skeletons; exact overlaps at
thinness 0 against numpy; re-tracking without skeletonizing; the shared viscous-fingering run against full-volume
tracking; the CLI's JSON and VDB output; bad input; the native step_overlaps against a numpy brute force on random
steps (every label type, both directions) and the points taken at a thinness against their definition."""
import glob
import importlib
import json
import os

import numpy as np
import pytest

import volrig
trackmod = importlib.import_module("volrig.track")  # the module (volrig.track is the function)
from volrig.track import track

FINGERS = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "timevarying",
                       "viscous_fingers_run01")


def ball(shape, centre, r):
    z, y, x = np.indices(shape)
    return (x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2 <= r * r


def series():
    """Four steps of 24 x 24 x 64: feature B (two overlapping balls) splits into a big and a small blob which merge
    again; A drifts and dissipates; C is created in the last step, where A never was."""
    shape = (24, 24, 64)
    a = [ball(shape, (8 + t, 12, 12), 5) for t in range(3)]
    big = [ball(shape, (x, 12, 12), 7) for x in (38, 36, 37, 38)]
    small = [ball(shape, (x, 12, 12), 5) for x in (47, 52, 51, 47)]  # apart at steps 1 and 2
    c3 = ball(shape, (21, 12, 12), 4)
    steps = [a[0] | big[0] | small[0], a[1] | big[1] | small[1], a[2] | big[2] | small[2], big[3] | small[3] | c3]
    return [s.astype(np.float32) * 10 for s in steps]


def test_features_are_numbered_as_scipy_numbers_6_connected_components():
    ndimage = pytest.importorskip("scipy.ndimage")
    rng = np.random.default_rng(5)
    for _ in range(6):
        v = rng.random((15, 17, 19)).astype(np.float32)
        tr = track([v, v], lo=0.7, min_size=3, thinness=0)
        ref, n = ndimage.label(v >= 0.7)
        sizes = np.bincount(ref.ravel())[1:]
        keep = np.flatnonzero(sizes >= 3) + 1
        want = np.zeros_like(ref)
        for k, lab in enumerate(keep):
            want[ref == lab] = k + 1
        assert np.array_equal(tr.labels[0], want)
        assert np.array_equal(tr.volumes[0], sizes[keep - 1])
        centre = np.array(ndimage.center_of_mass(want > 0, want, range(1, len(keep) + 1)))[:, ::-1]
        assert np.allclose(tr.centroids[0], centre)


@pytest.mark.parametrize("thinness", [0.0, 1.0, 2.0])
def test_events_and_track_ids_of_a_known_history(thinness):
    tr = track(series(), lo=5, thinness=thinness)
    ev = [(e.step, e.kind, e.before, e.after) for e in tr.events]
    # features are numbered by first voxel (lowest z first): B (or its big branch) 1, A 2, the small branch 3, C 2
    assert ev == [(0, "split", (1,), (1, 3)), (0, "continuation", (2,), (2,)),
                  (1, "continuation", (1,), (1,)), (1, "continuation", (2,), (2,)), (1, "continuation", (3,), (3,)),
                  (2, "merge", (1, 3), (1,)), (2, "dissipation", (2,), ()), (2, "creation", (), (2,))]
    # B's id persists through the split's larger branch and the merge; the small branch and C get new ids
    assert [list(t) for t in tr.track_ids] == [[1, 2], [1, 2, 3], [1, 2, 3], [1, 4]]
    assert tr.event_counts()["split"] == 1 and tr.event_counts()["merge"] == 1
    vol = tr.track_volume(1)
    assert set(np.unique(vol)) == {0, 1, 2, 3} and np.array_equal(vol > 0, tr.labels[1] > 0)


def test_thinness_0_overlaps_are_the_exact_intersections():
    steps = series()
    tr = track(steps, lo=5, thinness=0)
    for s, a, b, overlap in tr.edges:
        assert overlap == np.count_nonzero((tr.labels[s] == a) & (tr.labels[s + 1] == b))
    # and every pair that overlaps at all by a tenth of the smaller feature is an edge
    for s in range(tr.steps - 1):
        la, lb = tr.labels[s].ravel(), tr.labels[s + 1].ravel()
        both = (la > 0) & (lb > 0)
        pairs, counts = np.unique(np.stack([la[both], lb[both]]), axis=1, return_counts=True)
        want = {(int(a), int(b)) for (a, b), c in zip(pairs.T, counts)
                if c >= 0.1 * min(tr.volumes[s][a - 1], tr.volumes[s + 1][b - 1])}
        assert {(a, b) for t, a, b, _ in tr.edges if t == s} == want


def test_retracking_at_another_thinness_does_not_skeletonize_again(monkeypatch):
    tr = track(series(), lo=5, thinness=1.0)
    calls = []
    monkeypatch.setattr(trackmod, "skeletonize", lambda *a, **k: calls.append(1))
    thin = tr.at(3.0)
    assert calls == [] and thin.thinness == 3.0
    ijk, radii = thin.skeleton_points(0, 1)
    ijk1, _ = tr.skeleton_points(0, 1)
    assert 0 < len(ijk) < len(ijk1)  # a thinner skeleton of the same feature
    assert np.all(tr.labels[0][tuple(ijk.T)] == 1) and np.all(radii > 0)
    assert thin.agreement(tr.at(0)) == {"matches": 1.0, "events": 1.0}


@pytest.mark.skipif(not os.path.isdir(FINGERS), reason="../shared/data/timevarying is absent (the shared data)")
def test_viscous_fingers_match_full_volume_tracking_from_a_thin_skeleton():
    steps = [volrig.load(f).array[:52] for f in sorted(glob.glob(os.path.join(FINGERS, "*.vti")))]
    full = track(steps, lo=30, thinness=0)
    assert len(full.events) > 50 and full.event_counts()["split"] >= 5  # a history worth tracking
    points = sum(len(s.voxels) for s in full._steps)
    for tp, least in ((1.0, 1.0), (2.0, 0.9)):
        tr = full.at(tp)
        agree = tr.agreement(full)
        assert agree["matches"] >= least and agree["events"] >= least, (tp, agree)
        used = sum(trackmod._count_above(s.scores, tp) for s in full._steps)
        assert used < points * (0.35 if tp == 1.0 else 0.05)


def test_cli_writes_the_graph_and_a_track_grid_a_step(tmp_path, capsys):
    from volrig.cli import main
    folder = tmp_path / "steps"
    folder.mkdir()
    from test_io_vti import vti_bytes  # the time series as VTK image data, as simulations write them
    for i, s in enumerate(series()):
        (folder / f"step_{i:02d}.vti").write_bytes(vti_bytes(s, zlib_blocks=4096))
    (folder / "notes.txt").write_text("not a step")
    out = tmp_path / "tracks.json"
    assert main(["track", str(folder), "--lo", "5", "-o", str(out), "--vdb", str(tmp_path / "vdb")]) == 0
    text = capsys.readouterr().out
    assert "4 steps, 10 features, 4 tracks" in text and "split [1] -> [1, 3]" in text
    graph = json.loads(out.read_text())
    assert [e["kind"] for e in graph["events"]].count("merge") == 1
    assert {"step": 0, "feature": 1, "next_feature": 3} == {k: graph["edges"][1][k] for k in
                                                            ("step", "feature", "next_feature")}
    grid = volrig.load(str(tmp_path / "vdb" / "track_0003.vdb"), grid="track")
    assert set(np.unique(grid.array)) == {0, 1, 4}


def test_vdb_steps_cropped_to_their_own_boxes_share_the_box_around_them(tmp_path):
    steps = series()
    for i, s in enumerate(steps):
        volrig.write_vdb(str(tmp_path / f"s{i}.vdb"), {"density": volrig.Volume(s, (0.5, 0.5, 0.5), (1, 2, 3))})
    boxes = {volrig.load(str(tmp_path / f"s{i}.vdb")).dims for i in range(len(steps))}
    assert len(boxes) > 1  # each file holds its active voxels only
    tr = track(str(tmp_path), lo=5, thinness=0)
    ref = track(steps, lo=5, thinness=0)
    assert tr.edges == ref.edges and tr.events == ref.events
    assert np.allclose(np.concatenate(tr.centroids), np.concatenate(ref.centroids) * 0.5 + (1, 2, 3))


def test_bad_input_is_refused_clearly(tmp_path):
    v = series()[0]
    with pytest.raises(volrig.VolrigError, match="at least two time steps"):
        track([v], lo=5)
    with pytest.raises(volrig.VolrigError, match="share one grid"):
        track([v, v[:, :, :32]], lo=5)
    with pytest.raises(volrig.VolrigError, match="thinness"):
        track([v, v], lo=5, thinness=float("nan"))
    with pytest.raises(volrig.VolrigError, match="hi >= lo"):
        track([v, v], lo=5, hi=1)
    with pytest.raises(volrig.VolrigError, match="no volume files"):
        track(str(tmp_path), lo=5)
    with pytest.raises(volrig.Cancelled):
        track([v, v, v], lo=5, progress=lambda f: f < 0.5)
    nan = v.copy()
    nan[0] = np.nan  # NaN is no feature
    assert track([nan, v], lo=5, thinness=0).volumes[0].sum() == (v[1:] >= 5).sum()


def _brute_overlaps(a, b, both):
    """The overlaps step_overlaps should give, by numpy: each direction's weights summed per pair in point order,
    scaled by the feature's size over its points' total, the larger of the two directions kept."""
    out = {}
    for (look, count, index, label, weight, sizes, totals), other, swap in ((a, b, False), (b, a, True))[:1 + both]:
        hit = other[0].reshape(-1)[index.astype(np.int64)]
        sums = np.zeros((count + 1, other[1] + 1))
        np.add.at(sums, (label.astype(np.int64), hit.astype(np.int64)),
                  np.ones(len(index)) if weight is None else weight.astype(np.float64))
        for x, y in zip(*np.nonzero(sums[:, 1:])):
            w = sums[x, y + 1] if weight is None else sums[x, y + 1] * sizes[x - 1] / totals[x]
            pair = (int(y + 1), int(x)) if swap else (int(x), int(y + 1))
            out[pair] = max(out.get(pair, 0.0), w)
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32])
def test_step_overlaps_equal_a_brute_force_on_random_steps(dtype):
    rng = np.random.default_rng(int(np.dtype(dtype).itemsize))
    for trial in range(8):
        shape = tuple(int(n) for n in rng.integers(4, 12, 3))
        steps = []
        for _ in range(2):
            labels, sizes, _ = volrig._volrig.track_features((rng.random(shape) < 0.4).view(np.uint8), 1)
            steps.append((labels.astype(dtype), sizes))
        sides = []
        for labels, sizes in steps:
            index = np.flatnonzero(labels).astype(np.uint32 if trial % 2 else np.int64)
            index = index[rng.random(len(index)) < (1.0 if trial < 2 else 0.4)]
            label = labels.reshape(-1)[index]
            weight = rng.uniform(0.1, 5, len(index)).astype(np.float32)
            totals = np.bincount(label, weights=weight, minlength=len(sizes) + 1)
            sides.append([labels, len(sizes), index, label, weight, sizes, totals])
        if trial < 2:  # every voxel a point of weight 1: one direction, the exact intersections
            for s in sides:
                s[4:] = [None, None, None]
        for both in ([False] if trial < 2 else [False, True]):
            fa, fb, w = volrig._volrig.step_overlaps(tuple(sides[0]), tuple(sides[1]), both)
            want = _brute_overlaps(sides[0], sides[1], both)
            assert list(zip(fa.tolist(), fb.tolist())) == sorted(want)  # sorted by pair, each once
            assert np.allclose(w, [want[p] for p in sorted(want)], rtol=1e-12, atol=0)
            if trial < 2:  # integer counts: |A ∩ B|
                la, lb = sides[0][0].astype(np.int64), sides[1][0].astype(np.int64)
                assert all(v == np.count_nonzero((la == x) & (lb == y)) for x, y, v in zip(fa, fb, w))


def test_points_at_a_thinness_are_the_skeleton_in_index_order():
    tr = track(series(), lo=5, thinness=1.0)
    for s in tr._steps:
        for tp in (0.5, 1.0, 3.0, 50.0):
            look, count, index, label, weight, sizes, totals = trackmod._points_at(s, tp)
            # the voxels scoring above the thinness, and each feature's best-scoring voxel whatever its score
            best = {}
            for i, f in enumerate(s.point_label):
                best.setdefault(int(f), i)
            keep = set(np.flatnonzero(s.scores > np.float32(tp)).tolist()) | set(best.values())
            want = np.sort(s.points[sorted(keep)])
            assert np.array_equal(index.astype(np.int64), want) and count == len(s.sizes)
            assert np.array_equal(label, s.labels.reshape(-1)[want]) and look.dtype == np.uint8
            assert np.allclose(weight, (s.dt[[int(np.flatnonzero(s.points == v)[0]) for v in want]]) ** 3)
            assert np.allclose(totals[1:], [weight[label == f].sum() for f in range(1, count + 1)])


def test_run_overlaps_are_the_exact_intersections_of_random_steps():
    rng = np.random.default_rng(7)
    for trial in range(10):
        shape = tuple(int(n) for n in rng.integers(3, 14, 3))
        labels = [volrig._volrig.track_features((rng.random(shape) < p).view(np.uint8), 1)[0]
                  for p in (0.3 + 0.05 * trial, 0.6 - 0.04 * trial)]
        runs = [trackmod._runs(lab) for lab in labels]
        for lab, r in zip(labels, runs):  # the runs cover every feature voxel once, with its label
            again = np.zeros(lab.size, np.int32).reshape(-1, shape[2])
            for row, x0, x1, f in r.T:
                assert x1 > x0 and not again[row, x0:x1].any()
                again[row, x0:x1] = f
            assert np.array_equal(again.reshape(shape), lab)
        counts = [int(lab.max()) for lab in labels]
        fa, fb, w = volrig._volrig.run_overlaps(runs[0], counts[0], runs[1], counts[1])
        la, lb = labels[0].ravel(), labels[1].ravel()
        both = (la > 0) & (lb > 0)
        pairs, n = np.unique(np.stack([la[both], lb[both]]), axis=1, return_counts=True)
        assert [(int(x), int(y), float(c)) for (x, y), c in zip(pairs.T, n)] == list(zip(fa.tolist(), fb.tolist(),
                                                                                          w.tolist()))
    with pytest.raises(volrig.VolrigError, match="no feature of its step"):
        volrig._volrig.run_overlaps(runs[0], counts[0] - 1, runs[1], counts[1])
    with pytest.raises(volrig.VolrigError, match="int32 array"):
        volrig._volrig.run_overlaps(runs[0].T.copy(), counts[0], runs[1], counts[1])


@pytest.mark.parametrize("thinness", [0, 1.0, 3.0])
def test_a_step_without_features_is_tracked_at_any_thinness(thinness):
    none = np.zeros((10, 10, 10), np.float32)
    cube = none.copy()
    cube[2:6, 2:6, 2:6] = 1
    tr = track([none, cube, none, cube], lo=0.5, thinness=thinness, min_size=1)
    assert [(e.step, e.kind) for e in tr.events] == [(0, "creation"), (1, "dissipation"), (2, "creation")]
    assert tr.edges == [] and [len(v) for v in tr.volumes] == [0, 1, 0, 1]


def test_step_overlaps_refuse_bad_points():
    a = np.zeros((2, 2, 2), np.uint8)
    a[0, 0, 0] = 1
    side = (a, 1, np.array([0], np.uint32), np.array([1], np.uint8), None, None, None)
    assert [x.tolist() for x in volrig._volrig.step_overlaps(side, side, False)] == [[1], [1], [1.0]]
    with pytest.raises(volrig.VolrigError, match="off the grid"):
        volrig._volrig.step_overlaps((a, 1, np.array([8], np.uint32)) + side[3:], side, False)
    with pytest.raises(volrig.VolrigError, match="no feature"):
        volrig._volrig.step_overlaps(side[:3] + (np.array([2], np.uint8),) + side[4:], side, False)
    with pytest.raises(volrig.VolrigError, match="above the other step's feature count"):
        volrig._volrig.step_overlaps(side, (a, 0) + side[2:], False)
    with pytest.raises(volrig.VolrigError, match="differ in type"):
        volrig._volrig.step_overlaps(side, (a.astype(np.uint16),) + side[1:], False)
    with pytest.raises(volrig.VolrigError, match="sizes and totals"):
        volrig._volrig.step_overlaps(side[:4] + (np.ones(1, np.float32), None, None), side, True)

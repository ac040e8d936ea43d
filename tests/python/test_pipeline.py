"""volrig.pipeline without Blender: the import heuristics, segmentation, frame ranges, the rig step and baking to a
folder, as the command line and the add-on both use them."""
import json
import os

import numpy as np
import pytest

import volrig
from volrig import pipeline
from volrig.pipeline import Segmentation

from conftest import shared


# ---- errors -----------------------------------------------------------------------------------------------------

def test_volrig_errors_share_one_base():
    assert issubclass(volrig.FileFormatError, volrig.VolrigError)
    assert issubclass(volrig.Cancelled, volrig.VolrigError)
    assert issubclass(volrig.VolrigError, ValueError)  # so `except ValueError` callers keep working
    # Python-side checks raise it too, and so do the core's (through the bindings)
    with pytest.raises(volrig.VolrigError, match="lo .* is above hi"):
        volrig.segment(volrig.Volume(np.zeros((2, 2, 2))), lo=3, hi=1)
    with pytest.raises(volrig.VolrigError, match="unknown volume format"):
        volrig.load("scan.xyz")
    with pytest.raises(volrig.VolrigError, match="unknown deform mode 'bendy'"):
        _tiny_bake_inputs()[3].frame(volrig.rest_pose(2), mode="bendy")


# ---- import heuristics ------------------------------------------------------------------------------------------

def test_label_maps_are_told_from_intensities():
    rng = np.random.default_rng(1)
    labels = rng.integers(0, 7, size=(40, 30, 20)).astype(np.uint8)  # 0..6: organ labels
    assert pipeline.looks_like_labels(labels)
    assert pipeline.looks_like_labels(labels.astype(np.float32))  # labels stored as floats are still labels
    ct = rng.normal(40, 300, size=(40, 30, 20)).round().astype(np.int16)  # Hounsfield units, negative
    assert not pipeline.looks_like_labels(ct)
    smooth = rng.random((40, 30, 20)).astype(np.float32) * 5  # fractional intensities
    assert not pipeline.looks_like_labels(smooth)
    levels = np.zeros((40, 30, 20), np.uint8)
    levels[10:30, 5:25, 5:15] = 100
    levels[15:25, 10:20, 8:12] = 220  # the phantom's flesh and bone levels: 3 values up to 220, not labels
    assert not pipeline.looks_like_labels(levels)
    binary = (levels > 0).astype(np.uint8)  # a mask (0/1) is no label map either: its largest value is 1
    assert not pipeline.looks_like_labels(binary)
    assert not pipeline.looks_like_labels(np.zeros((0, 3, 3)))
    with_nan = labels.astype(np.float32)
    with_nan[0, 0, 0] = np.nan
    assert pipeline.looks_like_labels(with_nan)


def test_label_maps_hold_few_values_for_their_largest():
    # labels are about numbered from 1 up: 0, 1, 2, 3, 30 (5 values, the largest above 2 * 5 + 8) are refused,
    # 0, 1, 3, 5, 9 (gaps, the largest within 2 * 5 + 8) pass
    a = np.zeros((10, 10, 10), np.uint8)
    for k, value in enumerate((1, 2, 3, 30)):
        a[k] = value
    assert not pipeline.looks_like_labels(a)
    for k, value in enumerate((1, 3, 5, 9)):
        a[k] = value
    assert pipeline.looks_like_labels(a)


def test_import_defaults():
    a = np.zeros((20, 10, 10), np.float32)
    a[5:15] = np.linspace(1, 100, 10 * 10 * 10).reshape(10, 10, 10)
    v = volrig.Volume(a, spacing=(0.5, 0.5, 2.0))
    d = pipeline.import_defaults(v, unit_scale=0.001)
    assert (d.value_min, d.value_max, d.high) == (0.0, 100.0, 100.0)
    assert d.low == pytest.approx(np.percentile(a[a != 0], 5))
    assert not d.label_map and d.labels == "" and d.sampling == "trilinear"
    # the largest extent is z: 20 voxels x 2 mm = 40 mm = 0.04 scene units -> density 40 / 0.04
    assert d.density_scale == pytest.approx(1000.0)
    labels = volrig.Volume(np.arange(6, dtype=np.uint8).repeat(200).reshape(12, 10, 10))
    d = pipeline.import_defaults(labels)
    assert d.label_map and d.labels == "1-5" and d.sampling == "nearest" and d.low == 1.0


def test_import_defaults_of_real_scans():
    frog = volrig.load(str(shared("frogtissue/frogtissue.mhd")))
    d = pipeline.import_defaults(frog, 0.001)
    assert d.label_map and d.labels == f"1-{int(frog.array.max())}" and d.sampling == "nearest"
    tooth = volrig.load(str(shared("tooth/tooth.nrrd")))
    d = pipeline.import_defaults(tooth, 0.001)
    assert not d.label_map and d.sampling == "trilinear"
    assert d.low == pytest.approx(np.percentile(tooth.array[tooth.array != 0], 5))


def test_float_samples_zero_the_non_finite():
    a = np.array([[[1, np.nan], [np.inf, -2]]], np.float64)
    out = pipeline.float_samples(volrig.Volume(a, spacing=(2, 3, 4), origin=(1, 1, 1)))
    assert out.array.dtype == np.float32 and out.array.tolist() == [[[1, 0], [0, -2]]]
    assert out.spacing == (2, 3, 4) and out.origin == (1, 1, 1)


def test_load_source_raw_hints(tmp_path):
    a = np.arange(4 * 3 * 2, dtype=np.int16).reshape(2, 3, 4)
    raw = tmp_path / "x.raw"
    raw.write_bytes(b"\0" * 8 + a.astype(">i2").tobytes())
    v = pipeline.load_source(str(raw), dims=(4, 3, 2), dtype="int16", big_endian=True, offset=8, spacing=(1, 2, 3))
    np.testing.assert_array_equal(v.array, a)
    assert v.spacing == (1, 2, 3)
    with pytest.raises(volrig.VolrigError, match="x.raw: a raw file needs its size"):
        pipeline.load_source(str(raw))
    with pytest.raises(volrig.VolrigError, match="element type"):
        pipeline.load_source(str(raw), dims=(4, 3, 2))


# ---- segmentation -----------------------------------------------------------------------------------------------

def test_parse_labels():
    assert pipeline.parse_labels("1 4 7-9") == [1, 4, 7, 8, 9]
    assert pipeline.parse_labels("2,3;5") == [2, 3, 5]
    for text, words in (("eighty", "'eighty' is not a number"), ("9-7", "bad range"), ("  ", "none given")):
        with pytest.raises(volrig.VolrigError, match=words):
            pipeline.parse_labels(text)


def test_segmentation_mask_and_live_count_agree():
    rng = np.random.default_rng(3)
    a = rng.integers(0, 6, size=(20, 16, 12)).astype(np.uint8)
    v = volrig.Volume(a)
    for seg in (Segmentation(lo=2), Segmentation(lo=1, hi=3), Segmentation.of_labels("1 4-5"),
                Segmentation(lo=2, labels=(1, 2, 5)), Segmentation()):
        mask = seg.mask(v)
        assert seg.count(a) == int(np.count_nonzero(mask.array)), seg
    assert Segmentation.of_labels("4 5").count(a) == int(np.count_nonzero(np.isin(a, [4, 5])))
    # largest keeps one 26-connected part: fewer voxels than the count, which ignores it
    two = np.zeros((10, 10, 10), np.uint8)
    two[1:3, 1:3, 1:3] = 1
    two[6:9, 6:9, 6:9] = 1
    seg = Segmentation(lo=1, largest=True)
    assert seg.count(two) == 8 + 27 and int(seg.mask(volrig.Volume(two)).array.sum()) == 27
    assert hash(seg) == hash(Segmentation(lo=1.0, largest=True))  # a cache key
    with pytest.raises(volrig.VolrigError, match="segmentation is empty"):
        Segmentation(lo=250).mask(v, name="scan")
    with pytest.raises(volrig.VolrigError, match=r"lo \(5\) is above hi \(2\)"):
        Segmentation(lo=5, hi=2)


def test_load_mask_of_a_mesh(tmp_path):
    with pytest.raises(FileNotFoundError, match="arm.obj"):
        pipeline.load_mask(str(tmp_path / "arm.obj"), Segmentation())
    arm = shared("meshes/arm.obj")
    mask = pipeline.load_mask(str(arm), Segmentation(), voxel_size=0.01)
    v, f = volrig.read_mesh(str(arm))
    np.testing.assert_array_equal(mask.array, volrig.voxelize(v, f, 0.01).array)
    with pytest.raises(volrig.VolrigError, match="positive"):
        pipeline.load_mask(str(arm), Segmentation(), voxel_size=0)
    # no voxel size: the longest side / 160, as rig_mesh and the add-on
    size = float((v.max(0) - v.min(0)).max()) / 160
    mask = pipeline.load_mask(str(arm), Segmentation())
    assert mask.spacing == pytest.approx((size,) * 3) and max(mask.array.shape) in range(160, 170)
    np.testing.assert_array_equal(mask.array, volrig.voxelize(v, f, size).array)


# ---- skeleton ---------------------------------------------------------------------------------------------------

def test_thinness_in_voxels():
    assert pipeline.thinness_from_voxels(0.5, "euclidean", (0.8, 0.4, 2.0)) == pytest.approx(0.2)
    assert pipeline.thinness_from_voxels(0.5, "chamfer345", (0.8, 0.4, 2.0)) == 0.5
    for metric in ("euclidean", "chamfer345"):
        tp = pipeline.thinness_from_voxels(0.37, metric, (0.3, 0.5, 0.7))
        assert pipeline.voxels_from_thinness(tp, metric, (0.3, 0.5, 0.7)) == pytest.approx(0.37)


def test_skeleton_points_take_a_thinness_or_a_count():
    mask = volrig.segment(volrig.phantom.humanoid(0.2).volume)
    sk = pipeline.skeleton_of(mask)
    np.testing.assert_array_equal(pipeline.skeleton_points(sk, thinness=0.4).ijk, sk.at(0.4).ijk)
    assert len(pipeline.skeleton_points(sk, count=300)) == 300
    for kw in ({}, {"thinness": 0.4, "count": 3}):
        with pytest.raises(volrig.VolrigError, match="one of the two"):
            pipeline.skeleton_points(sk, **kw)


# ---- rig --------------------------------------------------------------------------------------------------------

def test_rig_skeleton_is_the_three_steps_and_reports_them():
    mask = volrig.segment(volrig.phantom.humanoid(0.25).volume)
    steps = []
    sk = pipeline.skeleton_of(mask, progress=lambda step, f: steps.append(step))
    pts = sk.top(3000)
    r = pipeline.rig_skeleton(pts, mask, bones=24, progress=lambda step, f: steps.append(step), source="p.nrrd")
    assert [s for k, s in enumerate(steps) if k == 0 or steps[k - 1] != s] == list(pipeline.STEPS)
    tree = volrig.skeleton_tree(pts, mask)
    rig = volrig.autorig(pts, tree, mask, bones=24)
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    np.testing.assert_array_equal(r.tree.edges, tree.edges)
    assert r.rig.names == rig.names and r.rig.kind == "humanoid" and r.source == "p.nrrd"
    np.testing.assert_allclose(r.rig.joints, rig.joints)
    assert (r.binding.weights != binding.weights).nnz == 0 and r.binding.mode == "smooth"
    with pytest.raises(volrig.VolrigError, match="needs at least 2 skeleton points, got 1"):
        pipeline.rig_skeleton(sk.top(1), mask)
    with pytest.raises(volrig.Cancelled):
        pipeline.rig_skeleton(pts, mask, progress=lambda step, f: step != "autorig")


def test_load_rigged_says_what_is_missing(tmp_path):
    mask = volrig.segment(volrig.phantom.humanoid(0.2).volume)
    pts = volrig.skeletonize(mask).top(500)
    volrig.save_rig(tmp_path / "points.vrig", pts)
    with pytest.raises(volrig.VolrigError, match="points.vrig: the file holds no rig"):
        pipeline.load_rigged(str(tmp_path / "points.vrig"))
    r = pipeline.rig_skeleton(pts, mask)
    volrig.save_rig(tmp_path / "bare.vrig", pts, rig=r.rig)
    assert pipeline.load_rigged(str(tmp_path / "bare.vrig")).rig.names == r.rig.names
    with pytest.raises(volrig.VolrigError, match="no binding"):
        pipeline.load_rigged(str(tmp_path / "bare.vrig"), binding=True)


# ---- frames -----------------------------------------------------------------------------------------------------

def test_parse_frames():
    assert pipeline.parse_frames("1-3, 7 5") == [1, 2, 3, 5, 7]
    assert pipeline.parse_frames("4-6,5") == [4, 5, 6]
    assert pipeline.parse_frames("", default=(10, 12)) == [10, 11, 12]
    assert pipeline.parse_frames("-2-1") == [-2, -1, 0, 1]  # scene frames may be negative
    for text, kw, words in (("", {}, "none given"), ("5-x", {}, "'5-x' is not a frame or a range FIRST-LAST"),
                            ("5-3", {}, "empty range '5-3'"),
                            ("0-5", {"bounds": (1, 994, "131_01.bvh")}, "131_01.bvh has frames 1-994; asked for 0-5"),
                            ("5-3", {"bounds": (1, 994, "clip")}, "has frames 1-994; asked for 5-3"),
                            ("990-995", {"bounds": (1, 994, "clip")}, "asked for 990-995")):
        with pytest.raises(volrig.VolrigError, match=words):
            pipeline.parse_frames(text, **kw)


def test_clip_frames_on_a_step_grid_split_alike():
    assert pipeline.clip_frames(10).tolist() == list(range(10))
    assert pipeline.clip_frames(100, "1-61", step=30).tolist() == [0, 30, 60]
    # frames named by pieces of the range, each on the clip's grid, make up the whole range's frames
    whole = pipeline.clip_frames(994, "1-200", step=7)
    pieces = np.concatenate([pipeline.clip_frames(994, r, step=7) for r in ("1-50", "51-123", "124-200")])
    np.testing.assert_array_equal(pieces, whole)
    assert [pipeline.sequence_number(f, 7) for f in whole[:3]] == [1, 2, 3]
    assert pipeline.sequence_number(whole[-1], 7) == len(whole)
    # anchored at the first frame asked for (the add-on's Drive with BVH): every step-th from there
    assert pipeline.clip_frames(994, "5-20", step=5, anchor=5).tolist() == [4, 9, 14, 19]
    with pytest.raises(volrig.VolrigError, match="none falls on the step 30 grid"):
        pipeline.clip_frames(994, "2-20", step=30)
    with pytest.raises(volrig.VolrigError, match="at least 1"):
        pipeline.clip_frames(994, step=0)


# ---- baking to a folder -----------------------------------------------------------------------------------------

def _tiny_bake_inputs():
    """A two-bone bar: source, points, binding, a Deformer."""
    a = np.zeros((30, 12, 12), np.float32)
    a[3:27, 3:9, 3:9] = np.linspace(50, 150, 24)[:, None, None]
    source = volrig.Volume(a, spacing=(1.0, 1.0, 1.0))
    mask = volrig.segment(source, lo=1)
    pts = volrig.skeletonize(mask).at(0.0)
    rig = volrig.Rig(joints=[[6, 6, 3], [6, 6, 15], [6, 6, 26]], bones=[[0, 1], [1, 2]], names=["low", "high"])
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    return source, pts, binding, volrig.Deformer(source, pts, binding), rig


def test_folder_bake_writes_the_deformers_frames_and_tracks_poses(tmp_path):
    source, pts, binding, deformer, rig = _tiny_bake_inputs()
    bent = rig.pose({"high": ([1, 0, 0], 30)})
    folder = str(tmp_path / "frames")
    bake = pipeline.FolderBake(source, pts, binding, folder, "bar", mode="linear", track=True, setup="rig-1")
    assert not bake.up_to_date(1, bent)
    stats = bake.bake(1, bent)
    bake.bake(2, volrig.rest_pose(2))  # while frame 1's file is written
    bake.finish()
    assert sorted(os.listdir(folder)) == ["bar_0001.vdb", "bar_0002.vdb", "poses.json"]
    expected = deformer.frame(bent, mode="linear")
    # a bake's frames are in bricks: the same voxels, decided block by block on the brick-aligned box
    assert stats == deformer.frame(bent, mode="linear", bricks=True).stats
    assert stats["covered"] == int(np.count_nonzero(expected.bone.array))
    got = volrig.load(bake.path(1), grid="bone")
    np.testing.assert_array_equal(got.array, expected.bone.array)
    assert bake.up_to_date(1, bent) and not bake.up_to_date(1, volrig.rest_pose(2))
    # another bake of the same setup (another machine, or the next session) reads the record
    again = pipeline.FolderBake(source, pts, binding, folder, "bar", mode="linear", track=True, setup="rig-1")
    assert again.up_to_date(1, bent) and again.up_to_date(2, volrig.rest_pose(2))
    # a different mode, setup or weights makes every frame out of date
    for kw in ({"mode": "rigid"}, {"setup": "rig-2"}, {"sampling": "nearest"}, {"keep_volume": False}):
        other = pipeline.FolderBake(source, pts, binding, folder, "bar", track=True, **{"mode": "linear",
                                                                                      "setup": "rig-1", **kw})
        assert not other.up_to_date(1, bent), kw
    os.remove(bake.path(2))
    assert not again.up_to_date(2, volrig.rest_pose(2))  # a missing file is never up to date
    # frames baked elsewhere into the same folder are merged into the record, not overwritten
    again.bake(3, bent)
    again.finish()
    record = json.loads((tmp_path / "frames" / "poses.json").read_text())
    assert sorted(record) == ["1", "2", "3"]
    # a record made by another revision of the deformation is out of date
    stale = pipeline.FolderBake(source, pts, binding, folder, "bar", mode="linear", track=True, setup="rig-1")
    import volrig.pipeline as P
    revision, P.DEFORM_REVISION = P.DEFORM_REVISION, P.DEFORM_REVISION + 1
    try:
        newer = pipeline.FolderBake(source, pts, binding, folder, "bar", mode="linear", track=True, setup="rig-1")
    finally:
        P.DEFORM_REVISION = revision
    assert stale.up_to_date(1, bent) and not newer.up_to_date(1, bent)
    # keep_volume=False bakes the plain blend
    blend = pipeline.FolderBake(source, pts, binding, str(tmp_path / "blend"), "bar", mode="linear", keep_volume=False)
    assert blend.bake(1, bent) == deformer.frame(bent, mode="linear", keep_volume=False, bricks=True).stats
    blend.finish()
    # without tracking nothing is recorded and nothing is up to date
    plain = pipeline.FolderBake(source, pts, binding, str(tmp_path / "plain"), "bar")
    plain.bake(1, bent)
    plain.finish()
    assert os.listdir(tmp_path / "plain") == ["bar_0001.vdb"] and not plain.up_to_date(1, bent)
    # with the bones' lattice tables from the first frame (lattice_after=0): the same file
    tables = pipeline.FolderBake(source, pts, binding, str(tmp_path / "tables"), "bar", mode="linear", lattice_after=0)
    tables.bake(1, bent)
    tables.finish()
    assert tables.deformer.lattice_tables and not plain.deformer.lattice_tables
    # a bake builds no tables (memory first) whatever its length; asked for them (lattice_tables=True), at once when
    # it knows it will draw enough frames for them to pay back (TABLES_PAY_AFTER), never in a shorter one, after the
    # Deformer's default when it does not know; lattice_after wins over both
    for frames in (None, pipeline.TABLES_PAY_AFTER, 1000):
        assert pipeline.FolderBake(source, pts, binding, folder, "bar", frames=frames).deformer.lattice_after == -1
    for frames, after in ((None, volrig.Deformer.LATTICE_AFTER), (pipeline.TABLES_PAY_AFTER, 0),
                          (pipeline.TABLES_PAY_AFTER - 1, -1)):
        bake = pipeline.FolderBake(source, pts, binding, folder, "bar", frames=frames, lattice_tables=True)
        assert bake.deformer.lattice_after == after
    for asked in (False, True):
        bake = pipeline.FolderBake(source, pts, binding, folder, "bar", frames=100, lattice_after=2, lattice_tables=asked)
        assert bake.deformer.lattice_after == 2
    assert not plain.deformer.lattice_tables and plain.deformer.lattice_after == -1
    for grid in ("bone", "density"):
        np.testing.assert_array_equal(volrig.load(tables.path(1), grid=grid).array,
                                      volrig.load(plain.path(1), grid=grid).array)
    # a file that cannot be written (a folder stands in its place) fails the bake at the next frame or at finish
    os.makedirs(plain.path(5))
    plain.bake(5, bent)
    with pytest.raises((OSError, volrig.VolrigError)):
        plain.finish()
    plain.bake(6, bent)  # the bake goes on after a reported failure
    plain.finish()
    assert os.path.isfile(plain.path(6)) and plain.deformer.kept_frame_bytes == 0


def test_mocap_poses_default_to_the_automatic_map():
    bvh = shared("bvh/131_01.bvh")
    motion = volrig.read_bvh(str(bvh))
    ph = volrig.phantom.humanoid(0.25)
    mask = volrig.segment(ph.volume)
    rig = pipeline.rig_skeleton(volrig.skeletonize(mask).top(3000), mask).rig
    frames = pipeline.clip_frames(motion.frame_count, "1-61", step=30)
    bone_map, m = pipeline.mocap_poses(rig, motion, frames)
    assert bone_map == volrig.default_bone_map(motion, rig)
    np.testing.assert_allclose(m, volrig.animate(rig, motion, frames=[0, 30, 60], bone_map=bone_map))


def test_every_mode_and_sampling_the_menus_offer_is_the_cores():
    """The CLI's choices and the add-on's menus come from volrig.deform.MODE_INFO / SAMPLING_INFO; the core parses
    the names: each one offered must be one it takes."""
    from volrig import _volrig
    from volrig.deform import MODE_INFO, MODES, SAMPLING_INFO, SAMPLINGS
    assert MODES == tuple(MODE_INFO) and SAMPLINGS == tuple(SAMPLING_INFO)
    assert set(MODES) == set(_volrig.DEFORM_MODES) == {"rigid", "linear", "dual_quaternion"}
    assert set(SAMPLINGS) == set(_volrig.SAMPLINGS) == {"trilinear", "nearest"}
    deformer, rig = _tiny_bake_inputs()[3:]
    for mode in MODES:
        for sampling in SAMPLINGS:
            assert deformer.frame(volrig.rest_pose(2), mode=mode, sampling=sampling).stats["covered"] > 0
    with pytest.raises(volrig.VolrigError, match="unknown sampling 'cubic'"):
        deformer.frame(volrig.rest_pose(2), sampling="cubic")


def test_bake_rate_bar_counts_frames_and_their_pace():
    rate = pipeline.BakeRate(4)
    assert rate.bar(8) == "[........] 0/4 frames"
    rate.start -= 2.0  # two seconds ago
    rate.tick()
    rate.tick()
    text = rate.bar(8)
    assert text.startswith("[####....] 2/4 frames, ") and " frames/s, " in text and text.endswith(" left")
    assert 0.9 < rate.per_second <= 1.0
    assert pipeline.BakeRate(0).bar(4) == "[####] 0/0 frames"


def test_folder_bake_thickness_per_frame(tmp_path):
    """A frame with a bone's thickness factor bakes the thickened volume (more voxels), records the thickness in
    its pose hash, and a frame without one is the plain bake."""
    import volrig
    from volrig import pipeline
    ph = volrig.phantom.humanoid(scale=0.3)
    vol = volrig.Volume(np.pad(ph.volume.array, 8), ph.volume.spacing,
                        tuple(np.array(ph.volume.origin) - 8 * np.array(ph.volume.spacing)))
    mask = volrig.segment(vol, lo=1)
    sk = volrig.skeletonize(mask)
    r = pipeline.rig_skeleton(sk.at(0.5), mask, up=(0.0, 0.0, 1.0))
    fb = pipeline.FolderBake(vol, r.points, r.binding, str(tmp_path), "ph", mode="rigid", track=True, rig=r.rig)
    M = volrig.rest_pose(len(r.rig.bones))
    thick = np.ones(len(r.rig.bones))
    thick[r.rig.index("thigh.L")] = 1.5
    fb.bake(1, M)
    fb.bake(2, M, thickness=thick)
    fb.finish()
    plain = np.count_nonzero(volrig.load(fb.path(1), grid="density").array > 50)
    thicker = np.count_nonzero(volrig.load(fb.path(2), grid="density").array > 50)
    assert thicker > plain * 1.02
    assert fb.up_to_date(2, M, thickness=thick) and not fb.up_to_date(2, M)
    assert fb.up_to_date(1, M, thickness=np.ones(len(r.rig.bones)))
    with pytest.raises(volrig.VolrigError, match="rig"):
        pipeline.FolderBake(vol, r.points, r.binding, str(tmp_path), "x").bake(1, M, thickness=thick)

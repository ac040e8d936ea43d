"""Per-tissue looks for label maps (issues 21, 56): tissue tables, classes, the one ``tissue`` grid of class indices
(dense and brick by brick), its classes in the file's metadata, and bakes that write them (the Python package and
the command line)."""
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import SHARED_DATA

import volrig
from volrig.tissues import OTHER, TissueClass

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

TABLE = {0: "ExternalAir", 2: "InternalAir", 84: "BoneCortical", 92: "BoneMarrow", 136: "Fat", 180: "Muscle",
         204: "SkinDry", 61: "HeartMuscle", 7: "Mystery"}


def test_reads_tsv_and_csv_tables_with_or_without_a_header(tmp_path):
    tsv = tmp_path / "t.tsv"
    tsv.write_text("value\ttissue\tvoxels\n0\tExternalAir\t5\n84\tBoneCortical\t3\n\n180\t Muscle \t9\n")
    assert volrig.read_tissue_table(str(tsv)) == {0: "ExternalAir", 84: "BoneCortical", 180: "Muscle"}
    csv = tmp_path / "t.csv"
    csv.write_text("1,skin\n2,bone\n")
    assert volrig.read_tissue_table(str(csv)) == {1: "skin", 2: "bone"}


@pytest.mark.parametrize("text, words", [
    ("1\tskin\nx\tbone\n", "line 2: 'x' is not an integer"),
    ("1\tskin\n1\tbone\n", "code 1 appears twice"),
    ("1\tskin\n2\t\n", "code 2 has no tissue name"),
    ("code\tname\n", "no tissue codes"),
])
def test_bad_tables_are_refused(tmp_path, text, words):
    p = tmp_path / "bad.tsv"
    p.write_text(text)
    with pytest.raises(volrig.VolrigError, match=words):
        volrig.read_tissue_table(str(p))


def test_classes_group_codes_by_the_first_matching_name():
    t = {x.name: x for x in volrig.tissue_classes(TABLE)}
    assert t["bone"].codes == [84, 92]          # marrow is bone, not fat
    assert t["heart"].codes == [61]             # heart muscle is heart, not muscle
    assert t["muscle"].codes == [180] and t["fat"].codes == [136] and t["skin"].codes == [204]
    assert t["air"].codes == [2] and not t["air"].visible  # gas inside the body: hidden
    assert t[OTHER.name].codes == [7]           # no class matches
    assert all(0 not in x.codes for x in t.values())  # outside air and code 0 are in no class
    found = volrig.tissue_classes(TABLE)  # the class indices' order: skin (next to the outside), then by opacity
    weights = [x.opacity if x.visible else 0.0 for x in found[1:]]
    assert found[0].name == "skin" and weights == sorted(weights) and found[1].name == "air"
    assert [x.name for x in found] == ["skin", "air", "fat", "muscle", OTHER.name, "heart", "bone"]
    assert volrig.tissues.index_order(found[::-1]) == found
    assert [x.name for x in volrig.tissue_classes(TABLE, present=[0, 84, 136])] == ["fat", "bone"]
    mine = [TissueClass("hard", "bone", (1, 1, 1), 1.0), TissueClass("soft", "fat|muscle", (1, 0, 0), 0.2, False)]
    got = {x.name: (x.codes, x.visible) for x in volrig.tissue_classes(TABLE, mine)}
    assert got == {"hard": ([84, 92], True), "soft": ([61, 136, 180], False), "other": ([2, 7, 204], True)}


def _place(grid: volrig.Volume, like: volrig.Volume) -> np.ndarray:
    """A cropped grid put back on the full lattice of ``like``."""
    full = np.zeros(like.array.shape, grid.array.dtype)
    o = np.round((np.array(grid.origin) - np.array(like.origin)) / np.array(like.spacing)).astype(int)[::-1]
    s = grid.array.shape
    full[o[0]:o[0] + s[0], o[1]:o[1] + s[1], o[2]:o[2] + s[2]] = grid.array
    return full


def _reference(codes: np.ndarray, tissues) -> np.ndarray:
    """Each voxel's class index the slow way: k + 1 where the code is one of class k's, 0 elsewhere."""
    out = np.zeros(codes.shape, np.uint8)
    for k, t in enumerate(tissues):
        out[np.isin(codes, t.codes)] = k + 1
    return out


def _bricks(a: np.ndarray) -> np.ndarray:
    """A [z, y, x] array padded with zeros to multiples of 8 and cut into 8³ bricks [brick z, y, x, z, y, x]."""
    n = -(-np.array(a.shape) // 8) * 8
    padded = np.zeros(n, a.dtype)
    padded[:a.shape[0], :a.shape[1], :a.shape[2]] = a
    return np.ascontiguousarray(padded.reshape(n[0] // 8, 8, n[1] // 8, 8, n[2] // 8, 8).transpose(0, 2, 4, 1, 3, 5))


def _unbricked(b: np.ndarray, shape) -> np.ndarray:
    nb = b.shape[:3]
    whole = b.transpose(0, 3, 1, 4, 2, 5).reshape(nb[0] * 8, nb[1] * 8, nb[2] * 8)
    return whole[:shape[0], :shape[1], :shape[2]]


@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.float32, np.float16])
def test_the_tissue_grid_is_each_voxels_class_dense_and_by_brick(dtype):
    rng = np.random.default_rng(7)
    codes = np.array(sorted(TABLE))
    lab = volrig.Volume(rng.choice(codes, size=(9, 11, 13)).astype(dtype), (0.5, 1.0, 2.0), (3.0, -1.0, 2.0))
    tissues = volrig.tissue_classes(TABLE)
    want = _reference(lab.array, tissues)
    g = volrig.tissue_grid(lab, tissues)
    assert g.array.dtype == np.uint8 and g.spacing == lab.spacing and g.origin == lab.origin
    np.testing.assert_array_equal(g.array, want)
    got = volrig.tissues.brick_classes(_bricks(np.asarray(lab.array)), tissues)
    assert got.dtype == np.uint8
    np.testing.assert_array_equal(_unbricked(got, lab.array.shape), want)


def test_an_absent_class_has_no_voxels_and_bad_labels_are_refused():
    lab = volrig.Volume(np.full((4, 4, 4), 180, np.uint8), (1, 1, 1))
    tissues = volrig.tissue_classes(TABLE)
    g = volrig.tissue_grid(lab, tissues).array
    muscle = [t.name for t in tissues].index("muscle") + 1
    assert (g == muscle).all()
    for bad in (np.full((2, 2, 2), 1.5, np.float32), np.full((2, 2, 2), np.nan, np.float32)):
        with pytest.raises(volrig.VolrigError, match="not integers"):
            volrig.tissue_grid(volrig.Volume(bad, (1, 1, 1)), tissues)
        for values in (bad, bad.astype(np.float16)):  # (half floats: a bake's values, through their own table)
            with pytest.raises(volrig.VolrigError, match="not integers"):
                volrig.tissues.brick_classes(_bricks(values), tissues)


def test_the_classes_travel_in_the_files_metadata(tmp_path):
    tissues = volrig.tissue_classes(TABLE)
    lab = volrig.Volume(np.array(sorted(TABLE), np.int16).reshape(1, 1, -1), (1.0, 1.0, 1.0))
    path = str(tmp_path / "t.vdb")
    volrig.write_vdb(path, {"density": lab, "tissue": volrig.tissue_grid(lab, tissues)}, labels=("tissue",),
                     metadata=volrig.tissues.classes_metadata(tissues))
    assert volrig.tissues.classes_from_metadata(volrig.vdb_metadata(path)) == tissues
    assert {g["name"]: g["type"] for g in volrig.vdb_grids(path)}["tissue"] == "int32"
    np.testing.assert_array_equal(_place(volrig.load(path, grid="tissue"), lab), _reference(lab.array, tissues))
    plain = str(tmp_path / "plain.vdb")
    volrig.write_vdb(plain, {"density": lab})
    assert volrig.vdb_metadata(plain) == {} and volrig.tissues.classes_from_metadata({}) == []
    with pytest.raises(volrig.VolrigError, match="malformed"):
        volrig.tissues.classes_from_metadata({volrig.tissues.METADATA: "[{\"key\": 1}]"})
    (tmp_path / "not.vdb").write_bytes(b"x" * 100)
    with pytest.raises(volrig.FileFormatError, match="not an OpenVDB file"):
        volrig.vdb_metadata(str(tmp_path / "not.vdb"))
    cut = tmp_path / "cut.vdb"  # the metadata cut short: said so, nothing read past the file
    cut.write_bytes(open(path, "rb").read()[:90])
    with pytest.raises(volrig.FileFormatError, match="truncated or corrupt"):
        volrig.vdb_metadata(str(cut))


def test_the_visible_humans_table_puts_every_code_in_a_class():
    path = SHARED_DATA / "visible-human" / "austinman_tissues.tsv"
    if not path.exists():
        pytest.skip(f"real data not available: {path}")
    table = volrig.read_tissue_table(str(path))
    assert len(table) == 64
    t = {x.name: x for x in volrig.tissue_classes(table)}
    names = {c: table[c] for c in table}
    assert sorted(names[c] for c in t["bone"].codes) == ["BoneCortical", "BoneMarrow", "Tooth"]
    assert sorted(names[c] for c in t["skin"].codes) == ["Nail", "SkinDry"]
    assert names[180] == "Muscle" and 180 in t["muscle"].codes and 136 in t["fat"].codes
    assert OTHER.name not in t, t[OTHER.name].codes  # the preset names every tissue of the Visible Human
    assert sum(len(x.codes) for x in t.values()) == 63  # all but external air


def test_the_visible_humans_tissue_grid_by_brick_equals_the_dense_one(tmp_path):
    """The 4 mm Visible Human's label map, brick by brick (a bake's path) and written, against the dense reference."""
    data = SHARED_DATA / "visible-human"
    if not (data / "austinman_4mm_labels.nii.gz").exists() or not (data / "austinman_tissues.tsv").exists():
        pytest.skip(f"real data not available: {data}/austinman_4mm_labels.nii.gz, austinman_tissues.tsv")
    lab = volrig.load(str(data / "austinman_4mm_labels.nii.gz"))
    codes = np.asarray(lab.array)
    tissues = volrig.tissue_classes(volrig.read_tissue_table(str(data / "austinman_tissues.tsv")),
                                    present=np.unique(codes))
    want = _reference(codes, tissues)
    assert len(tissues) >= 12 and len(np.unique(want)) == len(tissues) + 1
    bricks = volrig.tissues.brick_classes(_bricks(codes.astype(np.float16)), tissues)  # (a bake's half values)
    np.testing.assert_array_equal(_unbricked(bricks, codes.shape), want)
    path = str(tmp_path / "vh.vdb")
    volrig.write_vdb(path, {"tissue": bricks}, lab.spacing, lab.origin, labels=("tissue",))
    np.testing.assert_array_equal(_place(volrig.load(path, grid="tissue"), lab), want)


@pytest.fixture(scope="module")
def labelled_rig(tmp_path_factory):
    """A small label map (a bar of 'bone' inside 'muscle' inside 'skin') rigged with two bones."""
    tmp = tmp_path_factory.mktemp("tissues")
    lab = np.zeros((12, 12, 40), np.uint8)
    lab[1:11, 1:11, 1:39] = 204
    lab[2:10, 2:10, 2:38] = 180
    lab[4:8, 4:8, 3:37] = 84
    vol = volrig.Volume(lab, (1.0, 1.0, 1.0))
    mask = volrig.Volume(lab > 0, vol.spacing)
    pts = volrig.skeletonize(mask).at(0.5)
    rig = volrig.Rig.from_bones([[2, 5.5, 5.5], [20, 5.5, 5.5]], [[20, 5.5, 5.5], [37, 5.5, 5.5]], ["a", "b"],
                                [-1, 0])
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    src = tmp / "bar.nrrd"
    vol.save(str(src))
    rig_file = tmp / "bar.vrig"
    volrig.save_rig(str(rig_file), pts, rig=rig, binding=binding, source=str(src))
    table = tmp / "bar.tsv"
    table.write_text("code\tname\n0\tExternalAir\n84\tBoneCortical\n180\tMuscle\n204\tSkinDry\n")
    return vol, pts, rig, binding, src, rig_file, table


def test_folder_bake_writes_the_tissue_grid_of_the_posed_labels(tmp_path, labelled_rig):
    vol, pts, rig, binding, *_ = labelled_rig
    tissues = volrig.tissue_classes({84: "BoneCortical", 180: "Muscle", 204: "SkinDry"})
    with pytest.raises(volrig.VolrigError, match="nearest sampling"):
        volrig.pipeline.FolderBake(vol, pts, binding, str(tmp_path), "bar", tissues=tissues)
    bake = volrig.pipeline.FolderBake(vol, pts, binding, str(tmp_path), "bar", sampling="nearest", tissues=tissues)
    m = rig.pose({"b": ([0, 0, 1], 40.0)})
    bake.bake(1, m)
    bake.finish()
    path = bake.path(1)
    assert {g["name"] for g in volrig.vdb_grids(path)} == {"density", "bone", "tissue"}
    assert volrig.tissues.classes_from_metadata(volrig.vdb_metadata(path)) == tissues
    frame = volrig.Deformer(vol, pts, binding).frame(m, mode="linear", sampling="nearest")
    want = _reference(np.asarray(frame.values.array), tissues)
    assert set(np.unique(want)) == {0, 1, 2, 3}
    np.testing.assert_array_equal(_place(volrig.load(path, grid="tissue"), frame.values), want)
    dense = str(tmp_path / "dense.vdb")  # a Frame's own save writes the same grid
    frame.save(dense, tissues=tissues)
    np.testing.assert_array_equal(_place(volrig.load(dense, grid="tissue"), frame.values), want)


def test_folder_bake_keeps_codes_past_half_float_range(tmp_path, labelled_rig):
    """A bake holds its frames' values as half floats, with tissue looks too unless the codes pass 2048: a 16-bit
    label map's code 4097 (4096 in half floats) keeps its voxels in its tissue's class."""
    vol, pts, rig, binding, *_ = labelled_rig
    lab = np.asarray(vol.array).astype(np.uint16)
    lab[lab == 84] = 4097
    wide = volrig.Volume(lab, vol.spacing)
    tissues = volrig.tissue_classes({4097: "BoneCortical", 180: "Muscle", 204: "SkinDry"})
    bake = volrig.pipeline.FolderBake(wide, pts, binding, str(tmp_path), "wide", sampling="nearest", tissues=tissues)
    assert not bake._half and volrig.pipeline.FolderBake(vol, pts, binding, str(tmp_path), "x", sampling="nearest",
                                                         tissues=tissues)._half
    m = rig.pose({"b": ([0, 0, 1], 40.0)})
    bake.bake(1, m)
    bake.finish()
    frame = volrig.Deformer(wide, pts, binding).frame(m, mode="linear", sampling="nearest")
    bone = _place(volrig.load(bake.path(1), grid="tissue"), frame.values) == [t.name for t in tissues].index("bone") + 1
    assert bone.any()
    np.testing.assert_array_equal(bone, np.asarray(frame.values.array) == 4097)


def test_cli_bake_mocap_with_tissues(tmp_path, labelled_rig):
    _, _, _, _, src, rig_file, table = labelled_rig
    clip = SHARED_DATA / "bvh" / "131_01.bvh"
    if not clip.exists():
        pytest.skip(f"real data not available: {clip}")
    env = dict(os.environ, PYTHONPATH=os.path.join(REPO, "python"))

    def run(*args):
        return subprocess.run([sys.executable, "-m", "volrig", "bake-mocap", str(src), str(rig_file), str(clip),
                               "-o", str(tmp_path / "out"), "--frames", "1", "--map", str(bone_map), "--scale", "1",
                               *args],
                              capture_output=True, text=True, env=env)
    bone_map = tmp_path / "map.json"
    bone_map.write_text('{"LeftHip": "a", "LeftKnee": "b"}')
    r = run("--tissues", str(table))
    assert r.returncode == 2 and "--sampling nearest" in r.stderr and "Traceback" not in r.stderr, r.stderr
    r = run("--tissues", str(table), "--sampling", "nearest")
    assert r.returncode == 0, r.stderr
    assert "tissues: skin (1), muscle (1), bone (1)" in r.stderr
    out = str(tmp_path / "out" / "bar_0001.vdb")
    assert {g["name"] for g in volrig.vdb_grids(out)} == {"density", "bone", "tissue"}
    assert [t.name for t in volrig.tissues.classes_from_metadata(volrig.vdb_metadata(out))] == ["skin", "muscle", "bone"]
    r = run("--tissues", str(tmp_path / "missing.tsv"), "--sampling", "nearest")
    assert r.returncode != 0 and "missing.tsv" in r.stderr and "Traceback" not in r.stderr


def test_classes_of_negative_and_large_codes():
    """Codes a lookup table cannot index (negative, huge) take the search path and give the same classes."""
    rng = np.random.default_rng(5)
    table = {-7: "BoneCortical", 3: "Muscle", 5_000_000: "Fat"}
    lab = volrig.Volume(rng.choice([0, -7, 3, 5_000_000, 11], size=(6, 7, 8)).astype(np.int64), (1.0, 1.0, 1.0))
    tissues = volrig.tissue_classes(table)
    np.testing.assert_array_equal(volrig.tissue_grid(lab, tissues).array, _reference(lab.array, tissues))
    small = volrig.Volume(rng.choice([0, 3, 9, 70], size=(6, 7, 8)).astype(np.int32), (1.0, 1.0, 1.0))
    tissues = volrig.tissue_classes({3: "Muscle", 9: "Fat"})  # 70: past the lookup table's codes, in no class
    np.testing.assert_array_equal(volrig.tissue_grid(small, tissues).array, _reference(small.array, tissues))


def test_finds_the_tissue_table_beside_a_label_map(tmp_path):
    lab = tmp_path / "body_labels.nii.gz"
    lab.write_bytes(b"")  # (only its folder matters)
    assert volrig.find_tissue_table(str(lab), [0, 84, 180]) == ""
    (tmp_path / "readme.txt").write_text("84\tBoneCortical\n180\tMuscle\n")        # not named for tissues
    (tmp_path / "labels_other.csv").write_text("1,skin\n2,bone\n")                 # names other codes
    (tmp_path / "tissue_broken.tsv").write_text("x\tBone\n84\tBone\n")            # not a table
    assert volrig.find_tissue_table(str(lab), [0, 84, 180]) == ""
    good = tmp_path / "body_tissues.tsv"
    good.write_text("value\ttissue\n84\tBoneCortical\n180\tMuscle\n")
    assert volrig.find_tissue_table(str(lab), [0, 84, 180]) == str(good)


@pytest.mark.parametrize("shape", [(0, 3, 3), (5,), (40, 300, 301), (3, 2, 2)])
def test_codes_present_are_np_unique_by_slabs(shape):
    a = np.random.default_rng(2).integers(-3, 200, size=shape).astype(np.int16)
    np.testing.assert_array_equal(volrig.tissues.codes_present(a), np.unique(a))


def test_body_codes_and_label_text_round_trip():
    table = {0: "ExternalAir", 1: "Void", 2: "InternalAir", 3: "Skin", 4: "Bone", 9: "Fat", 10: "Muscle"}
    body = volrig.tissues.body_codes(table, [0, 2, 3, 4, 9, 10, 77])
    assert body == [2, 3, 4, 9, 10]  # present, named, not outside; 77 is in no table, 1 not present
    text = volrig.pipeline.labels_text(body)
    assert text == "2-4, 9-10" and volrig.pipeline.parse_labels(text) == body
    assert volrig.pipeline.labels_text([5]) == "5"


@pytest.mark.skipif(__import__("shutil").which("blender") is None, reason="blender is not on PATH")
def test_the_showcase_script_renders_the_walking_visible_human(tmp_path):
    """scripts/showcase.py headless at a tiny size: the Visible Human rigged, one frame baked with tissue grids and
    rendered in two looks; the sheet shows a body (many pixels away from the background)."""
    labels = SHARED_DATA / "visible-human" / "austinman_4mm_labels.nii.gz"
    if not labels.exists():
        pytest.skip(f"real data not available: {labels}")
    out = tmp_path / "sheet.png"
    r = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                        os.path.join(REPO, "scripts", "showcase.py"), "--", "--count", "1", "--height", "96",
                        "--samples", "2", "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "humanoid (21 bones)" in r.stdout and "baked 1/1" in r.stdout and r.stdout.count("rendered 1/1") == 2
    import matplotlib.image as mpimg
    img = mpimg.imread(str(out))[..., :3]
    background = np.median(img.reshape(-1, 3), axis=0)
    assert (np.abs(img - background).sum(axis=2) > 0.15).mean() > 0.01
    bad = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                          os.path.join(REPO, "scripts", "showcase.py"), "--", "--hide", "feathers", "--count", "1",
                          "--height", "32", "--samples", "1", "--out", str(tmp_path / "x.png")],
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode != 0 and "no such tissue class" in bad.stdout + bad.stderr


@pytest.mark.skipif(__import__("shutil").which("blender") is None, reason="blender is not on PATH")
def test_the_showcase_script_encodes_a_video_of_a_walk_cycle(tmp_path):
    """scripts/showcase.py --video at a tiny size: three frames of a whole walk cycle (4 mm) rendered in the first
    look, encoded as H.264 (ffprobe reads back its codec, size and frames) with a contact sheet beside it."""
    import shutil
    labels = SHARED_DATA / "visible-human" / "austinman_4mm_labels.nii.gz"
    if not labels.exists():
        pytest.skip(f"real data not available: {labels}")
    if shutil.which("ffmpeg") is None or shutil.which("ffprobe") is None:
        pytest.skip("ffmpeg/ffprobe not installed (apt-get install -y ffmpeg; scripts/setup installs it)")
    video, frames = tmp_path / "walk.mp4", tmp_path / "frames"
    r = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                        os.path.join(REPO, "scripts", "showcase.py"), "--", "--mm", "4", "--count", "3",
                        "--full-cycle", "--width", "96", "--height", "54", "--samples", "1", "--video", str(video),
                        "--frames", str(frames), "--loops", "2", "--fps", "12"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "(a whole cycle)" in r.stdout and "baked 3/3" in r.stdout and r.stdout.count("rendered 3/3") == 1
    assert sorted(p.name for p in frames.iterdir()) == ["frame_001.png", "frame_002.png", "frame_003.png"]
    assert video.stat().st_size > 0 and (tmp_path / "walk_sheet.png").stat().st_size > 0
    probe = subprocess.run(["ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
                            "stream=codec_name,width,height,nb_read_frames", "-of", "csv=p=0", str(video)],
                           capture_output=True, text=True)
    assert probe.stdout.strip().split(",") == ["h264", "96", "54", "6"]  # (3 frames played twice)
    import matplotlib.image as mpimg
    img = mpimg.imread(str(frames / "frame_002.png"))[..., :3]
    background = np.median(img.reshape(-1, 3), axis=0)
    assert (np.abs(img - background).sum(axis=2) > 0.15).mean() > 0.01  # a body in the frame


def test_file_classes_of_files_that_are_not_vdb_are_none(tmp_path):
    """A drawing's image, a NIfTI or a folder has no baked classes (no error: the add-on asks of every import)."""
    from volrig.tissues import file_classes
    png = tmp_path / "hero.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n")
    assert file_classes(str(png)) == [] and file_classes(str(tmp_path)) == []
    assert file_classes(str(tmp_path / "body.nii.gz")) == []

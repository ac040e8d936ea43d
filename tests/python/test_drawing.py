"""volrig.inflate (issue 23, "a drawing becomes a character"): shapes inflate to the solids they should, the
background is found with and without alpha, drawn characters rig as what they are, parts drawn in front come out in
front, bad input is refused clearly."""
import os
import subprocess
import sys

import numpy as np
import pytest

import volrig
from volrig import drawing as D
from volrig_support import sketches as K

RIGIFY = ["hips", "spine", "chest", "neck", "head"] + [f"{b}.{s}" for s in "LR" for b in (
    "shoulder", "upper_arm", "forearm", "hand", "pelvis", "thigh", "shin", "foot")]


def rig_of(mask):
    pts = volrig.skeletonize(mask).top(15000)
    return volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=(0, 0, 1))


def runs(column):
    """Number of runs of True in a 1-D bool array."""
    c = np.concatenate([[False], column, [False]]).astype(np.int8)
    return int((np.diff(c) == 1).sum())


def test_disc_inflates_to_a_ball():
    img = K.disc(r=30)
    v = volrig.inflate(img, pixel_size=0.5)
    area = (np.abs(img - 1).max(axis=2) > 0.2).sum()
    r = np.sqrt(area / np.pi)
    volume = v.array.sum()
    assert v.array.dtype == np.bool_ and v.spacing == (0.5, 0.5, 0.5)
    assert volume == pytest.approx(4 / 3 * np.pi * r ** 3, rel=0.04)
    # round: the extents along x, y (depth) and z agree; the mid cross-sections are discs of equal area
    extents = [np.flatnonzero(v.array.any(axis=tuple(a for a in range(3) if a != k))).size for k in range(3)]
    assert max(extents) - min(extents) <= 2
    z, y, x = (s // 2 for s in v.array.shape)
    sections = [v.array[z].sum(), v.array[:, y].sum(), v.array[:, :, x].sum()]
    assert max(sections) / min(sections) < 1.05
    assert sections[0] == pytest.approx(np.pi * r ** 2, rel=0.06)


def test_bar_inflates_to_a_cylinder():
    v = volrig.inflate(K.bar(length=120, r=15)).array  # [z, y, x]: the bar runs along x
    middle = v[:, :, 30:90]
    areas = middle.sum(axis=(0, 1))
    assert areas.std() / areas.mean() < 0.01  # the same cross-section all along
    assert areas.mean() == pytest.approx(np.pi * 15 ** 2, rel=0.08)
    section = middle[:, :, 30]
    assert abs(np.flatnonzero(section.any(axis=0)).size - np.flatnonzero(section.any(axis=1)).size) <= 2  # round


def test_depth_scale_flattens():
    full = volrig.inflate(K.disc(r=20)).array
    flat = volrig.inflate(K.disc(r=20), depth_scale=0.5).array
    assert np.flatnonzero(flat.any(axis=(0, 2))).size == pytest.approx(np.flatnonzero(full.any(axis=(0, 2))).size / 2,
                                                                        abs=2)
    assert flat.sum() == pytest.approx(full.sum() / 2, rel=0.05)


def test_frame_up_is_plus_z_right_is_plus_x():
    img = np.ones((60, 40, 3))
    img[5:20, 5:15] = 0.5   # top left of the drawing
    img[5:55, 5:35][30:] = 0.5
    img[10:50, 10:30] = 0.5
    v = volrig.inflate(img, pixel_size=2.0)
    a = v.array
    top = a[-3].any(axis=0)  # the highest slice (z up) holds the top rows
    assert top.any()
    zs = v.origin[2] + 2.0 * np.arange(a.shape[0])
    assert zs[-2] == pytest.approx(2.0 * (60 - 1 - 5), abs=2.0)  # row 5 (top) at z = (H - 1 - 5) * pixel_size
    xs = v.origin[0] + 2.0 * np.flatnonzero(a.any(axis=(0, 1)))
    assert xs.min() == pytest.approx(2.0 * 5) and xs.max() == pytest.approx(2.0 * 34)


def test_background_from_the_border_and_from_alpha():
    img = K.disc(r=20)
    shape = np.abs(img - 1).max(axis=2) > 0.2
    on_white = volrig.inflate(img)
    dark_bg = volrig.inflate(np.where(shape[..., None], img, 0.1))  # any uniform background colour
    rgba = np.dstack([np.zeros_like(img), shape.astype(float)])     # black on transparent black
    alpha = volrig.inflate((rgba * 255).astype(np.uint8))
    assert on_white.array.sum() == dark_bg.array.sum() == alpha.array.sum()
    opaque = np.dstack([img, np.ones(shape.shape)])  # alpha everywhere opaque: the colours decide
    assert volrig.inflate(opaque).array.sum() == on_white.array.sum()
    grey = volrig.inflate((img.mean(axis=2) * 65535).astype(np.uint16))
    assert grey.array.sum() == on_white.array.sum()


def test_line_drawing_with_white_fill_is_solid():
    img = K.paint(K.canvas(80, 80), K.ellipse(80, 80, 40, 40, 30, 30), (1, 1, 1), line=2)
    v = volrig.inflate(img).array
    assert v[v.shape[0] // 2].sum() > 0.9 * np.pi * 30 ** 2


def test_png_path_and_colours(tmp_path):
    img = K.arm_across()
    path = tmp_path / "drawing.png"
    D.write_png(str(path), img)
    v = volrig.inflate(str(path))
    assert np.array_equal(v.array, volrig.inflate(img).array)
    c = volrig.drawing_colours(str(path), v)
    assert c.shape == v.array.shape + (3,) and c.dtype == np.float32
    z, y, x = np.argwhere(v.array)[len(np.argwhere(v.array)) // 2]
    row, col = img.shape[0] - 1 - int(round(v.origin[2] + z)), int(round(v.origin[0] + x))
    assert np.allclose(c[z, y, x], img[row, col], atol=0.01) or img[row, col].max() < 0.1  # a stroke: its fill
    # the outline is replaced by the fill colour: no voxel at the solid's rim is painted black
    from scipy import ndimage as ndi
    seen = v.array.any(axis=1)
    rim = v.array & (seen & ~ndi.binary_erosion(seen))[:, None, :]
    assert (c[rim].max(axis=1) > 0.3).mean() > 0.99


def test_phantom_silhouette_rigs_as_a_humanoid():
    from volrig_support import subjects
    s = subjects.phantom_subject(0.5)
    silhouette = s.mask.array.any(axis=1)[::-1]  # front view: along y (anterior -y), rows from the top (+z)
    img = np.pad(np.where(silhouette[..., None], 0.55, 1.0), ((4, 4), (4, 4), (0, 0)), constant_values=1.0)
    v = volrig.inflate(img, pixel_size=s.mask.spacing[0])
    rig = rig_of(v)
    assert rig.kind == "humanoid"
    assert sorted(rig.names) == sorted(RIGIFY)
    head, feet = rig.joints[rig.names.index("head")], rig.joints[rig.names.index("foot.L")]
    assert head[2] > feet[2]  # up is +z


def test_drawn_character_rigs_as_a_humanoid():
    rig = rig_of(volrig.inflate(K.character()))
    assert rig.kind == "humanoid" and set(RIGIFY) <= set(rig.names)
    left, right = (rig.joints[rig.names.index(f"hand.{s}")] for s in "LR")
    assert left[0] > right[0]  # the character's left is image right = +x


def test_character_with_an_arm_across_the_belly_rigs_as_a_humanoid():
    img = K.character(arm_over=True)
    labels, d = D.inflate_parts(img)
    assert labels.array.max() >= 2  # the forearm drawn over the belly lies in front
    rig = rig_of(labels.like(labels.array > 0))
    assert rig.kind == "humanoid" and set(RIGIFY) <= set(rig.names)


def test_drawn_quadruped_rigs_as_a_quadruped():
    img = K.quadruped()
    labels = D.analyse(img).parts
    assert len(D.in_front(labels)) == 2  # the near legs
    assert rig_of(volrig.inflate(img)).kind == "quadruped"


@pytest.mark.parametrize("gap", [0, 2])
def test_arm_drawn_across_the_body_lies_in_front(gap):
    img = K.arm_across()
    labels, d = D.inflate_parts(img, gap=gap)
    a = labels.array
    assert a.max() == 2  # the body (with the parts beside the arm) and the arm in front
    arm, body = a == 2, a == 1
    both = arm.any(axis=1) & body.any(axis=1)  # columns (z, x) where the arm crosses the body
    assert both.sum() > 1000
    ys = np.arange(a.shape[1])[None, :, None]
    arm_back = np.where(arm, ys, -1).max(axis=1)[both]
    body_front = np.where(body, ys, a.shape[1]).min(axis=1)[both]
    assert (arm_back < body_front - gap).all()  # every arm voxel before every body voxel, gap voxels between
    solid = a > 0
    if gap:
        assert all(runs(solid[z, :, x]) == 2 for z, x in np.argwhere(both))
    else:  # touching: one piece
        from scipy import ndimage as ndi
        assert ndi.label(solid, structure=np.ones((3, 3, 3)))[1] == 1
    # the body is completed under the arm: its depth there is what its outline alone would give
    z, x = np.argwhere(both)[len(np.argwhere(both)) // 2]
    assert body[z, :, x].sum() > 0.5 * body.sum(axis=1).max()


def test_no_inner_strokes_is_one_part():
    labels, _ = D.inflate_parts(K.character())
    assert labels.array.max() == 1


@pytest.mark.parametrize("image, message", [
    (np.ones((50, 50, 3)), "empty"),
    (np.zeros((50, 50, 4)), "empty"),
    (np.full((50, 50, 4), 255, np.uint8), "empty"),  # opaque white: the colours decide
    (np.random.default_rng(1).random((50, 50, 3)), "no background"),  # all figure: no border colour
    (np.dstack([np.zeros((50, 50, 3)), np.full((50, 50), 0.9)]), "empty"),  # all opaque, all one colour
    (np.full((50, 50, 3), np.nan), "NaN"),
    (np.full((50, 50, 3), 2.0), "0..1"),
    (np.ones((50, 50, 5)), "shape"),
    (np.ones((50,)), "shape"),
    (np.ones((2, 2, 3)), "shape"),
    (np.ones((50, 50, 3), np.int16), "unsigned"),
])
def test_bad_images_are_refused(image, message):
    with pytest.raises(volrig.VolrigError, match=message):
        volrig.inflate(image)


def test_bad_options_are_refused():
    for kw, message in [(dict(pixel_size=0), "pixel_size"), (dict(depth_scale=-1), "depth_scale"),
                        (dict(gap=0.5), "gap"), (dict(stroke_width=float("nan")), "stroke_width"),
                        (dict(resolution=2), "resolution")]:
        with pytest.raises(volrig.VolrigError, match=message):
            volrig.inflate(K.disc(r=10), **kw)


def test_malformed_png_is_refused(tmp_path):
    good = tmp_path / "good.png"
    D.write_png(str(good), K.disc(r=10))
    data = good.read_bytes()
    cases = {"truncated.png": data[:len(data) // 2], "text.png": b"not a png at all",
             "lying.png": data[:16] + (100000).to_bytes(4, "big") * 2 + data[24:]}  # IHDR claims 100000 x 100000
    for name, content in cases.items():
        p = tmp_path / name
        p.write_bytes(content)
        with pytest.raises(volrig.FileFormatError, match=name):
            volrig.inflate(str(p))
    with pytest.raises(FileNotFoundError):
        volrig.inflate(str(tmp_path / "missing.png"))


@pytest.mark.parametrize("channels", [None, 2, 3, 4])
def test_write_png_round_trips_through_the_native_reader(tmp_path, channels):
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (7, 9) if channels is None else (7, 9, channels)).astype(np.uint8)
    D.write_png(str(tmp_path / "x.png"), img)
    back = D.read_png(str(tmp_path / "x.png"))
    assert back.shape == (7, 9, 4) and back.dtype == np.uint8
    grey = img if channels is None else img[..., 0]
    assert np.array_equal(back[..., 0], grey if channels in (None, 2) else img[..., 0])
    assert np.array_equal(back[..., 3], img[..., -1] if channels in (2, 4) else np.full((7, 9), 255))


def test_resolution_downscales():
    big = K.disc(r=60)
    v = volrig.inflate(big, resolution=70)
    assert v.spacing == (2.0, 2.0, 2.0)
    assert v.array.sum() * 8 == pytest.approx(volrig.inflate(big).array.sum(), rel=0.06)


def test_a_solid_above_max_voxels_is_refused_with_the_resolution_that_fits():
    big = K.disc(r=60)  # 140 px: a 123^3 box
    with pytest.raises(volrig.VolrigError, match=r"inflates to a 12\d x 12\d x 12\d solid \(1,[\d,]+ voxels\), more "
                                                 r"than max_voxels=500,000: pass resolution=(\d+)") as e:
        volrig.inflate(big, max_voxels=500_000)
    fits = int(e.value.args[0].split("resolution=")[1].split()[0])
    v = volrig.inflate(big, resolution=fits, max_voxels=500_000)
    assert 0 < int(np.prod(v.dims)) <= 500_000


def test_the_size_refusal_names_the_drawing_file(tmp_path):
    path = tmp_path / "big disc.png"
    D.write_png(str(path), (K.disc(r=60) * 255).astype(np.uint8))
    with pytest.raises(volrig.VolrigError, match=rf"^{tmp_path}/big disc.png: the drawing inflates to"):
        volrig.inflate(str(path), max_voxels=500_000)
    r = subprocess.run([sys.executable, "-m", "volrig", "inflate", str(path), str(tmp_path / "o.vdb"),
                        "--max-voxels", "500000"], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=os.path.join(os.path.dirname(__file__), "..", "..", "python")))
    assert r.returncode != 0 and "big disc.png: the drawing inflates to" in r.stderr and "resolution=" in r.stderr
    assert not (tmp_path / "o.vdb").exists()


def test_cli_inflate(tmp_path):
    png, out = tmp_path / "quad.png", tmp_path / "quad.vdb"
    D.write_png(str(png), K.quadruped())
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    r = subprocess.run([sys.executable, "-m", "volrig", "inflate", str(png), str(out), "--pixel-size", "0.5"],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    v = volrig.load(str(out))
    assert v.spacing == (0.5, 0.5, 0.5) and (v.array > 0.5).sum() == volrig.inflate(str(png)).array.sum()
    grids = {g["name"] for g in volrig._volrig.vdb_grids(str(out))}
    assert {"density", "color_r", "color_g", "color_b"} <= grids
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    r = subprocess.run([sys.executable, "-m", "volrig", "inflate", str(bad), str(out)], capture_output=True,
                       text=True, env=env)
    assert r.returncode != 0 and "bad.png" in r.stderr and "Traceback" not in r.stderr

"""OpenVDB reading and writing through Python: round trips, grid types, named grids, bad files, and a check that
Blender (when installed) reads what volrig writes with the geometry volrig means.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_io_vdb.py
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import volrig
from volrig import _volrig

SPACING = (0.5, 1.25, 2.0)
ORIGIN = (-3.0, 4.0, 10.5)


def pattern(shape=(10, 13, 21), dtype=np.float32) -> np.ndarray:
    """[z, y, x] values with about a third zeros and non-zero corners (so the active bbox is the whole grid)."""
    z, y, x = np.indices(shape)
    a = np.where((x + 2 * y + 3 * z) % 3 == 0, 0.0, 0.25 * x - 1.5 * y + 0.75 * z + 0.1).astype(dtype)
    a[0, 0, 0] = 7
    a[-1, -1, -1] = -2
    return a


def test_round_trip_values_spacing_origin(tmp_path):
    a = pattern()
    path = tmp_path / "pattern.vdb"
    volrig.Volume(a, SPACING, ORIGIN).save(path)
    v = volrig.load(path)
    assert v.array.dtype == np.float32
    np.testing.assert_array_equal(v.array, a)
    assert v.spacing == pytest.approx(SPACING)
    assert v.origin == pytest.approx(ORIGIN)
    grids = _volrig.vdb_grids(str(path))
    assert len(grids) == 1
    g = grids[0]
    assert g["name"] == "density" and g["type"] == "float"
    assert g["active_voxels"] == int(np.count_nonzero(a))
    assert g["bbox_min"] == (0, 0, 0)
    assert g["bbox_max"] == (a.shape[2] - 1, a.shape[1] - 1, a.shape[0] - 1)


def test_crop_to_active_bbox_places_voxels_in_world(tmp_path):
    """Reading crops to the active voxels; voxel (x, y, z) stays at origin + spacing * (x, y, z)."""
    a = np.zeros((12, 20, 30), np.float32)
    a[1, 2, 3] = 5.0            # z=1, y=2, x=3
    a[4, 9, 17] = 6.0
    path = tmp_path / "crop.vdb"
    volrig.Volume(a, SPACING, ORIGIN).save(path)
    v = volrig.load(path)
    assert v.dims == (17 - 3 + 1, 9 - 2 + 1, 4 - 1 + 1)
    expected_origin = np.asarray(ORIGIN) + np.asarray(SPACING) * (3, 2, 1)
    assert v.origin == pytest.approx(tuple(expected_origin))
    assert v.array[0, 0, 0] == 5.0 and v.array[-1, -1, -1] == 6.0
    # the world position of the second voxel is the same before and after
    np.testing.assert_allclose(v.world([[3, 7, 14]])[0], np.asarray(ORIGIN) + np.asarray(SPACING) * (17, 9, 4))


def test_half_floats(tmp_path):
    a = pattern((20, 30, 40))
    full, half = tmp_path / "full.vdb", tmp_path / "half.vdb"
    volrig.Volume(a, SPACING, ORIGIN).save(full)
    volrig.Volume(a, SPACING, ORIGIN).save(half, half=True)
    assert half.stat().st_size < full.stat().st_size
    v = volrig.load(half)
    assert v.array.dtype == np.float32
    np.testing.assert_allclose(v.array, a, rtol=1 / 1024, atol=1e-6)
    assert not np.array_equal(v.array, a)  # really stored as half


def test_mixed_float_int_and_mask_grids(tmp_path):
    density = pattern()
    bone = (np.arange(density.size).reshape(density.shape) % 5 - 2).astype(np.int16) * 1000
    mask = density > 0
    path = tmp_path / "mixed.vdb"
    volrig.write_vdb(path, {"density": volrig.Volume(density, SPACING, ORIGIN), "bone": bone, "mask": mask}, half=False)
    types = {g["name"]: g["type"] for g in _volrig.vdb_grids(str(path))}
    assert types == {"density": "float", "bone": "int32", "mask": "float"}

    b = volrig.load(path, grid="bone")
    assert b.array.dtype == np.int32
    # bone's active bbox: the non-zero voxels
    nz = np.argwhere(bone != 0)
    lo, hi = nz.min(0), nz.max(0)
    np.testing.assert_array_equal(b.array, bone[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1])
    assert b.origin == pytest.approx(tuple(np.asarray(ORIGIN) + np.asarray(SPACING) * lo[::-1]))

    m = volrig.load(path, grid="mask")
    assert m.array.dtype == np.float32
    assert set(np.unique(m.array)) <= {0.0, 1.0}
    assert int(m.array.sum()) == int(mask.sum())

    d = volrig.load(path)  # default grid: density
    np.testing.assert_array_equal(d.array, density)


def test_integer_types(tmp_path):
    path = tmp_path / "ints.vdb"
    a = np.zeros((2, 3, 4), np.int64)
    a[0, 0, 0] = -(2 ** 31)
    a[1, 2, 3] = 2 ** 31 - 1
    volrig.write_vdb(path, {"labels": a}, spacing=1, origin=0)
    v = volrig.load(path, grid="labels")
    assert v.array.dtype == np.int32
    np.testing.assert_array_equal(v.array, a)
    a[1, 1, 1] = 2 ** 31
    with pytest.raises(volrig.VolrigError, match=r"2147483648.*\(1, 1, 1\).*int32"):
        volrig.write_vdb(tmp_path / "big.vdb", {"labels": a}, spacing=1, origin=0)
    assert not (tmp_path / "big.vdb").exists()
    u = np.full((2, 2, 2), 7, np.uint16)
    volrig.write_vdb(path, {"labels": u}, spacing=1, origin=0)
    np.testing.assert_array_equal(volrig.load(path, grid="labels").array, u.astype(np.int32))
    # bytes named as labels (a bake's bone labels) are an int32 grid too, not a float one; floats cannot be labels
    b = np.arange(8, dtype=np.uint8).reshape(2, 2, 2) * 36 + 3  # up to 255
    volrig.write_vdb(path, {"bone": b, "mask": b}, spacing=1, origin=0, labels=("bone",))
    assert {g["name"]: g["type"] for g in _volrig.vdb_grids(str(path))} == {"bone": "int32", "mask": "float"}
    np.testing.assert_array_equal(volrig.load(path, grid="bone").array, b.astype(np.int32))
    with pytest.raises(volrig.VolrigError, match="'density': labels are integers"):
        volrig.write_vdb(tmp_path / "f.vdb", {"density": b.astype(np.float32)}, spacing=1, origin=0,
                         labels=("density",))
    assert not (tmp_path / "f.vdb").exists()


def test_grid_selection_and_missing_grid(tmp_path):
    bone = np.zeros((4, 4, 4), np.int32)
    bone[1, 2, 3] = 9
    path = tmp_path / "bone_only.vdb"
    volrig.write_vdb(path, {"bone": bone}, spacing=SPACING, origin=ORIGIN)
    v = volrig.load(path)  # no density: the first scalar grid
    assert v.array.dtype == np.int32 and v.array.shape == (1, 1, 1) and v.array[0, 0, 0] == 9
    with pytest.raises(volrig.FileFormatError, match=r"no grid named 'temperature'.*'bone'"):
        volrig.load(path, grid="temperature")
    with pytest.raises(ValueError):  # FileFormatError is a ValueError
        volrig.load(path, grid="temperature")


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        volrig.load(tmp_path / "missing.vdb")
    garbage = tmp_path / "garbage.vdb"
    garbage.write_bytes(bytes((i * 7919) & 0xFF for i in range(4096)))
    with pytest.raises(volrig.FileFormatError, match="garbage.vdb"):
        volrig.load(garbage)
    with pytest.raises(volrig.FileFormatError, match="garbage.vdb"):
        _volrig.vdb_grids(str(garbage))
    empty = tmp_path / "empty.vdb"
    empty.write_bytes(b"")
    with pytest.raises(volrig.FileFormatError):
        volrig.load(empty)

    good = tmp_path / "good.vdb"
    volrig.write_vdb(good, {"density": pattern((27, 33, 40)), "bone": pattern((27, 33, 40)).astype(np.int32)},
                     spacing=1, origin=0)
    data = good.read_bytes()
    cut = tmp_path / "cut.vdb"
    for n in sorted({5, 40, 200, len(data) // 3, len(data) // 2, len(data) - 100, len(data) - 1}):
        cut.write_bytes(data[:n])
        for grid in ("density", "bone"):
            with pytest.raises(volrig.FileFormatError, match="cut.vdb"):
                volrig.load(cut, grid=grid)


def test_mismatched_geometry_and_bad_names(tmp_path):
    path = tmp_path / "bad.vdb"
    with pytest.raises(volrig.VolrigError, match="lattice"):
        _volrig.write_vdb(str(path), [("density", np.ones((4, 5, 6), np.float32)),
                                      ("bone", np.ones((4, 5, 7), np.int32))], (1, 1, 1), (0, 0, 0), False,
                          [(0, 0, 0), (0.5, 0, 0)])
    with pytest.raises(volrig.VolrigError, match="twice"):
        _volrig.write_vdb(str(path), [("density", np.ones((4, 5, 6), np.float32))] * 2, (1, 1, 1), (0, 0, 0), False)
    with pytest.raises(volrig.VolrigError):
        _volrig.write_vdb(str(path), [("density", np.ones((4, 5), np.float32))], (1, 1, 1), (0, 0, 0), False)
    with pytest.raises(volrig.VolrigError):
        _volrig.write_vdb(str(path), [("density", np.ones((4, 5, 6), np.complex64))], (1, 1, 1), (0, 0, 0), False)
    assert not path.exists()
    assert not list(tmp_path.iterdir())  # no temporary files left behind


def test_non_contiguous_input_and_max_bytes(tmp_path):
    a = pattern((12, 14, 16))
    path = tmp_path / "strided.vdb"
    _volrig.write_vdb(str(path), [("density", a[:, :, ::2])], SPACING, ORIGIN, False)
    np.testing.assert_array_equal(volrig.load(path).array, a[:, :, ::2])
    nbytes = a[:, :, ::2].nbytes
    with pytest.raises(volrig.FileFormatError, match="exceeds"):
        volrig.load(path, max_bytes=nbytes - 1)
    assert volrig.load(path, max_bytes=nbytes).array.shape == (12, 14, 8)


# ---- Blender reads what volrig writes ----------------------------------------------------------------------------

BLENDER_SCRIPT = r"""
import bpy, json, sys
path = sys.argv[sys.argv.index("--") + 1]
vol = bpy.data.volumes.new("phantom")
vol.filepath = path
vol.grids.load()
obj = bpy.data.objects.new("phantom", vol)
bpy.context.scene.collection.objects.link(obj)
bpy.context.view_layer.update()
ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
corners = [tuple(c) for c in ev.bound_box]
print("VOLRIG_RESULT " + json.dumps({
    "error": vol.grids.error_message,
    "grids": {g.name: g.data_type for g in vol.grids},
    "matrix": {g.name: [list(r) for r in g.matrix_object] for g in vol.grids},
    "bbox_min": [min(c[i] for c in corners) for i in range(3)],
    "bbox_max": [max(c[i] for c in corners) for i in range(3)],
}))
"""


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender is not on PATH")
def test_blender_reads_grids_and_geometry(tmp_path):
    # dims are multiples of 8 and the density fills the grid, so Blender's leaf-based bounds are the voxel centres'
    nx, ny, nz = 16, 24, 8
    density = np.ones((nz, ny, nx), np.float32)
    density[2:5, 3:9, 4:12] = 3.5
    bone = np.zeros_like(density, dtype=np.int32)
    bone[1:4, 2:6, 3:7] = 2
    path = tmp_path / "frame_0001.vdb"
    volrig.write_vdb(path, {"density": density, "bone": bone}, spacing=SPACING, origin=ORIGIN, half=True)
    script = tmp_path / "probe.py"
    script.write_text(BLENDER_SCRIPT)
    run = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(script), "--", str(path)],
                         capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": ""})
    lines = [ln for ln in run.stdout.splitlines() if ln.startswith("VOLRIG_RESULT ")]
    assert lines, f"blender printed no result (exit {run.returncode}):\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}"
    r = json.loads(lines[-1][len("VOLRIG_RESULT "):])
    assert not r["error"]
    assert r["grids"] == {"density": "FLOAT", "bone": "INT"}
    lo = np.asarray(ORIGIN)
    hi = lo + np.asarray(SPACING) * (nx - 1, ny - 1, nz - 1)
    np.testing.assert_allclose(r["bbox_min"], lo, atol=1e-4)
    np.testing.assert_allclose(r["bbox_max"], hi, atol=1e-4)
    for name in ("density", "bone"):  # index -> object matrix: diag(spacing), translation origin
        m = np.asarray(r["matrix"][name])
        np.testing.assert_allclose(m[:3, :3], np.diag(SPACING), atol=1e-6)
        np.testing.assert_allclose(m[:3, 3], ORIGIN, atol=1e-6)


def test_write_vdb_stores_half_floats_by_default(tmp_path):
    a = pattern()
    volrig.write_vdb(tmp_path / "default.vdb", {"density": volrig.Volume(a, SPACING, ORIGIN)})
    volrig.write_vdb(tmp_path / "full.vdb", {"density": volrig.Volume(a, SPACING, ORIGIN)}, half=False)
    assert (tmp_path / "default.vdb").stat().st_size < (tmp_path / "full.vdb").stat().st_size
    assert np.allclose(volrig.load(tmp_path / "default.vdb").array, volrig.load(tmp_path / "full.vdb").array, rtol=1e-3)
    # float16 samples (a bake's frames hold them) are the half floats stored: the same grid as from float32
    volrig.write_vdb(tmp_path / "f16.vdb", {"density": volrig.Volume(a.astype(np.float16), SPACING, ORIGIN)}, half=False)
    f16 = volrig.load(tmp_path / "f16.vdb")
    assert f16.array.dtype == np.float32
    np.testing.assert_array_equal(f16.array, volrig.load(tmp_path / "default.vdb").array)
    assert not np.array_equal(f16.array, a)  # (the pattern is not exact in half floats)


def test_grids_of_different_boxes_on_one_lattice(tmp_path):
    """Grids cropped to their own boxes (Volumes with their own origins) lie where they lie."""
    path = str(tmp_path / "boxes.vdb")
    a = volrig.Volume(pattern((6, 8, 10)), SPACING, ORIGIN)
    part = volrig.Volume(pattern((2, 3, 4)), SPACING, tuple(o + 2 * s for o, s in zip(ORIGIN, SPACING)))
    volrig.write_vdb(path, {"density": a, "part": part}, half=False)
    back = volrig.load(path, grid="part")
    np.testing.assert_allclose(back.origin, part.origin)
    np.testing.assert_array_equal(back.array, part.array)
    with pytest.raises(volrig.VolrigError, match="lattice"):
        volrig.write_vdb(path, {"density": a, "part": volrig.Volume(pattern((2, 3, 4)), SPACING, (0.3, 0, 0))})


def test_grids_built_now_written_later_and_in_bricks(tmp_path):
    """build_vdb checks and builds now (the arrays may go), VdbGrids.write writes once; arrays in 8³ bricks
    [brick z, y, x, z, y, x] give the grids of the same volume in C order."""
    from volrig.volume import build_vdb
    rng = np.random.default_rng(4)
    a = np.zeros((24, 16, 32), np.float32)
    a[3:20, 2:13, 5:29] = rng.random((17, 11, 24)).astype(np.float32) + 0.5
    labels = (a > 1.0).astype(np.int16) * 3
    bricks = lambda v: np.ascontiguousarray(v.reshape(3, 8, 2, 8, 4, 8).transpose(0, 2, 4, 1, 3, 5))
    path = tmp_path / "later.vdb"
    grids = build_vdb(path, {"density": bricks(a), "bone": bricks(labels)}, spacing=(0.5, 1, 2), origin=(1, 2, 3),
                      half=False)
    assert not path.exists() and not grids.written
    grids.write(str(path))
    assert grids.written
    with pytest.raises(volrig.VolrigError, match="written already"):
        grids.write(str(path))
    volrig.write_vdb(str(tmp_path / "dense.vdb"), {"density": a, "bone": labels}, spacing=(0.5, 1, 2),
                     origin=(1, 2, 3), half=False)
    for g in ("density", "bone"):
        got, want = volrig.load(str(path), grid=g), volrig.load(str(tmp_path / "dense.vdb"), grid=g)
        assert np.array_equal(got.array, want.array) and np.allclose(got.origin, want.origin), g
    # checked when built: names, and bricks need the brick shape (a 6-D array of other blocks is no volume)
    with pytest.raises(volrig.VolrigError, match="used twice"):
        build_vdb(path, [("d", a), ("d", a)])
    with pytest.raises(volrig.VolrigError, match="3-D"):
        build_vdb(path, {"density": a.reshape(3, 8, 2, 8, 4, 8)[..., :4]})

"""volrig.load / Volume.save: real scans against an independent decode (Python's gzip/zlib + numpy.frombuffer),
round trips, bad files, atomic saves.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_io.py
"""
from __future__ import annotations

import gzip
import os
import struct
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

import volrig
from volrig_support import data_root

DATA = data_root()
requires_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA.resolve()}")


# ---- independent decoders (no volrig code) -------------------------------------------------------------------

MET_TYPES = {"MET_UCHAR": "u1", "MET_CHAR": "i1", "MET_USHORT": "u2", "MET_SHORT": "i2", "MET_UINT": "u4",
             "MET_INT": "i4", "MET_ULONG": "u4", "MET_LONG": "i4", "MET_ULONG_LONG": "u8", "MET_LONG_LONG": "i8",
             "MET_FLOAT": "f4", "MET_DOUBLE": "f8"}
NIFTI_TYPES = {2: "u1", 4: "i2", 8: "i4", 16: "f4", 64: "f8", 256: "i1", 512: "u2", 768: "u4", 1024: "i8", 1280: "u8"}


def decode_metaimage(path: Path):
    raw = path.read_bytes()
    fields, pos = {}, 0
    while True:
        end = raw.index(b"\n", pos)
        key, _, value = raw[pos:end].decode().partition("=")
        fields[key.strip()] = value.strip()
        pos = end + 1
        if key.strip() == "ElementDataFile":
            break
    data = raw[pos:] if fields["ElementDataFile"] == "LOCAL" else (path.parent / fields["ElementDataFile"]).read_bytes()
    if fields.get("CompressedData") == "True":
        data = zlib.decompress(data)
    order = ">" if fields.get("BinaryDataByteOrderMSB", fields.get("ElementByteOrderMSB")) == "True" else "<"
    dims = [int(x) for x in fields["DimSize"].split()]
    arr = np.frombuffer(data, order + MET_TYPES[fields["ElementType"]]).reshape(dims[::-1])
    spacing = tuple(float(x) for x in fields.get("ElementSpacing", "1 1 1").split())
    origin = tuple(float(x) for x in fields.get("Offset", "0 0 0").split())
    return arr, spacing, origin


def decode_nrrd_raw(path: Path):
    raw = path.read_bytes()
    head, _, data = raw.partition(b"\n\n")
    fields = dict(line.split(": ", 1) for line in head.decode().splitlines()[1:] if not line.startswith("#"))
    assert fields["encoding"] == "raw" and fields["type"] in ("uint8_t", "uint8", "uchar")
    dims = [int(x) for x in fields["sizes"].split()]
    return np.frombuffer(data, np.uint8).reshape(dims[::-1])


def decode_nifti_gz(path: Path):
    raw = gzip.decompress(path.read_bytes())
    e = "<" if struct.unpack("<i", raw[:4])[0] == 348 else ">"
    dim = struct.unpack(e + "8h", raw[40:56])
    datatype = struct.unpack(e + "h", raw[70:72])[0]
    pixdim = struct.unpack(e + "8f", raw[76:108])
    vox_offset = int(struct.unpack(e + "f", raw[108:112])[0])
    qform, sform = struct.unpack(e + "2h", raw[252:256])
    if sform > 0:
        srow = struct.unpack(e + "12f", raw[280:328])
        origin = (srow[3], srow[7], srow[11])
    else:
        origin = struct.unpack(e + "3f", raw[268:280])
    if sform > 0 or qform > 0:  # NIfTI's RAS read as LPS
        origin = (-origin[0], -origin[1], origin[2])
    arr = np.frombuffer(raw[vox_offset:], e + NIFTI_TYPES[datatype]).reshape(dim[3], dim[2], dim[1])
    return arr, tuple(abs(p) for p in pixdim[1:4]), tuple(float(o) for o in origin)


# ---- real scans ----------------------------------------------------------------------------------------------

@requires_data
@pytest.mark.parametrize("name", ["frogtissue/frogtissue.mhd", "headmr/HeadMRVolume.mhd", "lidc2/LIDC2.mha"])
def test_metaimage_matches_independent_decode(name):
    path = DATA / name
    ref, spacing, origin = decode_metaimage(path)
    vol = volrig.load(path)
    assert vol.array.dtype == ref.dtype.newbyteorder("=")
    assert vol.array.shape == ref.shape
    np.testing.assert_array_equal(vol.array, ref)
    assert vol.spacing == pytest.approx(spacing)
    assert vol.origin == pytest.approx(origin)
    assert vol.path == str(path)


@requires_data
def test_tooth_nrrd_matches_independent_decode():
    ref = decode_nrrd_raw(DATA / "tooth/tooth.nrrd")
    vol = volrig.load(DATA / "tooth/tooth.nrrd")
    assert vol.dims == (103, 94, 161)
    np.testing.assert_array_equal(vol.array, ref)
    assert vol.spacing == (1.0, 1.0, 1.0)


@requires_data
@pytest.mark.parametrize("name", ["totalseg/example_ct.nii.gz", "totalseg/example_ct_sm.nii.gz",
                                  "totalseg/example_seg.nii.gz", "airway/Patient1_bronchialTree.nii.gz"])
def test_nifti_matches_independent_decode(name):
    path = DATA / name
    ref, spacing, origin = decode_nifti_gz(path)
    vol = volrig.load(path)
    assert vol.array.dtype == ref.dtype.newbyteorder("=")
    assert vol.array.shape == ref.shape
    np.testing.assert_array_equal(vol.array, ref)
    assert vol.spacing == pytest.approx(spacing)
    assert vol.origin == pytest.approx(origin)


@requires_data
def test_real_facts():
    frog = volrig.load(DATA / "frogtissue/frogtissue.mhd")
    assert frog.dims == (500, 470, 136) and frog.spacing == (1.0, 1.0, 1.5)
    assert frog.array.max() >= 20 and len(np.unique(frog.array)) == 26
    seg = volrig.load(DATA / "totalseg/example_seg.nii.gz")
    assert seg.array.min() == 0 and seg.array.max() == 117
    ct = volrig.load(DATA / "totalseg/example_ct.nii.gz")
    assert ct.dims == (122, 101, 112) and ct.array.dtype == np.int32 and ct.spacing == (3.0, 3.0, 3.0)
    lidc = volrig.load(DATA / "lidc2/LIDC2.mha")
    assert lidc.dims == (256, 256, 133)
    assert lidc.spacing == pytest.approx((1.40625, 1.40625, 2.5))


@requires_data
def test_reading_releases_the_gil():
    path = DATA / "airway/Patient1_bronchialTree.nii.gz"
    done = threading.Event()
    ticks = 0

    def read():
        volrig.load(path)
        done.set()

    t = threading.Thread(target=read)
    start = time.perf_counter()
    t.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0)
    t.join()
    elapsed = time.perf_counter() - start
    # While the native reader runs, this thread keeps going (it would stall for the whole read if the GIL were held).
    assert ticks > 100, f"main thread ran {ticks} times in {elapsed:.2f} s"


@requires_data
def test_max_bytes_limit():
    with pytest.raises(volrig.FileFormatError, match="tooth.nrrd.*exceeds the limit of 1000 bytes"):
        volrig.load(DATA / "tooth/tooth.nrrd", max_bytes=1000)


# ---- round trips ---------------------------------------------------------------------------------------------

DTYPES = ["uint8", "int8", "uint16", "int16", "uint32", "int32", "uint64", "int64", "float32", "float64"]


def random_array(dtype, shape=(3, 4, 5), seed=0):
    rng = np.random.default_rng(seed)
    return np.frombuffer(rng.bytes(int(np.prod(shape)) * np.dtype(dtype).itemsize), dtype).reshape(shape).copy()


@pytest.mark.parametrize("ending", [".nrrd", ".mha"])
@pytest.mark.parametrize("compress", [True, False])
@pytest.mark.parametrize("dtype", DTYPES)
def test_save_load_round_trip(tmp_path, ending, compress, dtype):
    arr = random_array(dtype, seed=DTYPES.index(dtype))
    vol = volrig.Volume(arr, spacing=(0.5, 0.1, 3.0), origin=(-12.25, 1e-3, 400.0))
    path = tmp_path / f"v{ending}"
    vol.save(path, compress=compress)
    back = volrig.load(path)
    assert back.array.dtype == arr.dtype
    assert back.array.tobytes() == arr.tobytes()  # bitwise (NaN payloads included)
    assert back.spacing == vol.spacing and back.origin == vol.origin
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_save_bool_and_non_contiguous(tmp_path):
    mask = np.zeros((4, 5, 6), bool)
    mask[1:3, 2:4, ::2] = True
    volrig.Volume(mask).save(tmp_path / "m.nrrd")
    back = volrig.load(tmp_path / "m.nrrd")
    assert back.array.dtype == np.uint8
    np.testing.assert_array_equal(back.array, mask)
    arr = random_array("int16", (6, 5, 4)).transpose(2, 1, 0)  # not C-contiguous
    volrig.Volume(arr).save(tmp_path / "t.mha")
    np.testing.assert_array_equal(volrig.load(tmp_path / "t.mha").array, arr)


def test_raw_files(tmp_path):
    arr = random_array("float32", (2, 3, 4))
    (tmp_path / "v.raw").write_bytes(b"HEADER" + arr.astype(">f4").tobytes())
    vol = volrig.load(tmp_path / "v.raw", dims=(4, 3, 2), dtype=np.float32, byte_order="big", offset=6,
                      spacing=(1, 2, 3), origin=(4, 5, 6))
    assert vol.array.tobytes() == arr.tobytes()
    assert vol.spacing == (1, 2, 3) and vol.origin == (4, 5, 6)
    with pytest.raises(volrig.FileFormatError, match=r"v\.raw: the layout says 4x3x3 float32 = 144 bytes"):
        volrig.load(tmp_path / "v.raw", dims=(4, 3, 3), dtype="float32")


# ---- bad files -----------------------------------------------------------------------------------------------

BAD_FILES = {
    "truncated.nrrd": b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 10 10\nencoding: raw\n\n" + bytes(999),
    "garbage.nrrd": bytes(range(256)) * 4,
    "bomb.nrrd": b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 10 10\nencoding: gzip\n\n"
                 + gzip.compress(bytes(10 << 20)),
    "huge.nrrd": b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100000 1000 1000\nencoding: gzip\n\n"
                 + gzip.compress(bytes(1000)),
    "garbage.nii": bytes(range(256)) * 4,
    "garbage.nii.gz": gzip.compress(bytes(range(256)) * 4),
    "empty.mha": b"",
    "nodata.mha": b"NDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
    "badzlib.mha": b"NDims = 3\nDimSize = 4 4 4\nCompressedData = True\nElementType = MET_UCHAR\n"
                   b"ElementDataFile = LOCAL\nnot zlib",
    "nan.mha": b"NDims = 3\nDimSize = 1 1 1\nElementSpacing = 1 nan 1\nElementType = MET_UCHAR\n"
               b"ElementDataFile = LOCAL\n\x00",
    "missingdata.mhd": b"NDims = 3\nDimSize = 1 1 1\nElementType = MET_UCHAR\nElementDataFile = nothere.raw\n",
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_files_raise_file_format_error_naming_the_file(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(BAD_FILES[name])
    expected = FileNotFoundError if name == "missingdata.mhd" else volrig.FileFormatError
    with pytest.raises(expected) as err:
        volrig.load(path)
    assert name in str(err.value)
    assert issubclass(volrig.FileFormatError, ValueError)


def test_missing_file_raises_file_not_found(tmp_path):
    for name in ("nope.nrrd", "nope.mha", "nope.nii.gz", "nope.raw"):
        with pytest.raises(FileNotFoundError, match=name):
            volrig.load(tmp_path / name, **({"dims": (1, 1, 1), "dtype": "uint8"} if name.endswith(".raw") else {}))


# ---- saves never leave partial files -------------------------------------------------------------------------

def test_save_into_missing_folder_raises_and_leaves_nothing(tmp_path):
    vol = volrig.Volume(np.zeros((2, 2, 2), np.uint8))
    for ending in (".nrrd", ".mha"):
        with pytest.raises(FileNotFoundError, match="missing"):
            vol.save(tmp_path / "missing" / f"x{ending}")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root ignores folder permissions")
def test_save_into_read_only_folder_raises_and_leaves_nothing(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises((OSError, volrig.VolrigError)):
            volrig.Volume(np.zeros((2, 2, 2), np.uint8)).save(ro / "x.nrrd")
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o700)


def test_failed_save_keeps_the_old_file(tmp_path):
    path = tmp_path / "keep.nrrd"
    path.write_bytes(b"old contents")
    with pytest.raises((TypeError, ValueError)):
        volrig.Volume(np.zeros((2, 2, 2), np.complex64)).save(path)
    assert path.read_bytes() == b"old contents"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.nrrd"]
    # Target is a folder: the rename fails, the temporary file is removed.
    (tmp_path / "dir.mha").mkdir()
    (tmp_path / "dir.mha" / "inside").write_bytes(b"x")
    with pytest.raises(volrig.VolrigError, match="dir.mha"):
        volrig.Volume(np.zeros((2, 2, 2), np.uint8)).save(tmp_path / "dir.mha")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.mha", "keep.nrrd"]

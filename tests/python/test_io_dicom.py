"""DICOM series through GDCM (volrig.load on folders, DICOMDIR-less folders, single files; volrig.dicom_series;
``volrig info``): series written here with pydicom, shuffled, oblique, rescaled, compressed, and broken."""
import json
import os
import random
import shutil
import subprocess

import numpy as np
import pytest

import volrig
from volrig.cli import main as cli

pydicom = pytest.importorskip("pydicom")
from pydicom.dataset import FileDataset, FileMetaDataset  # noqa: E402
from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, RLELossless, generate_uid  # noqa: E402

ROW = np.array([0.0, 1.0, 0.0])     # oblique-free but not axial: a sagittal stack
COL = np.array([0.0, 0.0, -1.0])
NORMAL = np.cross(ROW, COL)         # (-1, 0, 0)
ORIGIN = np.array([12.5, -40.0, 80.0])


def raw_slices(n=6, rows=7, cols=8):
    """uint16 stored values [n, rows, cols]: HU = value - 1024 differs in every voxel."""
    v = np.arange(n * rows * cols, dtype=np.int64).reshape(n, rows, cols) * 3 + 500
    return v.astype(np.uint16)


def write_slice(path, pixels, k, *, gap=2.5, series_uid, description="CT body", modality="CT", slope=1.0,
                intercept=-1024.0, row=ROW, col=COL, pixel_spacing=(0.7, 0.6), position=None, rle=False):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = CTImageStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.is_little_endian, ds.is_implicit_VR = True, False
    ds.SOPClassUID, ds.SOPInstanceUID = CTImageStorage, meta.MediaStorageSOPInstanceUID
    ds.StudyInstanceUID, ds.SeriesInstanceUID = "1.2.3.4", series_uid
    ds.Modality, ds.SeriesDescription, ds.InstanceNumber = modality, description, k + 1
    normal = np.cross(row, col)
    pos = ORIGIN + k * gap * normal if position is None else np.asarray(position)
    ds.ImagePositionPatient = [float(x) for x in pos]
    ds.ImageOrientationPatient = [float(x) for x in (*row, *col)]
    ds.PixelSpacing = list(pixel_spacing)   # row spacing (y), column spacing (x)
    ds.SliceThickness = 9.0                 # deliberately wrong: spacing comes from the positions
    ds.Rows, ds.Columns = pixels.shape
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 0
    ds.RescaleSlope, ds.RescaleIntercept = slope, intercept
    if rle:
        ds.compress(RLELossless, np.ascontiguousarray(pixels))
    else:
        ds.PixelData = np.ascontiguousarray(pixels).tobytes()
    ds.save_as(str(path), write_like_original=False)


def write_series(folder, pixels=None, *, shuffle=True, names=None, **kw):
    """A series in ``folder`` under random names, in random order; returns (pixels, uid)."""
    pixels = raw_slices() if pixels is None else pixels
    uid = kw.pop("series_uid", None) or generate_uid()
    os.makedirs(folder, exist_ok=True)
    order = list(range(len(pixels)))
    if shuffle:
        random.Random(7).shuffle(order)
    for i, k in enumerate(order):
        name = names[i] if names else f"IM{random.Random(uid + str(k)).randrange(10**8):08d}"
        write_slice(os.path.join(folder, name), pixels[k], k, series_uid=uid, **kw)
    return pixels, uid


def test_sagittal_series_sorted_spaced_rescaled_oriented(tmp_path):
    pixels, _ = write_series(tmp_path / "ct")
    v = volrig.load(str(tmp_path / "ct"))
    assert v.array.dtype == np.int16
    assert v.array.shape == pixels.shape                     # [slices, rows, columns] = [z, y, x]
    np.testing.assert_array_equal(v.array, pixels.astype(np.int32) - 1024)
    assert v.spacing == pytest.approx((0.6, 0.7, 2.5))       # columns, rows, the gap (not SliceThickness 9)
    assert v.origin == pytest.approx(tuple(ORIGIN))
    np.testing.assert_allclose(v.direction, np.column_stack([ROW, COL, NORMAL]), atol=1e-9)
    # voxel (x, y, z) sits at origin + x*0.6*row + y*0.7*col + z*2.5*normal (LPS)
    p = v.patient([[5, 3, 2]])[0]
    np.testing.assert_allclose(p, ORIGIN + 2 * 0.6 * ROW + 3 * 0.7 * COL + 5 * 2.5 * NORMAL)
    m = v.index_to_world()
    np.testing.assert_allclose(m @ [2, 3, 5, 1], [*p, 1])


def test_slices_given_in_reverse_normal_order_and_single_file(tmp_path):
    pixels, _ = write_series(tmp_path / "ct", gap=-1.25, shuffle=False)   # positions decrease along the normal
    v = volrig.load(str(tmp_path / "ct"))
    np.testing.assert_array_equal(v.array, pixels[::-1].astype(np.int32) - 1024)
    assert v.spacing[2] == pytest.approx(1.25)
    assert v.origin == pytest.approx(tuple(ORIGIN - 5 * 1.25 * NORMAL))
    one = sorted(os.listdir(tmp_path / "ct"))[0]
    s = volrig.load(str(tmp_path / "ct" / one))   # no ending: found by its preamble
    assert s.array.shape == (1, 7, 8)


def test_rescale_to_float_when_not_integral(tmp_path):
    pixels, _ = write_series(tmp_path / "ct", slope=0.5, intercept=-10.25)
    v = volrig.load(str(tmp_path / "ct"))
    assert v.array.dtype == np.float32
    np.testing.assert_allclose(v.array, pixels * 0.5 - 10.25)


def test_rle_compressed_series_is_decoded(tmp_path):
    pixels, _ = write_series(tmp_path / "rle", rle=True)
    assert pydicom.dcmread(str(next((tmp_path / "rle").iterdir()))).file_meta.TransferSyntaxUID == RLELossless
    v = volrig.load(str(tmp_path / "rle"))
    np.testing.assert_array_equal(v.array, pixels.astype(np.int32) - 1024)


@pytest.mark.skipif(shutil.which("gdcmconv") is None, reason="gdcmconv (libgdcm-tools) not installed")
@pytest.mark.parametrize("flag", ["--jpeg", "--jpegls", "--j2k"])
def test_lossless_jpeg_series_from_gdcmconv(tmp_path, flag):
    pixels, _ = write_series(tmp_path / "raw", shuffle=False, names=[f"s{k}.dcm" for k in range(6)])
    os.makedirs(tmp_path / "c")
    for k in range(6):
        subprocess.run(["gdcmconv", flag, str(tmp_path / "raw" / f"s{k}.dcm"), str(tmp_path / "c" / f"s{k}.dcm")],
                       check=True)  # lossless unless --lossy
    ts = pydicom.dcmread(str(tmp_path / "c" / "s0.dcm")).file_meta.TransferSyntaxUID
    assert ts != ExplicitVRLittleEndian
    v = volrig.load(str(tmp_path / "c"))
    np.testing.assert_array_equal(v.array, pixels.astype(np.int32) - 1024)


def test_several_series_largest_by_default_uid_picks(tmp_path):
    big, big_uid = write_series(tmp_path / "study", description="big")
    small, small_uid = write_series(tmp_path / "study", pixels=raw_slices(n=3, rows=4, cols=5) + 7,
                                    description="scout", modality="MR")
    listed = volrig.dicom_series(str(tmp_path / "study"))
    assert [s["uid"] for s in listed] == [big_uid, small_uid]
    assert listed[1]["dims"] == (5, 4, 3) and listed[1]["modality"] == "MR" and listed[1]["description"] == "scout"
    assert volrig.load(str(tmp_path / "study")).array.shape == big.shape
    v = volrig.load(str(tmp_path / "study"), series=small_uid)
    np.testing.assert_array_equal(v.array, small.astype(np.int32) - 1024)
    with pytest.raises(volrig.FileFormatError, match="no series with SeriesInstanceUID '9.9'"):
        volrig.load(str(tmp_path / "study"), series="9.9")


def test_cli_info_lists_the_series(tmp_path, capsys):
    _, uid = write_series(tmp_path / "study", description="big")
    write_series(tmp_path / "study", pixels=raw_slices(n=2), description="scout")
    assert cli(["info", str(tmp_path / "study")]) == 0
    out = capsys.readouterr().out
    assert "2 DICOM series" in out and uid in out and "'scout'" in out and "6 slices of 8 x 7" in out
    assert "direction (LPS" in out
    assert cli(["info", "--json", str(tmp_path / "study")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["series"][0]["uid"] == uid and info["series"][0]["slices"] == 6


def test_missing_slice_is_refused(tmp_path):
    write_series(tmp_path / "ct")
    victim = sorted((tmp_path / "ct").iterdir(), key=lambda p: pydicom.dcmread(str(p)).InstanceNumber)[3]
    victim.unlink()
    with pytest.raises(volrig.FileFormatError, match=r"incomplete series: no slice at 7.5 mm \(5, -40, 80\) \(along "
                                                      r"the slice normal from .*\) where the others are 2.5 mm apart"):
        volrig.load(str(tmp_path / "ct"))


def test_small_jitter_warns_what_was_assumed(tmp_path):
    pixels = raw_slices(n=4)
    uid = generate_uid()
    os.makedirs(tmp_path / "ct")
    for k, z in enumerate([0.0, 2.5, 5.01, 7.5]):
        write_slice(tmp_path / "ct" / f"{k}.dcm", pixels[k], k, series_uid=uid, position=ORIGIN + z * NORMAL)
    with pytest.warns(UserWarning, match=r"slice gaps vary from 2.49 mm to 2.51 mm; assumed the mean 2.5 mm"):
        v = volrig.load(str(tmp_path / "ct"))
    assert v.spacing[2] == pytest.approx(2.5)


def test_mixed_sizes_and_orientations_are_refused(tmp_path):
    uid = generate_uid()
    os.makedirs(tmp_path / "sizes")
    write_slice(tmp_path / "sizes" / "a.dcm", raw_slices()[0], 0, series_uid=uid)
    write_slice(tmp_path / "sizes" / "b.dcm", raw_slices(rows=6)[1], 1, series_uid=uid)
    with pytest.raises(volrig.FileFormatError, match="mixed slice sizes: a.dcm is 8x7, b.dcm is 8x6"):
        volrig.load(str(tmp_path / "sizes"))
    os.makedirs(tmp_path / "turned")
    write_slice(tmp_path / "turned" / "a.dcm", raw_slices()[0], 0, series_uid=uid)
    write_slice(tmp_path / "turned" / "b.dcm", raw_slices()[1], 1, series_uid=uid, row=np.array([1.0, 0, 0]))
    with pytest.raises(volrig.FileFormatError, match="mixed orientations"):
        volrig.load(str(tmp_path / "turned"))


def test_gantry_tilt_and_repeated_positions_are_refused(tmp_path):
    uid = generate_uid()
    os.makedirs(tmp_path / "tilt")
    for k in range(3):
        write_slice(tmp_path / "tilt" / f"{k}.dcm", raw_slices()[k], k, series_uid=uid,
                    position=ORIGIN + k * 2.5 * NORMAL + k * 1.0 * COL)
    with pytest.raises(volrig.FileFormatError, match="not on the slice normal"):
        volrig.load(str(tmp_path / "tilt"))
    os.makedirs(tmp_path / "twice")
    for k in range(2):
        write_slice(tmp_path / "twice" / f"{k}.dcm", raw_slices()[k], k, series_uid=uid, position=ORIGIN)
    with pytest.raises(volrig.FileFormatError, match="lie at the same position"):
        volrig.load(str(tmp_path / "twice"))


def test_not_dicom(tmp_path):
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notes.txt").write_text("hello")
    with pytest.raises(volrig.FileFormatError, match="no DICOM images found"):
        volrig.load(str(tmp_path / "junk"))
    bad = tmp_path / "bad.dcm"
    bad.write_bytes(b"\0" * 128 + b"DICM" + b"\x02\x00\x10\x00UI\xff\xff")
    with pytest.raises(volrig.FileFormatError, match="bad.dcm"):
        volrig.load(str(bad))

"""Hostile and careless input (issue 55): files that crashed the process, hung it, or loaded as a wrong volume.

Reads that could kill the process run in a subprocess here, so a crash fails the test instead of killing pytest.
Each crash test also reads the same file with the decoder's isolation turned off (VOLRIG_ISOLATE=0) and checks that
it does crash that way: the file really is one the decoder dies on.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest -q tests/python/test_hostile.py
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import volrig

PYTHON_DIR = str(Path(volrig.__file__).resolve().parents[1])

READ = """
import sys, volrig
try:
    volrig.load(sys.argv[1])
    print("LOADED")
except volrig.VolrigError as e:
    print(type(e).__name__ + ": " + str(e))
"""


def read_in_child(path, isolate=True, code=READ, timeout=60):
    """(returncode, stdout) of reading ``path`` with volrig.load in a fresh Python."""
    env = dict(os.environ, PYTHONPATH=PYTHON_DIR)
    if not isolate:
        env["VOLRIG_ISOLATE"] = "0"
    r = subprocess.run([sys.executable, "-c", code, str(path)], env=env, capture_output=True, text=True,
                       timeout=timeout)
    return r.returncode, r.stdout.strip()


# ---- DICOM: a JPEG stream GDCM's decoder aborts on ---------------------------------------------------------------

def broken_jpeg_dicom(path, first_fragment=b"\xff\xd8" + b"\0" * 62):
    """A JPEG Lossless DICOM slice whose only fragment is SOI followed by zeros (GDCM asserts precision >= 1)."""
    pydicom = pytest.importorskip("pydicom")
    from pydicom.encaps import encapsulate
    from pydicom.uid import generate_uid
    from test_dicom import write_slice

    write_slice(path, np.zeros((7, 8), np.uint16), 0, series_uid=generate_uid())
    ds = pydicom.dcmread(str(path))
    ds.file_meta.TransferSyntaxUID = "1.2.840.10008.1.2.4.70"  # JPEG Lossless, first-order prediction
    ds.PixelData = encapsulate([first_fragment])
    ds["PixelData"].is_undefined_length = True
    ds["PixelData"].VR = "OB"
    ds.save_as(str(path), write_like_original=False)
    return path


def test_jpeg_dicom_that_aborts_gdcm_is_a_file_format_error(tmp_path):
    f = broken_jpeg_dicom(tmp_path / "broken.dcm")
    rc, out = read_in_child(f, isolate=False)
    assert rc != 0, "GDCM no longer aborts on this file: the reproduction is gone"
    rc, out = read_in_child(f)
    assert rc == 0, out
    assert out.startswith(f"FileFormatError: {f}: GDCM's decoder crashed on this file (killed by signal 6")
    assert "precision" in out  # GDCM's failed assertion, from the child's stderr


def test_jpeg_dicom_folder_and_cli_survive(tmp_path):
    folder = tmp_path / "series"
    folder.mkdir()
    broken_jpeg_dicom(folder / "a.dcm")
    rc, out = read_in_child(folder)
    assert rc == 0 and out.startswith(f"FileFormatError: {folder / 'a.dcm'}: GDCM's decoder crashed"), out
    code = "import sys; from volrig.cli import main; sys.exit(main(['info', sys.argv[1]]))"
    env = dict(os.environ, PYTHONPATH=PYTHON_DIR)
    r = subprocess.run([sys.executable, "-c", code, str(folder)], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.startswith("error: ") and "crashed on this file" in r.stderr, r.stderr


def test_valid_jpeg_still_decodes_in_the_child(tmp_path):
    """The isolated path gives the same voxels, geometry and warnings as before (gdcmconv's lossless JPEG)."""
    import shutil
    if shutil.which("gdcmconv") is None:
        pytest.skip("gdcmconv (libgdcm-tools) not installed")
    pytest.importorskip("pydicom")
    from test_dicom import raw_slices, write_series
    pixels = raw_slices()
    write_series(tmp_path / "raw", pixels, shuffle=False, names=[f"s{k}.dcm" for k in range(6)])
    (tmp_path / "c").mkdir()
    for k in range(6):
        subprocess.run(["gdcmconv", "--jpeg", str(tmp_path / "raw" / f"s{k}.dcm"), str(tmp_path / "c" / f"s{k}.dcm")],
                       check=True)
    a, b = volrig.load(str(tmp_path / "raw")), volrig.load(str(tmp_path / "c"))
    np.testing.assert_array_equal(a.array, b.array)
    assert a.spacing == b.spacing and a.origin == b.origin
    one = volrig.load(str(tmp_path / "c" / "s3.dcm"))
    np.testing.assert_array_equal(one.array[0], a.array[3])


# ---- OpenVDB: one flipped bit that makes OpenVDB 10 overrun the heap -----------------------------------------------

# Bit flips (byte, bit) of the file below that segfault OpenVDB 10.0 (found by flipping 1,000 random bits).
VDB_FLIPS = [(1718, 3), (2368, 6), (2827, 5), (3801, 7)]


def sparse_half_vdb(path):
    a = np.random.default_rng(1).random((40, 36, 30)).astype(np.float32)
    a[a < 0.5] = 0
    volrig.Volume(a, (1, 1, 1), (0, 0, 0)).save(str(path), half=True)
    return path.read_bytes()


def test_vdb_flips_that_corrupt_the_heap_are_file_format_errors(tmp_path):
    data = sparse_half_vdb(tmp_path / "good.vdb")
    crashed_unisolated = 0
    for pos, bit in VDB_FLIPS:
        b = bytearray(data)
        b[pos] ^= 1 << bit
        f = tmp_path / f"flip_{pos}_{bit}.vdb"
        f.write_bytes(bytes(b))
        rc, out = read_in_child(f, isolate=False)
        crashed_unisolated += rc != 0
        rc, out = read_in_child(f)
        assert rc == 0, (pos, bit, out)
        assert out.startswith(f"FileFormatError: {f}: "), out
        # The grid list (header and stats metadata, read in a child too) is intact: one float grid.
        assert [g["name"] for g in volrig._volrig.vdb_grids(str(f))] == ["density"]
    assert crashed_unisolated >= 1, "OpenVDB no longer crashes on these flips: the reproduction is gone"


def test_vdb_still_reads_through_the_child(tmp_path):
    sparse_half_vdb(tmp_path / "good.vdb")
    v = volrig.load(str(tmp_path / "good.vdb"))
    a = np.random.default_rng(1).random((40, 36, 30)).astype(np.float32)
    a[a < 0.5] = 0
    np.testing.assert_allclose(v.array, a, atol=1e-3)

"""TIFF stacks through libtiff (volrig.load on multi-page files and folders of numbered files), written with
Pillow."""
import numpy as np
import pytest

import volrig

Image = pytest.importorskip("PIL.Image")


def test_multipage_uint16_with_dpi(tmp_path):
    pages = [np.arange(12, dtype=np.uint16).reshape(3, 4) * 100 + k for k in range(5)]
    ims = [Image.fromarray(p) for p in pages]
    ims[0].save(tmp_path / "s.tif", save_all=True, append_images=ims[1:], dpi=(254, 127))
    v = volrig.load(str(tmp_path / "s.tif"))
    assert v.array.dtype == np.uint16 and v.array.shape == (5, 3, 4)
    np.testing.assert_array_equal(v.array, np.stack(pages))
    assert v.spacing == pytest.approx((0.1, 0.2, 0.1))  # 254 and 127 dpi; z = x
    assert volrig.load(str(tmp_path / "s.tif"), spacing=(0, 0, 1.5)).spacing == pytest.approx((0.1, 0.2, 1.5))
    assert volrig.load(str(tmp_path / "s.tif"), spacing=2).spacing == (2, 2, 2)
    assert v.axis_aligned


def test_folder_in_natural_order_float32(tmp_path):
    for k in (1, 2, 10, 11, 3):
        Image.fromarray(np.full((2, 3), k / 2, np.float32)).save(tmp_path / f"img_{k}.tiff")
    (tmp_path / "Thumbs.db").write_bytes(b"not an image")   # other files do not make it a DICOM folder
    v = volrig.load(str(tmp_path))
    assert v.array.dtype == np.float32
    np.testing.assert_array_equal(v.array[:, 0, 0], np.array([1, 2, 3, 10, 11]) / 2)


def test_mismatched_pages_are_refused(tmp_path):
    Image.fromarray(np.zeros((2, 3), np.uint8)).save(tmp_path / "a1.tif")
    Image.fromarray(np.zeros((2, 4), np.uint8)).save(tmp_path / "a2.tif")
    with pytest.raises(volrig.FileFormatError, match="a2.tif: page 1 is 4x2 uint8 where the first page is 3x2"):
        volrig.load(str(tmp_path))
    Image.fromarray(np.zeros((2, 3, 3), np.uint8)).save(tmp_path / "rgb.tif")
    with pytest.raises(volrig.FileFormatError, match="rgb.tif: page 1: 3 samples per pixel"):
        volrig.load(str(tmp_path / "rgb.tif"))


def test_cli_info_on_a_stack(tmp_path, capsys):
    from volrig.cli import main
    Image.fromarray(np.ones((2, 3), np.uint8)).save(tmp_path / "one.tif")
    assert main(["info", "--tiff-spacing", "0.5", "0.5", "3", str(tmp_path / "one.tif")]) == 0
    assert "3 x 2 x 1 uint8, spacing (0.5, 0.5, 3.0)" in capsys.readouterr().out

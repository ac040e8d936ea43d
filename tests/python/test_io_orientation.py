"""Orientation: Volume.direction, index_to_world / grid_to_world, and one phantom saved with permuted and flipped
axes (NRRD, MetaImage, NIfTI) giving the same voxels at the same patient positions."""
import struct

import numpy as np
import pytest

import volrig
from volrig import Volume


def rotation(deg_z, deg_x):
    a, b = np.radians(deg_z), np.radians(deg_x)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return rx @ rz


def phantom():
    rng = np.random.default_rng(5)
    a = np.zeros((4, 5, 6), np.uint16)  # [z, y, x]
    mask = rng.random(a.shape) < 0.5
    a[mask] = np.arange(1, mask.sum() + 1)
    return Volume(a, (0.5, 0.75, 1.25), (10.0, -20.0, 30.0), direction=rotation(25, 10))


def permuted(v, perm, flip):
    """New axis a (x, y, z) = old axis perm[a], reversed when flip[a]; geometry keeps every voxel's position."""
    arr = v.array.transpose(2, 1, 0)            # [x, y, z]
    arr = arr.transpose(perm)
    for a in range(3):
        if flip[a]:
            arr = np.flip(arr, axis=a)
    first = np.zeros(3)
    for a in range(3):
        first[perm[a]] = v.dims[perm[a]] - 1 if flip[a] else 0
    direction = np.column_stack([v.direction[:, perm[a]] * (-1 if flip[a] else 1) for a in range(3)])
    origin = v.origin + v.direction @ (np.asarray(v.spacing) * first)
    return Volume(np.ascontiguousarray(arr.transpose(2, 1, 0)), tuple(np.asarray(v.spacing)[list(perm)]),
                  tuple(origin), direction=direction)


def positions(v):
    """value -> patient position of every non-empty voxel."""
    zyx = np.argwhere(v.array)
    return dict(zip(v.array[tuple(zyx.T)].tolist(), v.patient(zyx)))


def write_nifti(path, v):
    """A NIfTI-1 file with the volume's geometry as its sform (RAS: x and y negated)."""
    h = bytearray(352)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, *v.dims, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, 512, 16)
    struct.pack_into("<8f", h, 76, 1, *v.spacing, 1, 1, 1, 1)
    struct.pack_into("<f", h, 108, 352)
    struct.pack_into("<h", h, 254, 2)
    affine = v.index_to_world()[:3] * np.array([[-1], [-1], [1]])
    struct.pack_into("<12f", h, 280, *affine.ravel())
    h[344:348] = b"n+1\0"
    with open(path, "wb") as f:
        f.write(bytes(h) + v.array.astype("<u2").tobytes())


def test_matrices():
    v = phantom()
    m = v.index_to_world()
    np.testing.assert_allclose(m[:3, :3], v.direction @ np.diag(v.spacing))
    np.testing.assert_allclose(m @ [1, 2, 3, 1], [*v.patient([[3, 2, 1]])[0], 1])
    # grid frame (where skeletons and rigs live) -> patient
    g = v.grid_to_world()
    np.testing.assert_allclose(g @ [*v.world([[3, 2, 1]])[0], 1], [*v.patient([[3, 2, 1]])[0], 1])
    assert Volume(v.array).axis_aligned and not v.axis_aligned
    np.testing.assert_allclose(Volume(v.array).grid_to_world(), np.eye(4))
    with pytest.raises(volrig.VolrigError, match="orthonormal"):
        Volume(v.array, direction=[[1, 1, 0], [0, 1, 0], [0, 0, 1]])
    assert "direction=" in repr(v)


@pytest.mark.parametrize("perm", [(0, 1, 2), (2, 0, 1), (1, 2, 0), (2, 1, 0)])
@pytest.mark.parametrize("flip", [(False, False, False), (True, False, True), (False, True, False)])
def test_permuted_and_flipped_copies_agree_in_every_format(tmp_path, perm, flip):
    base = phantom()
    want = positions(base)
    v = permuted(base, perm, flip)
    for value, p in positions(v).items():
        np.testing.assert_allclose(p, want[value], atol=1e-9)
    v.save(str(tmp_path / "v.nrrd"))
    v.save(str(tmp_path / "v.mha"))
    write_nifti(str(tmp_path / "v.nii"), v)
    for name, tol in (("v.nrrd", 1e-9), ("v.mha", 1e-9), ("v.nii", 1e-4)):
        back = volrig.load(str(tmp_path / name))
        got = positions(back)
        assert got.keys() == want.keys()
        worst = max(np.abs(got[k] - want[k]).max() for k in want)
        assert worst < tol, name


def test_info_shows_the_direction(tmp_path, capsys):
    from volrig.cli import main
    phantom().save(str(tmp_path / "p.nrrd"))
    assert main(["info", str(tmp_path / "p.nrrd")]) == 0
    assert "direction (LPS, columns x y z)" in capsys.readouterr().out


def test_the_same_volume_as_a_dicom_series_and_a_tiff_stack(tmp_path):
    # The acceptance of issue 24: the oriented phantom as a DICOM series (ImageOrientationPatient, positions) gives
    # the same voxels at the same patient positions as the NRRD; as a TIFF stack (no orientation, no origin) the
    # same voxels on the same lattice.
    pytest.importorskip("pydicom")
    from test_io_dicom import write_slice
    v = phantom()
    want = positions(v)
    folder = tmp_path / "series"
    folder.mkdir()
    d, s = v.direction, np.asarray(v.spacing)
    for k in range(v.dims[2]):
        write_slice(folder / f"s{k:03d}.dcm", v.array[k], k, series_uid="1.2.826.0.1.3680043.2.1125.1",
                    row=d[:, 0], col=d[:, 1], pixel_spacing=(s[1], s[0]), gap=s[2], intercept=0.0,
                    position=np.asarray(v.origin) + d[:, 2] * s[2] * k)
    back = volrig.load(str(folder))
    got = positions(back)
    assert got.keys() == want.keys()
    assert max(np.abs(got[k] - want[k]).max() for k in want) < 1e-4
    from PIL import Image
    pages = [Image.fromarray(v.array[k].astype(np.uint16)) for k in range(v.dims[2])]
    pages[0].save(tmp_path / "stack.tif", save_all=True, append_images=pages[1:])
    tif = volrig.load(str(tmp_path / "stack.tif"), spacing=v.spacing)
    np.testing.assert_array_equal(tif.array, v.array)
    assert tif.spacing == pytest.approx(v.spacing) and tif.axis_aligned

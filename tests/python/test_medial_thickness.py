"""Local thickness (volrig.local_thickness, volrig thickness): against a brute-force numpy reference on small random
shapes and anisotropic grids, on shells and bent plates of known thickness, on real bone."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import volrig
from conftest import shared

REPO = Path(__file__).resolve().parents[2]


def brute_thickness(mask, spacing):
    """max over object voxels c with |p - c|^2 < DT(c)^2 (1 - 5e-7) of 2 DT(c): the definition (reconstruct's
    open ball), O(N^2)."""
    dt = volrig.distance_transform(volrig.Volume(mask, spacing))
    zz, yy, xx = np.indices(mask.shape)
    sx, sy, sz = spacing
    out = np.zeros(mask.shape, np.float32)
    for c in zip(*np.nonzero(mask)):
        r = float(dt[c])
        lim = r * r * (1.0 - 5e-7)
        rest = lim - ((yy - c[1]) ** 2) * sy * sy - ((zz - c[0]) ** 2) * sz * sz
        inside = ((xx - c[2]) ** 2) * sx * sx < rest
        out[inside] = np.maximum(out[inside], np.float32(2.0) * np.float32(r))
    return out


@pytest.mark.parametrize("seed", range(6))
def test_equals_brute_force_on_random_shapes(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(int(s) for s in rng.integers(4, 13, 3))
    spacing = (1.0, 1.0, 1.0) if seed % 2 == 0 else tuple(float(s) for s in rng.uniform(0.5, 2.0, 3))
    zz, yy, xx = np.indices(shape)
    mask = np.zeros(shape, bool)
    for _ in range(3):
        c = rng.uniform(0, 1, 3) * shape
        r = rng.uniform(1.5, 5)
        mask |= (zz - c[0]) ** 2 + (yy - c[1]) ** 2 + (xx - c[2]) ** 2 < r * r
    mask ^= rng.uniform(size=shape) < 0.03
    got = volrig.local_thickness(volrig.Volume(mask, spacing))
    assert got.array.dtype == np.float32 and got.spacing == spacing
    np.testing.assert_array_equal(got.array, brute_thickness(mask, spacing))


def shell(shape, spacing, centre, r_in, r_out):
    """A spherical shell r_in <= |p - centre| < r_out in world units."""
    z, y, x = np.indices(shape)
    d = np.sqrt(((x * spacing[0] - centre[0]) ** 2) + ((y * spacing[1] - centre[1]) ** 2)
                + ((z * spacing[2] - centre[2]) ** 2))
    return (d >= r_in) & (d < r_out)


def test_shell_of_known_thickness_on_an_anisotropic_grid():
    spacing = (0.5, 0.5, 0.8)
    shape = (70, 110, 110)  # z, y, x: 56 x 55 x 55 world units
    mask = shell(shape, spacing, (27.5, 27.5, 28.0), 18.0, 22.0)  # 4 world units thick
    t = volrig.local_thickness(volrig.Volume(mask, spacing)).array[mask]
    # Within one voxel (of the coarsest spacing) of the analytic thickness, almost everywhere; the median close.
    assert np.median(t) == pytest.approx(4.0, abs=0.5)
    assert np.mean(np.abs(t - 4.0) <= 0.8 + 1e-4) > 0.97


def test_bent_sheet_thickness_and_a_rod_attached():
    # A quarter-cylinder sheet 3 voxels thick with a rod of radius 5 standing on it: the sheet reads ~3-4, the rod
    # its diameter.
    shape = (60, 80, 80)
    z, y, x = np.indices(shape)
    rr = np.hypot(x - 0.0, y - 0.0)
    sheet = (rr >= 60) & (rr < 63) & (z >= 5) & (z < 55)
    rod = (np.hypot(x - 30, z - 30) < 5.5) & (y >= 20) & (np.hypot(x, y) < 61)
    t = volrig.local_thickness(sheet | rod).array
    away = sheet & ~(np.hypot(x - 30, z - 30) < 15)
    assert np.median(t[away]) in (3.0, 4.0)
    assert np.percentile(t[away], 95) <= 4.5
    core = rod & (np.hypot(x - 30, z - 30) < 2) & (y > 30) & (y < 45)
    assert np.all(np.abs(t[core] - 11.0) <= 1.0)


def test_empty_mask_and_cancel():
    assert not volrig.local_thickness(np.zeros((4, 5, 6), bool)).array.any()
    with pytest.raises(volrig.Cancelled):
        volrig.local_thickness(np.ones((8, 8, 8), bool), progress=lambda f: False)


def test_cli_writes_a_thickness_volume(tmp_path):
    a = np.zeros((20, 30, 40), np.uint8)
    a[5:9, 3:27, 3:37] = 1  # a plate 4 voxels thick
    src = tmp_path / "plate.nrrd"
    volrig.Volume(a, spacing=(0.5, 0.5, 2.0), origin=(1, 2, 3)).save(src)
    out = tmp_path / "thick.vdb"
    env = dict(os.environ, PYTHONPATH=str(REPO / "python"))
    r = subprocess.run([sys.executable, "-m", "volrig", "thickness", str(src), "-o", str(out)], capture_output=True,
                       text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert "thickness 5/50/95%" in r.stdout
    t = volrig.load(out, grid="thickness")
    assert t.spacing == pytest.approx((0.5, 0.5, 2.0))
    assert np.median(t.array[t.array > 0]) == pytest.approx(8.0)  # 4 slices of 2 mm
    bad = subprocess.run([sys.executable, "-m", "volrig", "thickness", str(src), "-o", str(tmp_path / "t.png")],
                         capture_output=True, text=True, env=env)
    assert bad.returncode != 0 and "t.png" in bad.stderr and not (tmp_path / "t.png").exists()


def test_real_bone_plates_are_thinner_than_long_bones():
    # The Visible Human Male at 4 mm: the skull's cortical bone is a plate a few mm thick, the femur's shaft a tube
    # ~3 cm across; their thickness must say so.
    vol = volrig.load(shared("visible-human/austinman_4mm_labels.nii.gz"))
    labels = vol.array
    bone = np.isin(labels, (84, 92))  # BoneCortical, BoneMarrow
    t = volrig.local_thickness(volrig.Volume(bone, vol.spacing, vol.origin)).array
    # a bone one voxel across reads two voxels (DT is measured to the background voxels' centres)
    assert t[bone].min() == pytest.approx(8.0) and t[~bone].max() == 0.0
    nz = labels.shape[0]
    head = bone.copy()
    head[: int(nz * 0.88)] = False  # the top 12% of the body: the skull
    assert np.median(t[head]) <= 8.0 + 1e-4 and np.percentile(t[head], 95) <= 16.0 + 1e-4
    assert np.percentile(t[bone], 99) > 40.0  # the pelvis, the vertebral bodies, the femoral heads


def test_plane_like_is_the_middle_layer_of_plates_and_leaves_thin_rods_out():
    # a plate 6 voxels thick with a rod of radius 2.5 standing on it: plane-like voxels are one layer in the plate's
    # middle (away from its rim), none in the rod (round it is ~8 voxels, below t = 10)
    m = np.zeros((60, 100, 100), bool)
    m[7:13, 10:90, 10:90] = True
    z, y, x = np.indices(m.shape)
    m |= ((x - 50) ** 2 + (y - 50) ** 2 < 6.5) & (z >= 13) & (z < 55)
    vol = volrig.Volume(m, (0.5, 0.5, 0.5))
    p = volrig.plane_like(vol, t=10.0)
    assert p.spacing == (0.5, 0.5, 0.5) and p.array.dtype == np.bool_
    assert not (p.array & ~m).any()
    layers = np.nonzero(p.array)[0]
    assert set(np.unique(layers)) <= {9, 10, 11}
    inner = p.array[:, 25:75, 25:75].sum(axis=0)
    assert (inner == 1).mean() > 0.99
    assert not p.array[14:].any()  # the rod
    d = volrig.plane_measure(vol, t=10.0)
    assert np.isinf(d.array[10, 50, 30]) and d.array[0, 0, 0] == 0.0
    assert np.all(d.array[~m] == 0.0)
    with pytest.raises(volrig.VolrigError, match="t must be"):
        volrig.plane_like(vol, t=0.0)


def test_plane_like_on_the_skull_at_2mm():
    # The Visible Human's bone at 2 mm: the skull vault is a plate, so most of its plane-like voxels lie in the head,
    # and the long bones (tubes) keep few.
    vol = volrig.load(shared("visible-human/austinman_2mm_labels.nii.gz"))
    bone = np.isin(vol.array, (84, 92))
    z0 = int(bone.shape[0] * 0.88)
    head = volrig.Volume(np.ascontiguousarray(bone[z0:]), vol.spacing, vol.origin)
    p = volrig.plane_like(head, t=5.0).array
    assert p.sum() > 0.05 * head.array.sum()

"""voxelize's method= ("flood", "winding", "auto"): the generalized winding number for meshes that are not closed.
Open boxes and spheres made here; the open character 9477_ori.obj (a girl in a skirt, open parts) and lion.off
(an open back) from ../shared/data (skipped when absent); closed meshes give the flood mask bit for bit with "auto".

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_mesh_winding.py
"""
from __future__ import annotations

import inspect

import numpy as np
import pytest

import volrig
from conftest import shared
from test_mesh import REAL_MESHES, box, boundary_edges, cap_holes, icosphere
from volrig.segment import label_components
from volrig.skin import mesh_voxel_size


def open_box():
    """The unit box without its top face (z = 1)."""
    v, f = box()
    return v, np.delete(f, [2, 3], axis=0)


def centres(m):
    z, y, x = np.meshgrid(*[np.arange(n) for n in m.array.shape], indexing="ij")
    o, s = np.asarray(m.origin), np.asarray(m.spacing)
    return o[0] + s[0] * x, o[1] + s[1] * y, o[2] + s[2] * z


def test_open_box_is_filled_by_the_winding_number_and_lost_by_the_flood():
    v, f = open_box()
    assert len(boundary_edges(f)) == 4
    m = volrig.voxelize(v, f, 0.05, method="auto")
    x, y, z = centres(m)
    want = (x > 0) & (x < 1) & (y > 0) & (y < 1) & (z > 0) & (z < 1)
    np.testing.assert_array_equal(m.array, want)
    np.testing.assert_array_equal(volrig.voxelize(v, f[:, ::-1], 0.05, method="winding").array, want)  # reversed
    try:
        assert volrig.voxelize(v, f, 0.05).array.sum() < 0.5 * want.sum()  # the default, flood
    except ValueError as e:
        assert "encloses no voxel centre" in str(e)


def test_closed_meshes_give_the_flood_mask_bit_for_bit_with_auto():
    v, f = icosphere(3, 0.8, (1.0, 2.0, 3.0))
    for h, r in ((0.03, 1.5), (0.05, 0.0), (0.04, 3.0)):
        np.testing.assert_array_equal(volrig.voxelize(v, f, h, closing_radius=r, method="auto").array,
                                      volrig.voxelize(v, f, h, closing_radius=r).array)
    v, f = volrig.read_mesh(shared("meshes/cow.off"))
    assert len(boundary_edges(f)) == 0
    h = mesh_voxel_size(v, 160)
    np.testing.assert_array_equal(volrig.voxelize(v, f, h, method="auto").array,
                                  volrig.voxelize(v, f, h, method="flood").array)


def test_soup_of_overlapping_and_reversed_parts():
    (v1, f1), (v2, f2) = open_box(), box((0.5, 0.5, 0.5), (1.5, 1.5, 1.5))
    v = np.concatenate([v1, v2])
    f = np.concatenate([f1, f2[:, ::-1] + len(v1)])  # the second box reversed
    m = volrig.voxelize(v, f, 0.05, method="winding")
    x, y, z = centres(m)
    a = (x > 0) & (x < 1) & (y > 0) & (y < 1) & (z > 0) & (z < 1)
    b = (x > 0.5) & (x < 1.5) & (y > 0.5) & (y < 1.5) & (z > 0.5) & (z < 1.5)
    np.testing.assert_array_equal(m.array, a ^ b)  # w = 1 - 1 = 0 where they overlap


def test_character_with_open_parts_comes_out_in_one_piece():
    """9477_ori.obj: 880 triangles, 130 boundary edges. The flood leaks into every open part (hundreds of
    fragments); the winding number gives one body."""
    v, f = volrig.read_mesh(shared("characters/rignet/9477_ori.obj"))
    h = mesh_voxel_size(v, 160)
    m = volrig.voxelize(v, f, h, method="auto")
    sizes = label_components(m)[1]
    print(f"\n9477_ori: auto {len(sizes)} components, largest {sizes.max()} of {sizes.sum()} voxels")
    assert sizes.max() >= 0.9 * sizes.sum()
    assert sizes.sum() > 50_000
    flood = label_components(volrig.voxelize(v, f, h, method="flood"))[1]
    assert flood.sum() < 0.2 * sizes.sum()  # what the flood keeps


def test_lion_head_with_an_open_back_is_filled():
    nv, nf, open_edges, h = REAL_MESHES["lion.off"]
    v, f = volrig.read_mesh(shared("meshes/lion.off"))
    assert len(boundary_edges(f)) == open_edges > 0
    m = volrig.voxelize(v, f, h, method="auto")
    sizes = label_components(m)[1]
    capped = volrig.voxelize(*cap_holes(v, f), h)
    assert len(sizes) == 1
    # the winding number spans the hole with a (near) minimal surface, the capping with a fan: close volumes
    assert sizes[0] == pytest.approx(capped.array.sum(), rel=0.03)
    assert (m.array & capped.array).sum() >= 0.97 * capped.array.sum()


def test_method_errors_and_bad_input():
    v, f = open_box()
    with pytest.raises(ValueError, match="method must be one of 'auto', 'winding', 'flood'"):
        volrig.voxelize(v, f, 0.1, method="solid")
    bad = v.copy()
    bad[3, 1] = np.nan
    for method in ("auto", "winding"):
        with pytest.raises(ValueError, match="vertices must be finite: vertex 3"):
            volrig.voxelize(bad, f, 0.1, method=method)
        with pytest.raises(ValueError, match="faces is empty"):
            volrig.voxelize(v, f[:0], 0.1, method=method)
        with pytest.raises(ValueError, match="encloses no voxel centre"):
            volrig.voxelize(v, f[:2], 0.1, method=method)  # one flat face


def test_rig_mesh_and_the_cli_default_to_auto():
    import argparse
    from volrig import cli, pipeline
    assert inspect.signature(volrig.rig_mesh).parameters["voxelize_method"].default == "auto"
    assert inspect.signature(pipeline.load_mask).parameters["voxelize_method"].default == "auto"
    parser = argparse.ArgumentParser()
    cli._rig_command(parser.add_subparsers())
    assert parser.parse_args(["rig", "m.obj", "-o", "m.vrig"]).voxelize == "auto"
    assert parser.parse_args(["rig", "m.obj", "-o", "m.vrig", "--voxelize", "flood"]).voxelize == "flood"

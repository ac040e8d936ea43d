"""Pore Network: two chambers joined by a neck, on an oriented grid, shown as spheres and a cylinder coloured by
their diameters."""
import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op


@pytest.fixture(scope="module")
def chambers_file(tmp_path_factory):
    """Two balls of radius 7 voxels joined by a neck of radius 2.5 along x; values 200 (pore) in 0 (rock)."""
    z, y, x = np.mgrid[:20, :20, :40].astype(float)
    dy, dz = y - 9.5, z - 9.5
    pore = (((x - 10.5) ** 2 + dy ** 2 + dz ** 2 < 49) | ((x - 29.5) ** 2 + dy ** 2 + dz ** 2 < 49)
            | ((x > 10.5) & (x < 29.5) & (dy ** 2 + dz ** 2 < 6.25)))
    vol = volrig.Volume(np.where(pore, 200, 0).astype(np.uint8), (0.5, 0.5, 0.5), (5.0, -3.0, 2.0),
                        direction=np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    path = tmp_path_factory.mktemp("chambers") / "chambers.nrrd"
    vol.save(str(path))
    return str(path), vol


def test_pore_network_makes_spheres_and_cylinders_coloured_by_size(empty_scene, chambers_file):
    path, source = chambers_file
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    s = vol.volrig
    s.low, s.high, s.largest = 100, 255, False
    run_op(bpy.ops.volrig.pore_network)
    obj = [o for o in bpy.data.objects if o.volrig.role == "PORES"]
    assert len(obj) == 1
    obj = obj[0]
    assert obj.name == "chambers_pores" and obj.type == "MESH" and obj.parent == vol
    want = volrig.pore_network(volrig.Volume(source.array >= 100, source.spacing, source.origin))
    assert want.pore_count == 2 and want.throat_count == 1
    mesh = obj.data
    per_sphere = (len(mesh.vertices) - 16) // 2
    assert len(mesh.vertices) == 2 * per_sphere + 16
    co = np.array([v.co[:] for v in mesh.vertices])
    # Each sphere around its pore (grid frame: voxel centres at origin + i spacing), of its inscribed radius.
    centres = want.pore_coords + np.array(source.origin) - 0.25
    for k in range(2):
        ball = co[k * per_sphere:(k + 1) * per_sphere]
        np.testing.assert_allclose(ball.mean(axis=0), centres[k], atol=1e-3)
        np.testing.assert_allclose(np.linalg.norm(ball - centres[k], axis=1), want.pore_diameter[k] / 2, rtol=1e-4)
    # The throat's cylinder runs between them at the neck's radius.
    tube = co[2 * per_sphere:]
    axis = centres[1] - centres[0]
    off = tube - centres[0]
    radial = off - np.outer(off @ axis / (axis @ axis), axis)
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), want.throat_diameter[0] / 2, rtol=1e-4)
    # Coloured by size: the thickness attribute holds each part's diameter, the ramp spans them.
    th = np.array([d.value for d in mesh.attributes["thickness"].data])
    np.testing.assert_allclose(th[:per_sphere], want.pore_diameter[0], rtol=1e-5)
    np.testing.assert_allclose(th[-16:], want.throat_diameter[0], rtol=1e-5)
    nodes = obj.active_material.node_tree.nodes
    assert nodes["volrig thickness"].attribute_name == "thickness"
    # In the scene: the volume object's matrix (mm to m, turned) carries it, as the medial surface.
    world = np.array([(obj.matrix_world @ mesh.vertices[0].co)[:]])
    expect = (source.grid_to_world() @ np.r_[co[0], 1.0])[:3] * 0.001
    np.testing.assert_allclose(world[0], expect, atol=1e-6)
    # Again: the same object, new geometry.
    run_op(bpy.ops.volrig.pore_network)
    assert [o for o in bpy.data.objects if o.volrig.role == "PORES"] == [obj]

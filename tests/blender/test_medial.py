"""Medial Surface: a plate with a rod on an anisotropic, oriented grid, shown as a mesh coloured by thickness."""
import numpy as np
import pytest

import bpy
import volrig
from conftest import run_op


@pytest.fixture(scope="module")
def plate_file(tmp_path_factory):
    """A disc plate 6 mm thick (radius 16 mm) with a rod (radius 2 mm) standing on it, values 200 in 0."""
    sp = (1.0, 1.0, 1.4)
    shape = (30, 44, 44)
    z, y, x = np.indices(shape).astype(float)
    X, Y, Z = x * sp[0], y * sp[1], z * sp[2]
    cx, cy, cz = 22.13, 22.21, 7.0
    rho, dz = np.hypot(X - cx, Y - cy), Z - cz
    plate = np.where(rho <= 16.0, np.abs(dz), np.hypot(rho - 16.0, dz)) < 3.0
    rod = (np.hypot(X - cx - 5, Y - cy) < 2.0) & (Z > cz) & (Z < cz + 20.0)
    vol = volrig.Volume(np.where(plate | rod, 200, 0).astype(np.uint8), sp, (5.0, -3.0, 2.0),
                        direction=np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    path = tmp_path_factory.mktemp("plate") / "plate.nrrd"
    vol.save(str(path))
    return str(path), vol


def test_medial_surface_makes_a_mesh_coloured_by_thickness(empty_scene, plate_file):
    path, source = plate_file
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    s = vol.volrig
    s.low, s.high, s.largest = 100, 255, False
    run_op(bpy.ops.volrig.medial_surface)
    obj = [o for o in bpy.data.objects if o.volrig.role == "MEDIAL"]
    assert len(obj) == 1
    obj = obj[0]
    assert obj.name == "plate_medial" and obj.type == "MESH" and obj.parent == vol
    want = volrig.medial_surface(volrig.Volume(source.array >= 100, source.spacing, source.origin), t=s.plane_t)
    mesh = obj.data
    rod_points = sum(len(r) for r in want.rods)
    assert len(mesh.polygons) == len(want.faces) > 500 and len(mesh.vertices) == len(want.vertices) + rod_points
    assert len(want.rods) == 1 and len([e for e in mesh.edges if e.is_loose]) == rod_points - 1
    co = np.array([v.co[:] for v in mesh.vertices[:len(want.vertices)]])
    np.testing.assert_allclose(co, want.vertices, atol=1e-4)
    th = np.array([d.value for d in mesh.attributes["thickness"].data])
    np.testing.assert_allclose(th[:len(want.vertices)], want.thickness, rtol=1e-5)
    assert abs(np.median(th[:len(want.vertices)]) - 6.0) <= 1.4
    # In the scene, the plate's mid-plane is where the scan puts it: the volume object's matrix (mm to m, turned).
    world = np.array([(obj.matrix_world @ v.co)[:] for v in mesh.vertices[:len(want.vertices)]])
    expect = (source.grid_to_world() @ np.c_[want.vertices, np.ones(len(want.vertices))].T).T[:, :3] * 0.001
    np.testing.assert_allclose(world, expect, atol=1e-6)
    # Coloured by the thickness attribute through the ramp, spanning its values.
    nodes = obj.active_material.node_tree.nodes
    assert nodes["volrig thickness"].attribute_name == "thickness"
    assert nodes["volrig thickness ramp"].outputs["Color"].is_linked
    top = nodes["volrig thickness span"].inputs["From Max"].default_value
    assert top == pytest.approx(np.percentile(th, 99), rel=1e-5)
    # The rods render as tubes (geometry nodes on the loose edges), coloured like the rest.
    assert obj.modifiers["volrig rods"].node_group.name == "volrig rods"
    rod_flags = np.array([d.value for d in mesh.attributes["rod"].data])
    assert rod_flags.sum() == rod_points - 1
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    assert len(evaluated.polygons) >= len(mesh.polygons) + 8 * (rod_points - 1)
    every = np.array([v.co[:] for v in evaluated.vertices])
    base = np.array([v.co[:] for v in mesh.vertices])
    new_points = np.min(np.linalg.norm(every[:, None, :] - base[None, :, :], axis=2), axis=1) > 1e-5
    tube = every[new_points]
    assert len(tube) == 8 * rod_points  # an 8-sided ring around each rod point
    line = want.rods[0]
    near = np.min(np.linalg.norm(tube[:, None, :] - line[None, :, :], axis=2), axis=1)
    np.testing.assert_allclose(near, np.repeat(want.rod_radii[0], 8).min(), atol=0.6)  # at the rods' radii
    # Again (another t): the same object, new geometry; the panel shows the button.
    s.plane_t = 8.0
    run_op(bpy.ops.volrig.medial_surface)
    assert [o for o in bpy.data.objects if o.volrig.role == "MEDIAL"] == [obj]
    assert len(obj.data.polygons) > 0


def test_medial_surface_without_plates_and_of_an_empty_mask(empty_scene, plate_file):
    path, _ = plate_file
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    s = vol.volrig
    s.low, s.high, s.largest = 100, 255, False
    s.plane_t = 200.0  # larger than any plate here: no surface, the curve skeleton alone (rods as loose edges)
    run_op(bpy.ops.volrig.medial_surface)
    (obj,) = [o for o in bpy.data.objects if o.volrig.role == "MEDIAL"]
    assert len(obj.data.polygons) == 0 and len(obj.data.edges) > 5
    s.low, s.high = 230, 250  # nothing in range: reported, not raised
    with pytest.raises(RuntimeError, match="segmentation is empty"):
        bpy.ops.volrig.medial_surface()

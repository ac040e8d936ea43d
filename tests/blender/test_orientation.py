"""A volume whose file says how its voxels lie in the patient (NRRD space directions): the add-on places the Volume
object with that matrix, and the rig volrig computes in the grid frame lands on the volume, upright."""
import numpy as np
import pytest

import bpy
import volrig
from conftest import import_and_rig
from mathutils import Vector


def _lying(ph_volume):
    """The standing phantom stored lying down: the file's x axis is the patient's +z (superior), its z axis the
    patient's -x; the direction and origin put every voxel where the standing phantom has it."""
    a = ph_volume.array
    nx = a.shape[2]
    b = np.ascontiguousarray(np.transpose(a, (2, 1, 0))[::-1])  # b[z', y', x'] = a[x', y', nx - 1 - z']
    sx, sy, sz = ph_volume.spacing
    d = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # columns: patient directions of x', y', z'
    origin = np.asarray(ph_volume.origin) + np.array([sx * (nx - 1), 0.0, 0.0])
    return volrig.Volume(b, (sz, sy, sx), tuple(origin), direction=d)


def test_an_oriented_file_lands_in_the_patient_frame_and_its_rig_stands(empty_scene, phantom_file, tmp_path):
    path, ph = phantom_file
    lying = _lying(ph.volume)
    # the two files hold the same voxels at the same patient positions
    ijk = np.argwhere(lying.array)[::997]
    standing = ph.volume.array
    pat = lying.patient(ijk)
    idx = np.round((pat - np.asarray(ph.volume.origin)) / np.asarray(ph.volume.spacing)).astype(int)
    assert standing[idx[:, 2], idx[:, 1], idx[:, 0]].all()
    file = tmp_path / "lying.nrrd"
    lying.save(str(file))
    vol = import_and_rig(str(file))
    m = np.array(vol.matrix_world)
    np.testing.assert_allclose(m, np.diag([0.001, 0.001, 0.001, 1.0]) @ lying.grid_to_world(), atol=1e-9)
    # a voxel's grid-frame position (where volrig computes) lands on its patient position in Blender (LPS axes, mm)
    grid = np.asarray(lying.origin) + ijk[:, ::-1] * np.asarray(lying.spacing)
    world = np.array([tuple(vol.matrix_world @ Vector(p)) for p in grid])
    np.testing.assert_allclose(world, 0.001 * pat, atol=1e-6)
    # the rig (computed in the grid frame, the scene's +Z passed as up) stands in Blender: head above the feet,
    # at the standing phantom's joints
    from volrig_addon.objects import members
    rig_obj = members(vol)["RIG"]
    np.testing.assert_allclose(np.array(rig_obj.matrix_world), m, atol=1e-9)
    bones = rig_obj.data.bones
    world_of = lambda v: np.array(rig_obj.matrix_world @ v) / 0.001  # noqa: E731  (mm)
    head, feet = world_of(bones["head"].tail_local), [world_of(bones[f"foot.{s}"].head_local) for s in "LR"]
    height = ph.volume.dims[2] * ph.volume.spacing[2]
    assert all(head[2] - f[2] > 0.8 * height for f in feet)
    # its joints on the standing phantom's true ones (the .L side is the patient's left, +x, in both)
    for bone, joint in (("forearm", "elbow"), ("shin", "knee"), ("hand", "wrist"), ("foot", "ankle")):
        for s in "LR":
            err = np.linalg.norm(world_of(bones[f"{bone}.{s}"].head_local) - np.asarray(ph.joints[f"{joint}.{s}"]))
            assert err < 30.0, f"{joint}.{s} {err:.1f} mm from the true joint"

"""Straightening through the rig machinery (thesis §9.3, docs/ALGORITHMS.md §9.3): a chain armature along the
centerline (volrig.straightening_rig), skeleton spheres bound to it and deformed with the straight pose give a
straight tube; and the centerline's progress callback."""
import numpy as np
import pytest

import volrig
from test_centerline import helix, torus_segment, tube


@pytest.fixture(scope="module")
def bent():
    c = torus_segment(bend=20.0, angle=1.5 * np.pi)  # a 270 degree bend, tube radius 4
    m = tube(c, 4.0)
    line = volrig.centerline(m)
    return m, line, volrig.skeletonize(m).at(0.3)


def _axial_radial(points, origin, axis):
    rel = np.asarray(points) - origin
    along = rel @ axis
    return along, np.linalg.norm(rel - along[:, None] * axis, axis=1)


def test_the_chain_lies_along_the_centerline_and_its_straight_pose_on_a_line(bent):
    m, line, _ = bent
    sr = volrig.straightening_rig(line, bones=12)
    rig = sr.rig
    assert len(rig) == 12 and rig.names[0] == "seg.000" and list(rig.parents) == list(range(-1, 11))
    lengths = np.linalg.norm(rig.tails() - rig.heads(), axis=1)
    assert np.allclose(lengths, lengths.mean(), rtol=0.02)      # equal arc pieces (chords of them)
    assert np.allclose(rig.joints[0], line.points[0]) and np.allclose(rig.joints[-1], line.points[-1])
    assert np.allclose(sr.matrices(0.0), np.eye(4), atol=1e-12)   # the rest pose is the curve itself
    assert np.allclose(sr.matrices(1.0), sr.straight, atol=1e-9)  # forward kinematics gives the straight pose
    for M in sr.straight:  # rigid
        assert np.allclose(M[:3, :3] @ M[:3, :3].T, np.eye(3), atol=1e-9) and np.linalg.det(M[:3, :3]) > 0
    # posed joints on the line from the first joint along the axis, spaced by the bone lengths
    heads = np.einsum("bij,bj->bi", sr.straight, np.c_[rig.heads(), np.ones(12)])[:, :3]
    tails = np.einsum("bij,bj->bi", sr.straight, np.c_[rig.tails(), np.ones(12)])[:, :3]
    assert np.allclose(heads[1:], tails[:-1], atol=1e-9)        # still connected
    along, off = _axial_radial(np.r_[heads, tails[-1:]], rig.joints[0], sr.axis)
    assert off.max() < 1e-9 and np.allclose(np.diff(along), lengths)
    chord = rig.joints[-1] - rig.joints[0]
    assert np.allclose(sr.axis, chord / np.linalg.norm(chord))
    # Blender's bases of a connected chain are pure rotations about each bone's head
    basis = rig.basis_matrices(sr.straight)
    assert np.abs(basis[:, :3, 3]).max() < 1e-9
    # halfway: still connected, between curved and straight
    half = sr.matrices(0.5)
    h = np.einsum("bij,bj->bi", half, np.c_[rig.heads(), np.ones(12)])[:, :3]
    t = np.einsum("bij,bj->bi", half, np.c_[rig.tails(), np.ones(12)])[:, :3]
    assert np.allclose(h[1:], t[:-1], atol=1e-9)
    with pytest.raises(volrig.VolrigError, match="bones"):
        volrig.straightening_rig(line, bones=0)
    with pytest.raises(volrig.VolrigError, match="axis"):
        volrig.straightening_rig(line, axis=(0, 0, 0))


@pytest.mark.parametrize("mode", ["linear", "dual_quaternion"])
def test_deforming_a_bent_tube_with_the_straight_pose_gives_a_straight_tube(bent, mode):
    m, line, pts = bent
    sr = volrig.straightening_rig(line, bones=12)
    binding = volrig.bind(pts, sr.rig, m, mode="smooth")
    source = m.like(m.array.astype(np.float32))
    frame = volrig.deform(source, pts, binding, sr.straight, mode=mode)
    inside = frame.values.array > 0.5
    assert abs(inside.sum() - m.array.sum()) < 0.03 * m.array.sum()   # volume kept within 3 %
    w = np.asarray(frame.values.origin) + np.argwhere(inside)[:, ::-1] * np.asarray(frame.values.spacing)
    along, off = _axial_radial(w, sr.rig.joints[0], sr.axis)
    # every voxel within the tube's radius (4) plus a voxel of the straight axis, from 0 to the length
    assert np.percentile(off, 99) < 5.0 and off.max() < 5.5, np.percentile(off, [50, 99, 100])
    assert along.min() > -1.5 and abs(along.max() - line.length) < 1.5, (along.min(), along.max(), line.length)
    # its own centerline is straight, as long as the bent one, with the same radius
    straight = volrig.centerline(frame.values.like(inside))
    _, dev = _axial_radial(straight.points, sr.rig.joints[0], sr.axis)
    assert dev.mean() < 0.6 and dev.max() < 1.5, (dev.mean(), dev.max())
    assert abs(straight.length - line.length) < 0.03 * line.length, (straight.length, line.length)
    assert abs(np.median(straight.radii) - np.median(line.radii)) < 0.5
    # the bent tube was far from straight
    _, bent_dev = _axial_radial(line.points, sr.rig.joints[0], sr.axis)
    assert bent_dev.max() > 15


def test_progress_reaches_one_and_cancels():
    c = helix(turns=1.0, n=20000)
    m = tube(c, 3.0)
    seen = []
    line = volrig.centerline(m, progress=lambda f: seen.append(f) or True)
    assert seen[-1] == 1.0 and np.all(np.diff(seen) >= 0) and len(seen) >= 4
    assert np.allclose(line.points, volrig.centerline(m).points)
    seen.clear()
    volrig.centerline_tree(m, progress=lambda f: seen.append(f) or True)
    assert seen[-1] == 1.0 and np.all(np.diff(seen) >= 0) and len(seen) >= 4
    for fn in (volrig.centerline, volrig.centerline_tree):
        calls = []
        with pytest.raises(volrig.Cancelled):
            fn(m, progress=lambda f: calls.append(f) or f < 0.3)
        assert 0.3 <= calls[-1] < 1.0

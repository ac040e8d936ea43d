"""autorig on shared meshes (../shared/data/meshes): the knight is a humanoid standing along +y, the cow a quadruped
with its head at +x and a tail. Up and head directions were read off the meshes' silhouettes."""
import numpy as np
import pytest

import volrig
from conftest import shared


def read_off(path):
    """Vertices and triangles (fans of polygons) of an OFF file."""
    tokens = [t for line in path.read_text().splitlines() for t in line.split("#")[0].split()]
    assert tokens[0] == "OFF"
    nv, nf = int(tokens[1]), int(tokens[2])
    v = np.array(tokens[4:4 + 3 * nv], dtype=np.float64).reshape(nv, 3)
    faces, i = [], 4 + 3 * nv
    for _ in range(nf):
        k = int(tokens[i])
        poly = [int(t) for t in tokens[i + 1:i + 1 + k]]
        faces += [[poly[0], poly[j], poly[j + 1]] for j in range(1, k - 1)]
        i += 1 + k
    return v, np.array(faces, dtype=np.int64)


def rig_of_mesh(name, up=None, voxels=160):
    v, f = read_off(shared(f"meshes/{name}"))
    mask = volrig.voxelize(v, f, float((v.max(0) - v.min(0)).max()) / voxels)
    pts = volrig.skeletonize(mask).top(15000)
    return volrig.autorig(pts, volrig.skeleton_tree(pts, mask), mask, up=up)


@pytest.mark.parametrize("up", [None, (0, 1, 0)], ids=["up inferred", "up given"])
def test_knight_is_a_humanoid_with_its_head_up(up):
    rig = rig_of_mesh("decimated-knight.off", up)
    assert rig.kind == "humanoid"
    assert rig.up @ [0, 1, 0] > 0.9
    head = rig.joints[rig.bones[rig.index("head"), 1]]
    for foot in ("foot.L", "foot.R"):
        assert head[1] > rig.joints[rig.bones[rig.index(foot), 1]][1] + 0.5 * np.ptp(rig.joints[:, 1])


def test_cow_is_a_quadruped_with_its_head_forward_and_a_tail():
    rig = rig_of_mesh("cow.off")
    assert rig.kind == "quadruped"
    along = rig.joints[:, 0]  # the head end is +x
    lo, span = along.min(), np.ptp(along)
    assert rig.joints[rig.bones[rig.index("head"), 1]][0] > lo + 0.75 * span
    tail = [b for b, n in enumerate(rig.names) if n.startswith("tail")]
    assert len(tail) >= 2
    assert rig.joints[rig.bones[tail]][..., 0].max() < lo + 0.5 * span
    assert rig.names[rig.parents[rig.index("tail")]] in ("hips", "pelvis.L", "pelvis.R")
    assert rig.up @ [0, 1, 0] > 0.7  # legs toward -y

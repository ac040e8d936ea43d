"""Meshes rigged through their volume (issue 23): volrig.rig_mesh, skin_weights, pose_vertices, thickness editing.

Posed subjects: the left elbow bent 90 degrees and the left knee 60 degrees (about the hip line) on the shared
knight and quadrupeds; the arm against libigl's arm.tgf.
"""
import numpy as np
import pytest

from conftest import SHARED_DATA

import volrig
from volrig_support import subjects as S
from volrig.mesh import subdivide
from volrig.pipeline import rig_mesh
from volrig.skin import (MeshRig, _closest_on_bones, mesh_voxel_size, pose_vertices, skin_weights,
                         thickness_offsets)

TRUNK = ("hips", "spine", "chest", "neck", "head")


def needs(name):
    if not SHARED_DATA.exists():
        pytest.skip(f"real data not available: {SHARED_DATA}")
    return S._close_holes(*volrig.read_mesh(str(SHARED_DATA / S.MESHES[name][0])))


_RIGS = {}


def rigged(name, **kw) -> MeshRig:
    key = (name, tuple(sorted(kw.items())))
    if key not in _RIGS:
        v, f = needs(name)
        _RIGS[key] = rig_mesh(v, f, up=np.array(S.MESHES[name][3], float), **kw)
    return _RIGS[key]


@pytest.fixture(scope="module", autouse=True)
def _free():
    yield
    _RIGS.clear()


def descendants(rig, b):
    out = {b}
    grown = True
    while grown:
        grown = False
        for c, p in enumerate(rig.parents):
            if p in out and c not in out:
                out.add(c)
                grown = True
    return out


def bent(rig, up, bends=(("forearm.L", 90.0), ("shin.L", 60.0))):
    """Rest-to-pose matrices with each named bone (and everything below it) turned about its head: knees about the
    hip line, elbows about the axis across the bone and up."""
    M = volrig.rest_pose(len(rig.bones))
    for name, degrees in bends:
        b = rig.index(name)
        d = rig.tails()[b] - rig.heads()[b]
        if name.startswith("shin"):
            axis = rig.heads()[rig.index("thigh.L")] - rig.heads()[rig.index("thigh.R")]
        else:
            axis = np.cross(d, up)
            if np.linalg.norm(axis) < 1e-6 * np.linalg.norm(d):
                axis = np.cross(d, [1.0, 0.0, 0.0])
        R = volrig.rotation_about(axis, degrees, rig.heads()[b])
        for c in descendants(rig, b):
            M[c] = R @ M[c]
    return M


def nearest_bone(rig, points):
    """Each point's nearest bone segment in a straight line."""
    return np.linalg.norm(_closest_on_bones(rig, points) - points[None], axis=2).argmin(0)


def check_rows(w, influences=4):
    counts = np.diff(w.indptr)
    assert counts.min() >= 1 and counts.max() <= influences
    assert np.allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0, atol=1e-5)
    assert (w.data > 0).all()


# ---- synthetic ----------------------------------------------------------------------------------------------------

def box_mesh(lo, hi):
    """A closed box (12 triangles)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7],
                  [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return v, f


def bar():
    """A bar 12 long and 2 thick along x, subdivided, with a two-bone chain along its axis."""
    v, f = box_mesh((0, -1, -1), (12, 1, 1))
    for _ in range(4):
        v, f = subdivide(v, f)
    mask = volrig.voxelize(v, f, 0.1)
    rig = volrig.Rig.from_bones([[0.5, 0, 0], [6, 0, 0]], [[6, 0, 0], [11.5, 0, 0]], ["a", "b"], [-1, 0])
    return v, f, mask, rig


def test_bar_weights_blend_near_the_joint_only():
    v, f, mask, rig = bar()
    w = skin_weights(mask, rig, v)
    check_rows(w)
    dense = w.toarray()
    far = np.abs(v[:, 0] - 6) > 2.5  # beyond 2.5 radii of the joint: one bone
    assert np.all(dense[far].max(axis=1) == 1.0)
    assert np.all(dense[far & (v[:, 0] < 6), 0] == 1.0)
    near = np.abs(v[:, 0] - 6) < 0.3
    assert np.all(np.abs(dense[near, 0] - 0.5) < 0.15)
    # posing bone b 90 degrees: its far vertices follow it exactly, a's stay
    M = volrig.rest_pose(2)
    M[1] = volrig.rotation_about([0, 0, 1], 90, [6, 0, 0])
    for method in ("linear", "dual_quaternion"):
        p = pose_vertices(v, w, M, method)
        rigid = v @ M[1, :3, :3].T + M[1, :3, 3]
        assert np.allclose(p[far & (v[:, 0] > 6)], rigid[far & (v[:, 0] > 6)], atol=1e-9)
        assert np.allclose(p[far & (v[:, 0] < 6)], v[far & (v[:, 0] < 6)], atol=1e-9)


def test_one_rigid_motion_moves_every_vertex_rigidly():
    v, f, mask, rig = bar()
    w = skin_weights(mask, rig, v)
    R = volrig.rotation_about([1, 2, 3], 70, [3, 1, 0])
    M = np.stack([R, R])
    for method in ("linear", "dual_quaternion"):
        assert np.allclose(pose_vertices(v, w, M, method), v @ R[:3, :3].T + R[:3, 3], atol=1e-9)


def test_thickness_scales_the_radius_about_the_bone():
    v, f, mask, rig = bar()
    w = skin_weights(mask, rig, v)
    mr = MeshRig(v, f, rig, w, mask, 0.1, None, None, None, None)
    thick = mr.thicken({"b": 2.0})
    far_b = (v[:, 0] > 8.5) & (v[:, 0] < 11.5)  # beside the bone (the end cap moves out along it)
    radial = np.linalg.norm(v[:, 1:], axis=1)
    assert np.allclose(np.linalg.norm(thick[far_b, 1:], axis=1), 2 * radial[far_b])
    assert np.allclose(thick[far_b, 0], v[far_b, 0])  # along the bone: unchanged
    assert np.allclose(thick[v[:, 0] < 3.5], v[v[:, 0] < 3.5])  # bone a untouched
    # linear in the factor: a shape key holding the offset at 2 gives any factor
    o2 = thickness_offsets(rig, w, v, {"b": 2.0})
    assert np.allclose(thickness_offsets(rig, w, v, {1: 0.25}), -0.75 * o2)
    with pytest.raises(volrig.VolrigError, match="factor"):
        mr.thicken({"b": np.nan})
    with pytest.raises(KeyError):
        mr.thicken({"nope": 2})


def test_bad_input_is_refused():
    v, f, mask, rig = bar()
    with pytest.raises(volrig.VolrigError, match="influences"):
        skin_weights(mask, rig, v, influences=0)
    with pytest.raises(volrig.VolrigError, match=r"\(V, 3\)"):
        skin_weights(mask, rig, v[:, :2])
    with pytest.raises(volrig.VolrigError, match="finite"):
        skin_weights(mask, rig, np.array([[np.nan, 0, 0]]))
    with pytest.raises(volrig.VolrigError, match="empty"):
        skin_weights(mask.like(np.zeros_like(mask.array)), rig, v)
    w = skin_weights(mask, rig, v)
    with pytest.raises(volrig.VolrigError, match="bone_matrices"):
        pose_vertices(v, w, np.eye(4)[None])
    with pytest.raises(volrig.VolrigError, match="method"):
        pose_vertices(v, w, volrig.rest_pose(2), "cubic")
    with pytest.raises(volrig.VolrigError, match="extent"):
        mesh_voxel_size(np.zeros((3, 3)))


def test_voxelize_anchor_puts_voxels_on_a_given_lattice():
    v, f = box_mesh((0.03, 0.0, 0.0), (1.0, 0.5, 0.7))
    a = volrig.voxelize(v, f, 0.1)
    b = volrig.voxelize(v + [0.27, 0.0, 0.0], f, 0.1, anchor=a.origin)
    k = (np.array(b.origin) - np.array(a.origin)) / 0.1
    assert np.allclose(k, np.round(k), atol=1e-9)
    assert b.array.sum() == a.array.sum() or abs(int(b.array.sum()) - int(a.array.sum())) < 0.2 * a.array.sum()


# ---- the shared meshes --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["knight", "cow", "horse", "camel"])
def test_posed_characters_trunk_stays_limbs_follow(name):
    mr = rigged(name)
    rig, v = mr.rig, mr.vertices
    assert rig.kind == S.MESHES[name][2]
    check_rows(mr.weights)
    up = np.array(S.MESHES[name][3], float)
    height = np.ptp(v @ up)
    M = bent(rig, up)
    p = mr.pose(M)
    near = nearest_bone(rig, v)
    trunk = np.isin(near, [rig.index(n) for n in TRUNK])
    assert trunk.sum() > 50
    assert np.linalg.norm(p - v, axis=1)[trunk].max() <= 0.01 * height
    for bone in ("forearm.L", "shin.L"):
        b = rig.index(bone)
        h, t = rig.heads()[b], rig.tails()[b]
        along = (v - h) @ (t - h) / np.dot(t - h, t - h)
        distal = (near == b) & (along > 0.5) & (along < 1.0)  # the bone's distal half
        assert distal.sum() >= 5
        rigid = v @ M[b, :3, :3].T + M[b, :3, 3]
        assert np.linalg.norm(p - rigid, axis=1)[distal].max() <= 0.005 * height


def test_skinned_arm_matches_the_reference_skeleton():
    """Each vertex's heaviest bone lies along the arm.tgf bone nearest the vertex (both by nearest segment)."""
    mr = rigged("arm")
    check_rows(mr.weights)
    joints, edges = volrig.read_tgf(str(SHARED_DATA / "meshes/arm.tgf"))
    ref = volrig.Rig.from_bones(joints[edges[:, 0]], joints[edges[:, 1]], [f"t{i}" for i in range(len(edges))],
                                [-1] * len(edges))
    rig = mr.rig
    mid = (rig.heads() + rig.tails()) / 2
    ref_of_bone = nearest_bone(ref, mid)
    heaviest = np.asarray(mr.weights.argmax(axis=1)).ravel()
    agree = (ref_of_bone[heaviest] == nearest_bone(ref, mr.vertices)).mean()
    assert agree >= 0.9, agree


def voxel_difference(mr: MeshRig, M, mode="rigid") -> float:
    """Share of the object voxels (union) on which the posed mesh's voxelization and the deformed volume differ."""
    posed = volrig.voxelize(mr.pose(M), mr.faces, mr.voxel_size, anchor=mr.mask.origin)
    frame = volrig.deform(mr.mask, mr.points, mr.binding, M, mode=mode, sampling="nearest").values
    h = mr.voxel_size
    boxes = []
    for vol in (frame, posed):
        lo = np.round((np.array(vol.origin) - np.array(mr.mask.origin)) / h).astype(int)
        boxes.append((lo, np.asarray(vol.array) != 0))
    lo = np.minimum(boxes[0][0], boxes[1][0])
    hi = np.maximum(*[b[0] + np.array(b[1].shape[::-1]) for b in boxes])
    grids = []
    for o, a in boxes:
        g = np.zeros(tuple((hi - lo)[::-1]), bool)
        s = o - lo
        g[s[2]:s[2] + a.shape[0], s[1]:s[1] + a.shape[1], s[0]:s[0] + a.shape[2]] = a
        grids.append(g)
    return float((grids[0] ^ grids[1]).sum() / (grids[0] | grids[1]).sum())


@pytest.mark.parametrize("name, voxels", [("cow", None), ("horse", None), ("camel", None), ("knight", 256)])
def test_posed_mesh_and_posed_volume_agree(name, voxels):
    """Issue 23: the posed mesh voxelized and the posed volume differ on at most 2% of the voxels. Both are
    voxel-accurate pictures of the shape, so the measure has a floor: the whole knight turned rigidly by 30 degrees
    (no deformation at all) differs on 3.5% at the default 160 voxels along its height, whose thin limbs are a few
    voxels across, and on 2.2% at 256; it is measured there (the quadrupeds at the default)."""
    kw = {}
    if voxels:
        v, _ = needs(name)
        kw["voxel_size"] = float((v.max(0) - v.min(0)).max()) / voxels
    mr = rigged(name, thinness=0.0, **kw)  # every skeleton point: the volume reconstructs exactly at rest
    rig = mr.rig
    assert voxel_difference(mr, volrig.rest_pose(len(rig.bones))) == 0.0
    assert voxel_difference(mr, bent(rig, np.array(S.MESHES[name][3], float))) <= 0.02


def test_thicken_volume_stretches_a_bone_radially_and_poses():
    """A bar volume of two bones: bone b at factor 1.5 gets 1.5 times the cross-section radius beside it, bone a
    keeps its own; posing the thickened source with the scaled spheres at rest gives it back."""
    v, f, _, rig = bar()
    mask = volrig.voxelize(v, f, 0.1, padding=8)  # room to grow
    source = mask.like(mask.array.astype(np.float32))
    sk = volrig.skeletonize(mask)
    pts = sk.at(0.0)
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    thick, rs = volrig.skin.thicken_volume(source, pts, binding, rig, {"b": 1.5})
    assert rs.shape == (len(pts),) and rs.min() >= 1.0 and rs.max() == pytest.approx(1.5)
    a = np.asarray(thick.array) > 0.5
    xs = np.array(mask.origin[0]) + np.arange(mask.dims[0]) * mask.spacing[0]
    area = a.sum(axis=(0, 1)).astype(float)
    rest_area = np.asarray(mask.array).sum(axis=(0, 1)).astype(float)
    beside_b = (xs > 9) & (xs < 11)
    beside_a = (xs > 1) & (xs < 3)
    # the bar's square section: 20 voxels wide -> 30 across its middle beside b, the area grows; a's unchanged
    assert (area[beside_b] > 1.5 * rest_area[beside_b]).all()
    assert (area[beside_a] == rest_area[beside_a]).all()
    middle = a[a.shape[0] // 2, :, beside_b].sum(axis=1)
    assert np.abs(middle - 30).max() <= 2, middle
    frame = volrig.Deformer(thick, pts, binding).frame(volrig.rest_pose(2), radius_scale=rs)
    fv = np.asarray(frame.values.array) > 0.5
    o = np.round((np.array(frame.values.origin) - np.array(mask.origin)) / 0.1).astype(int)[::-1]
    inside = a[o[0]:o[0] + fv.shape[0], o[1]:o[1] + fv.shape[1], o[2]:o[2] + fv.shape[2]]
    assert (fv == inside[:fv.shape[0], :fv.shape[1], :fv.shape[2]]).mean() > 0.999
    same, rs1 = volrig.skin.thicken_volume(source, pts, binding, rig, {})
    assert same is source and (rs1 == 1).all()


def test_rig_mesh_skins_given_points_instead_of_the_vertices():
    """skin_points: the surface voxelized is one mesh (Blender's evaluated mesh after a subdivision), the points
    skinned another (the mesh's own vertices): the weights are those the same points get as vertices."""
    v, f, _, _ = bar()
    coarse = v[::7]
    a = rig_mesh(v, f, voxels=60, kind="chains")
    b = rig_mesh(v, f, voxels=60, kind="chains", skin_points=coarse)
    assert b.weights.shape == (len(coarse), len(a.rig.bones)) and b.faces.shape == (0, 3)
    assert np.array_equal(b.vertices, coarse)
    assert b.rig.names == a.rig.names
    expected = skin_weights(a.mask, a.rig, coarse)
    assert abs(b.weights - expected).max() == 0
    assert np.allclose(b.pose(volrig.rest_pose(len(b.rig.bones))), coarse)


def stick_figure_mesh(thickness):
    """A T-posed figure about 1.8 units tall of closed boxes: arms ``thickness`` across, legs 1.5 times, the trunk 3
    times and the head 5 times as thick (at rig_mesh's 160 voxels, a thickness of 0.011 is one voxel)."""
    t = thickness / 2
    boxes = [((-3 * t, -2 * t, 0.9), (3 * t, 2 * t, 1.5)),                      # trunk
             ((-5 * t, -5 * t, 1.52), (5 * t, 5 * t, 1.52 + 10 * t)),           # head, on a neck
             ((-t, -t, 1.5), (t, t, 1.53)),                                    # neck
             ((-0.7, -t, 1.42 - t), (0.7, t, 1.42 + t)),                       # arms, spread
             ((-0.15, -1.5 * t, 0.9 - 1.5 * t), (0.15, 1.5 * t, 0.9 + 1.5 * t))]  # hips
    boxes += [((s * 0.15 - 1.5 * t, -1.5 * t, 0.0), (s * 0.15 + 1.5 * t, 1.5 * t, 0.9)) for s in (-1, 1)]  # legs
    vs, fs = [], []
    for lo, hi in boxes:
        v, f = box_mesh(lo, hi)
        fs.append(f + sum(len(x) for x in vs))
        vs.append(v)
    return np.concatenate(vs), np.concatenate(fs)


def test_a_stick_figure_is_voxelized_finer_until_its_limbs_are_whole():
    """At 160 voxels the sticks are one voxel across: no body plan can be read. rig_mesh voxelizes such a mesh once
    more, finer (its skeleton's median radius under MIN_RADIUS_VOXELS), and finds the humanoid; told not to, it
    stays at 160."""
    from volrig import pipeline
    v, f = stick_figure_mesh(0.011)
    side = float(np.ptp(v, axis=0).max())
    fine = rig_mesh(v, f, up=(0, 0, 1))
    assert fine.voxel_size < side / 160 / 1.25  # refined
    assert fine.voxel_size >= side / pipeline.MAX_MESH_VOXELS - 1e-9
    assert fine.rig.kind == "humanoid", fine.rig.note
    coarse = rig_mesh(v, f, up=(0, 0, 1), min_radius_voxels=0)
    assert coarse.voxel_size == pytest.approx(side / 160)
    assert coarse.rig.kind != "humanoid"
    # a thick figure is left at 160 voxels
    v, f = stick_figure_mesh(0.1)
    assert rig_mesh(v, f, up=(0, 0, 1)).voxel_size == pytest.approx(float(np.ptp(v, axis=0).max()) / 160)

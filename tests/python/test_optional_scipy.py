"""volrig without scipy (Blender's own Python has numpy only; volrig/_optional.py): the numpy paths give what the
scipy ones give (weights the same arrays, bit for bit; quaternions and the Gaussian blur too; a rotation's power
to rounding), the pipeline runs, and what needs scipy says so. scipy is hidden by putting None in sys.modules."""
import contextlib
import re
import sys

import numpy as np
import pytest

import volrig
from volrig import _optional
from volrig import rig as rigmod

sparse = pytest.importorskip("scipy.sparse")
from scipy import ndimage  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402


@contextlib.contextmanager
def no_scipy():
    saved = {k: v for k, v in sys.modules.items() if k == "scipy" or k.startswith("scipy.")}
    for k in saved:
        sys.modules[k] = None
    sys.modules["scipy"] = None
    try:
        yield
    finally:
        for k in [k for k in sys.modules if k == "scipy" or k.startswith("scipy.")]:
            del sys.modules[k]
        sys.modules.update(saved)


def same(a, b):
    a, b = a.tocsr(), b.tocsr()
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.indptr, b.indptr) and \
        np.array_equal(a.indices, b.indices) and np.array_equal(a.data, b.data)


def test_no_scipy_hides_it():
    with no_scipy():
        assert not _optional.have_scipy()
    assert _optional.have_scipy()


def random_binding_inputs(rng):
    n, nb = int(rng.integers(1, 40)), int(rng.integers(1, 8))
    names = [f"b{i}" for i in range(nb)]
    groups = {}
    for b in range(nb):
        if rng.random() < 0.2:
            continue
        k = int(rng.integers(0, n + 1))
        idx = rng.choice(n, k, replace=False) if k else np.zeros(0, int)
        w = rng.choice([0.0, 0.5, 1.0, 0.25], k) if rng.random() < 0.5 else rng.random(k)  # ties too
        groups[names[b]] = (idx, w)
    bones = rng.integers(-1, nb, (n, 3))
    bones[:, 0] = rng.integers(0, nb, n)
    for i in range(n):  # distinct bones per point, -1 = unused
        u = np.unique(bones[i][bones[i] >= 0])
        bones[i] = np.r_[u, -np.ones(3 - len(u), int)]
    return n, names, groups, bones, rng.random((n, 3))


def test_weights_without_scipy_are_scipys_arrays():
    rng = np.random.default_rng(1)
    for _ in range(200):
        n, names, groups, bones, weights = random_binding_inputs(rng)
        nb = len(names)
        wm = rigmod.weights_matrix(bones, weights, nb)
        with no_scipy():
            wm0 = rigmod.weights_matrix(bones, weights, nb)
        assert isinstance(wm, sparse.csr_matrix) and isinstance(wm0, _optional.CSR) and same(wm, wm0)
        fallback = rigmod.Binding(np.zeros(n, np.int32), wm, "smooth", rng.random(n) < 0.3, names)
        if rng.random() < 0.3:
            fallback = None
        try:
            a = rigmod.Binding.from_groups(groups, names, n, fallback)
        except volrig.VolrigError as e:
            with no_scipy(), pytest.raises(volrig.VolrigError, match=re.escape(str(e))):
                rigmod.Binding.from_groups(groups, names, n, fallback)
            continue
        with no_scipy():
            b = rigmod.Binding.from_groups(groups, names, n, fallback)
        assert isinstance(a.weights, sparse.csr_matrix) and isinstance(b.weights, _optional.CSR)
        assert same(a.weights, b.weights) and np.array_equal(a.bone, b.bone) and a.mode == b.mode
        assert np.array_equal(a.unreachable, b.unreachable)
        pts, bone = rng.random(n) < 0.3, int(rng.integers(0, nb))
        r = a.reassign(pts, bone)
        with no_scipy():
            r0 = b.reassign(pts, bone)
        assert same(r.weights, r0.weights) and np.array_equal(r.bone, r0.bone)
        g = a.groups()
        with no_scipy():
            g0 = b.groups()
        assert all(np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1]) for x, y in zip(g, g0))


def test_csr_methods_match_scipy():
    rng = np.random.default_rng(2)
    for _ in range(50):
        n, nb = int(rng.integers(1, 30)), int(rng.integers(1, 6))
        dense = np.where(rng.random((n, nb)) < 0.4, rng.random((n, nb)), 0.0).astype(np.float32)
        dense[rng.random((n, nb)) < 0.1] = 0.0
        s = sparse.csr_matrix(dense)
        c = _optional.CSR(s.data, s.indices, s.indptr, s.shape)
        assert np.array_equal(c.toarray(), dense)
        sc, cc = s.tocsc(), c.tocsc()
        assert np.array_equal(sc.indptr, cc.indptr) and np.array_equal(sc.indices, cc.indices) and \
            np.array_equal(sc.data, cc.data)
        keep = np.flatnonzero(rng.random(n) < 0.5)
        mask = rng.random(n) < 0.5
        assert same(s[keep], c[keep]) and same(s[mask], c[mask])
        x = rng.random(nb)
        assert np.allclose(s @ x, c @ x, rtol=1e-12, atol=0)
        assert same(c.to_scipy(), s)
        z = _optional.CSR(np.array([0.0, 1.0, 0.0], np.float32), np.array([0, 1, 2]), np.array([0, 2, 3]), (2, 3))
        z.eliminate_zeros()
        assert np.array_equal(z.indptr, [0, 1, 1]) and np.array_equal(z.indices, [1])


def test_rotations_and_blur_without_scipy():
    R = np.concatenate([Rotation.random(500, random_state=3).as_matrix(),
                        [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]])
    assert np.array_equal(_optional.matrix_quaternions(R), Rotation.from_matrix(R).as_quat())
    for r in R[::20]:
        for t in (0.0, 0.3, 1.0, -0.7, 2.0):
            ref = Rotation.from_rotvec(Rotation.from_matrix(r).as_rotvec() * t).as_matrix()
            assert np.abs(_optional.rotation_power(r)(t) - ref).max() < 1e-13
    rng = np.random.default_rng(4)
    for shape, sigma in [((20, 30, 25), 1.5), ((2, 7, 9), 2.0), ((12, 10, 14), 0.6)]:
        a = (rng.random(shape) < 0.4).astype(np.float32)
        assert np.array_equal(_optional.gaussian_filter(a, sigma), ndimage.gaussian_filter(a, sigma))


@pytest.fixture(scope="module")
def phantom_rig():
    ph = volrig.phantom.humanoid(scale=0.25)
    mask = volrig.segment(ph.volume, lo=1.0)
    pts = volrig.skeletonize(mask).top(3000)
    tree = volrig.skeleton_tree(pts, mask, alpha=0.9)
    return ph, mask, pts, tree, volrig.autorig(pts, tree, mask)


def test_pipeline_without_scipy_gives_the_same_frames(phantom_rig, tmp_path):
    ph, mask, pts, tree, rig = phantom_rig
    M = volrig.rest_pose(len(rig.bones))
    M[:, :3, 3] += [3.0, 0.0, 0.0]
    M[-1] = volrig.rotation_about([0, 1, 0], 30.0, rig.joints[rig.bones[-1][0]]) @ M[-1]
    binding = volrig.bind(pts, rig, mask, mode="smooth")
    with_scipy = volrig.Deformer(ph.volume, pts, binding).frame(M, mode="linear").values
    with no_scipy():
        b0 = volrig.bind(pts, rig, mask, mode="smooth")
        assert isinstance(b0.weights, _optional.CSR)
        volrig.save_rig(str(tmp_path / "p.vrig"), pts, tree, rig, b0)
        r = volrig.load_rig(str(tmp_path / "p.vrig"))
        assert isinstance(r.binding.weights, _optional.CSR)
        frame = volrig.Deformer(ph.volume, pts, r.binding).frame(M, mode="linear").values
        assert same(b0.weights, binding.weights)
        assert np.array_equal(np.asarray(frame.array), np.asarray(with_scipy.array)) and \
            frame.origin == with_scipy.origin
        with pytest.raises(volrig.VolrigError, match=r"volrig.drawing .* needs scipy \(scipy.ndimage\)") as e:
            volrig.inflate(np.zeros((8, 8, 3), np.uint8))
        assert isinstance(e.value, ImportError)


def test_mesh_pose_without_scipy(phantom_rig):
    ph, mask, pts, tree, rig = phantom_rig
    rng = np.random.default_rng(5)
    inside = np.argwhere(np.asarray(mask.array))[rng.choice(int(np.asarray(mask.array).sum()), 200)]
    verts = np.asarray(mask.origin) + inside[:, ::-1] * np.asarray(mask.spacing)
    w = volrig.skin_weights(mask, rig, verts)
    M = volrig.rest_pose(len(rig.bones))
    M[-1] = volrig.rotation_about([1, 0, 0], 40.0, rig.joints[rig.bones[-1][0]])
    ref = {m: volrig.pose_vertices(verts, w, M, m) for m in ("linear", "dual_quaternion")}
    with no_scipy():
        w0 = volrig.skin_weights(mask, rig, verts)
        assert isinstance(w0, _optional.CSR) and same(w0, w)
        for m in ("linear", "dual_quaternion"):
            assert np.allclose(volrig.pose_vertices(verts, w0, M, m), ref[m], rtol=0, atol=1e-9), m

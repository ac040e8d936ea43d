"""The skeleton-tree (volrig.tree): synthetic shapes with known structure and brute-force references.

points_at and segment_sampled_inside are shared with test_rig.py."""
import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import minimum_spanning_tree

import volrig
from volrig import _volrig
from volrig.skeleton import SkeletonPoints
from volrig.tree import skeleton_tree


def points_at(ijk, radii, spacing=(1.0, 1.0, 1.0)):
    """SkeletonPoints for hand-placed voxels [z, y, x] (centres = ijk * spacing, origin 0)."""
    ijk = np.asarray(ijk, dtype=np.int32).reshape(-1, 3)
    centers = ijk[:, ::-1] * np.asarray(spacing)
    r = np.asarray(radii, dtype=np.float32) * np.ones(len(ijk), np.float32)
    return SkeletonPoints(ijk, centers, r, r, np.zeros(len(ijk), np.float32), "euclidean", tuple(spacing),
                          (0.0, 0.0, 0.0))


def segment_sampled_inside(mask, a, b, strict=False):
    """Independent containment check of the discrete line a-b ([z, y, x]): at each step of the driving axis the
    voxel nearest the segment must be object; where the segment passes exactly between two voxels, either one
    (or, with strict, both)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    steps = int(np.abs(b - a).max())
    for k in range(steps + 1):
        p = a + (b - a) * (k / steps if steps else 0.0)
        options = [[int(np.floor(c)), int(np.ceil(c))] if abs(c - np.floor(c) - 0.5) < 1e-9 else [int(round(c))]
                   for c in p]
        hits = [mask[z, y, x] for z in options[0] for y in options[1] for x in options[2]]
        if not (all(hits) if strict else any(hits)):
            return False
    return True


def test_ring_tree_is_the_cycle_minus_one_edge_and_never_crosses_the_hole():
    # A torus (ring radius 20, tube radius 4) and its centre circle as skeleton points.
    shape = (9, 61, 61)
    zz, yy, xx = np.indices(shape)
    rho = np.hypot(yy - 30, xx - 30)
    mask = (rho - 20) ** 2 + (zz - 4) ** 2 <= 16
    ang = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    ring = np.unique(np.stack([np.full(400, 4), np.rint(30 + 20 * np.sin(ang)), np.rint(30 + 20 * np.cos(ang))],
                              1).astype(int), axis=0)
    assert mask[ring[:, 0], ring[:, 1], ring[:, 2]].all()
    pts = points_at(ring, 4.0)
    for e in (1.8, 60.0):  # a large E would cross the hole if containment were not enforced
        tree = skeleton_tree(pts, mask, alpha=1.0, max_edge=e)
        n = len(pts)
        assert tree.component_count == 1 and len(tree) == n - 1
        for i, j in tree.edges:
            assert segment_sampled_inside(mask, ring[i], ring[j])
            assert np.linalg.norm(pts.centers[i] - pts.centers[j]) <= 3.0  # neighbours along the ring, not chords
        deg = tree.degree()
        assert (deg == 1).sum() == 2 and (deg == 2).sum() == n - 2  # a path: the cycle minus one edge
        a, b = np.flatnonzero(deg == 1)
        assert np.linalg.norm(pts.centers[a] - pts.centers[b]) <= 1.8  # the removed edge joins the two ends


def test_tree_weight_equals_brute_force_mst_in_a_convex_object():
    rng = np.random.default_rng(3)
    mask = np.ones((20, 22, 24), bool)
    ijk = np.unique(rng.integers(0, [20, 22, 24], size=(300, 3)), axis=0)
    pts = points_at(ijk, rng.uniform(1, 5, len(ijk)))
    tree = skeleton_tree(pts, mask, alpha=1.0, max_edge=100.0)
    d = np.linalg.norm(pts.centers[:, None] - pts.centers[None], axis=-1)
    reference = minimum_spanning_tree(csr_matrix(np.triu(d, 1))).sum()
    assert tree.component_count == 1
    assert tree.weights.sum() == pytest.approx(reference, rel=1e-9)
    # alpha < 1 adds the radius term: never below the brute force over all pairs
    tree9 = skeleton_tree(pts, mask, alpha=0.9, max_edge=100.0)
    w = 0.9 * d + 0.1 * np.abs(pts.radii[:, None] - pts.radii[None])
    ref9 = minimum_spanning_tree(csr_matrix(np.triu(w, 1))).sum()
    assert ref9 * (1 - 1e-6) <= tree9.weights.sum() <= ref9 * 1.02


def test_separate_parts_stay_apart_unless_bridged():
    mask = np.zeros((10, 10, 30), bool)
    mask[2:8, 2:8, 2:12] = True
    mask[2:8, 2:8, 15:28] = True  # a gap of 3 voxels
    ijk = np.array([[5, 5, x] for x in list(range(4, 11)) + list(range(17, 27))])
    pts = points_at(ijk, 2.0)
    tree = skeleton_tree(pts, mask, max_edge=20.0)
    assert tree.component_count == 2 and len(tree) == len(ijk) - 2 and not tree.bridged.any()
    bridged = skeleton_tree(pts, mask, max_edge=20.0, bridge=True)
    assert bridged.component_count == 1 and bridged.bridged.sum() == 1
    i, j = bridged.edges[bridged.bridged][0]
    assert {int(ijk[i, 2]), int(ijk[j, 2])} == {10, 17}  # the closest pair across the gap


def test_line_inside_matches_an_independent_check():
    rng = np.random.default_rng(7)
    mask = rng.random((12, 13, 14)) < 0.85
    for _ in range(400):
        a, b = rng.integers(0, [12, 13, 14], size=(2, 3))
        got = _volrig.line_inside(mask.view(np.uint8), tuple(int(v) for v in a), tuple(int(v) for v in b))
        if got:  # Bresenham visits a subset of the voxels near the segment, all of them object
            assert mask[tuple(a)] and mask[tuple(b)]
        if segment_sampled_inside(mask, a, b, strict=True):  # every voxel near the segment is object
            assert got


def test_tree_errors_are_clear():
    mask = np.zeros((5, 5, 5), bool)
    mask[1:4, 1:4, 1:4] = True
    with pytest.raises(volrig.VolrigError, match="not an object voxel"):
        skeleton_tree(points_at([[0, 0, 0]], 1.0), mask)
    with pytest.raises(volrig.VolrigError, match="outside the mask's grid"):
        skeleton_tree(points_at([[9, 2, 2]], 1.0), mask)
    with pytest.raises(ValueError, match="alpha"):
        skeleton_tree(points_at([[2, 2, 2]], 1.0), mask, alpha=1.5)
    with pytest.raises(ValueError, match="max_edge"):
        skeleton_tree(points_at([[2, 2, 2]], 1.0), mask, max_edge=-1)
    pts = points_at([[2, 2, 2]], 1.0)
    bad = SkeletonPoints(pts.ijk, pts.centers, np.array([np.nan], np.float32), pts.dt, pts.scores, "euclidean",
                         pts.spacing, pts.origin)
    with pytest.raises(volrig.VolrigError, match="radius"):
        skeleton_tree(bad, mask)

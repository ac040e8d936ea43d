"""Centerlines, centerline trees and straightening (issue 20) on synthetic tubes with known centerlines, and on the
shared airway tree (skipped when ../shared/data is absent)."""
import time

import numpy as np
import pytest
from scipy.spatial import cKDTree

import volrig
from conftest import shared


def tube(curve, radius, spacing=(1.0, 1.0, 1.0), pad=3):
    """A bool Volume of the voxels within ``radius`` (a number or one per curve point) of a densely sampled curve
    (M, 3), cut flat at both ends (perpendicular to the curve)."""
    curve = np.asarray(curve, float)
    sp = np.asarray(spacing, float)
    r = np.broadcast_to(np.asarray(radius, float), (len(curve),))
    lo = curve.min(0) - r.max() - pad * sp
    dims = np.ceil((curve.max(0) + r.max() + pad * sp - lo) / sp).astype(int) + 1
    axes = [lo[a] + sp[a] * np.arange(dims[a]) for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    q = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    d, i = cKDTree(curve).query(q, distance_upper_bound=1.5 * r.max())
    ok = np.isfinite(d)
    inside = np.zeros(len(q), bool)
    inside[ok] = d[ok] <= r[i[ok]]
    for end, nxt in ((0, 1), (len(curve) - 1, len(curve) - 2)):  # flat caps: nothing beyond the end planes
        t = curve[end] - curve[nxt]
        inside &= ~((i == end) & ((q - curve[end]) @ (t / np.linalg.norm(t)) > 1e-9))
    return volrig.Volume(inside.reshape(z.shape), tuple(sp), tuple(lo))


def distances(points, curve):
    return cKDTree(curve).query(points)[0]


def arc(curve):
    return float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())


def torus_segment(bend=25.0, angle=1.5 * np.pi, n=20000):
    t = np.linspace(0, angle, n)
    return np.stack([bend * np.cos(t), bend * np.sin(t), 0 * t], 1)


def helix(radius=15.0, pitch=30.0, turns=2.0, n=40000):
    t = np.linspace(0, 2 * np.pi * turns, n)
    return np.stack([radius * np.cos(t), radius * np.sin(t), pitch * t / (2 * np.pi)], 1)


def segment(a, b, n=4000):
    return np.linspace(a, b, n)


@pytest.fixture(scope="module")
def helix_tube():
    c = helix()
    return c, tube(c, 4.0)


@pytest.mark.parametrize("name", ["torus", "helix"])
def test_centerline_follows_the_analytic_axis(name, helix_tube):
    c, m = (torus_segment(), tube(torus_segment(), 4.0)) if name == "torus" else helix_tube
    cl = volrig.centerline(m)
    d = distances(cl.points, c)
    assert d.mean() < 0.5, d.mean()
    assert d.max() < 1.5, d.max()
    assert abs(cl.length - arc(c)) < 0.02 * arc(c), (cl.length, arc(c))
    steps = np.linalg.norm(np.diff(cl.points, axis=0), axis=1)
    assert np.allclose(steps, cl.step, rtol=0.02)          # equal arc length
    assert cl.step <= 1.0 + 1e-9
    assert abs(np.median(cl.radii) - 4.0) < 1.0            # the DT: largest inscribed ball
    # either end is at the centre of a cap
    ends = sorted([np.linalg.norm(cl.points[0] - c[0]), np.linalg.norm(cl.points[-1] - c[0])])
    assert ends[0] < 1.0
    assert min(np.linalg.norm(cl.points[0] - c[-1]), np.linalg.norm(cl.points[-1] - c[-1])) < 1.0


def test_given_endpoints_are_snapped_and_kept(helix_tube):
    c, m = helix_tube
    start, end = c[2000] + [0.0, 0.0, 2.5], c[30000]      # start off-centre, inside the tube
    cl = volrig.centerline(m, start=start, end=end)
    assert np.linalg.norm(cl.points[0] - c[2000]) < 2.0     # moved towards the middle of its cross-section
    assert np.linalg.norm(cl.points[-1] - end) < 1.0
    assert distances(cl.points, c).mean() < 0.5
    assert abs(cl.length - arc(c[2000:30001])) < 0.02 * arc(c[2000:30001])


def test_varying_radius_on_an_anisotropic_grid():
    t = np.linspace(0, 1, 20000)
    c = np.stack([60 * t, 12 * np.sin(np.pi * t), 8 * np.cos(2 * np.pi * t)], 1)
    r = 2.5 + 3.0 * t                                       # 2.5 mm to 5.5 mm
    m = tube(c, r, spacing=(0.6, 0.7, 1.1))
    cl = volrig.centerline(m)
    d = distances(cl.points, c)
    assert d.mean() < 0.5 * 0.6, d.mean()                   # half the finest voxel
    nearest = cKDTree(c).query(cl.points)[1]
    inner = (nearest > 2000) & (nearest < len(c) - 2000)   # a radius away from the caps
    assert np.abs(cl.radii[inner] - r[nearest[inner]]).max() < 1.1   # within a voxel of the true radius
    assert abs(cl.length - arc(c)) < 0.02 * arc(c)


def test_touching_loop_and_one_voxel_bridge_are_not_shortcuts():
    # a U whose arms (radius 3, axes 7 apart) nearly touch, joined by one-voxel bridges, with a blind pouch
    t = np.linspace(0, np.pi, 4000)
    bend = np.stack([3.5 - 3.5 * np.cos(t), -3.5 * np.sin(t), 0 * t], 1)
    u = np.concatenate([segment([0, 40, 0], [0, 0, 0]), bend, segment([7, 0, 0], [7, 40, 0])])
    m = tube(u, 3.0)
    a = m.array.copy()
    sp, org = np.array(m.spacing), np.array(m.origin)

    def index(p):
        return np.round((np.asarray(p, float) - org) / sp).astype(int)

    for y in (10, 20, 30):                                  # bridges across the gap
        i0, i1 = index([0, y, 0]), index([7, y, 0])
        a[i0[2], i0[1], i0[0]:i1[0] + 1] = True
    pouch = tube(segment([0, 25, 0], [0, 25, 9]), 2.5)      # a blind pouch off the first arm
    pz, py, px = np.nonzero(pouch.array)
    idx = index(np.stack([px, py, pz], 1) * np.array(pouch.spacing) + np.array(pouch.origin))
    ok = np.all((idx >= 0) & (idx < np.array(m.dims)), axis=1)
    a[idx[ok, 2], idx[ok, 1], idx[ok, 0]] = True
    m = volrig.Volume(a, m.spacing, m.origin)
    cl = volrig.centerline(m, start=[0, 40, 0], end=[7, 40, 0])
    d = distances(cl.points, u)
    assert d.mean() < 0.5 and d.max() < 1.5, (d.mean(), d.max())
    assert abs(cl.length - arc(u)) < 0.03 * arc(u)          # round the U (91 long), not across a bridge (7)


def test_holes_in_the_lumen_and_the_wall(helix_tube):
    c, m = helix_tube
    sp, org = np.array(m.spacing), np.array(m.origin)
    cavities, walls = m.array.copy(), m.array.copy()
    for k in range(2000, 38000, 3000):
        i = np.round((c[k] - org) / sp).astype(int)              # a 2-voxel cavity on the axis
        cavities[i[2] - 1:i[2] + 1, i[1] - 1:i[1] + 1, i[0] - 1:i[0] + 1] = False
        out = np.array([np.cos(k / 40000 * 4 * np.pi), np.sin(k / 40000 * 4 * np.pi), 0])
        i = np.round((c[k] + 3.5 * out - org) / sp).astype(int)  # a 3-voxel hole through the wall
        walls[i[2] - 1:i[2] + 2, i[1] - 1:i[1] + 2, i[0] - 1:i[0] + 2] = False
    for a in (cavities, walls):
        cl = volrig.centerline(volrig.Volume(a, m.spacing, m.origin))
        d = distances(cl.points, c)
        assert d.mean() < 0.5 and d.max() < 2.0, (d.mean(), d.max())
        assert abs(cl.length - arc(c)) < 0.02 * arc(c)


def y_branch():
    stem = segment([0, 0, 0], [0, 0, 40])
    left = segment([0, 0, 40], [-25, 0, 70])
    right = segment([0, 0, 40], [25, 0, 70])
    return stem, left, right


def test_y_branch_centerline_and_tree():
    stem, left, right = y_branch()
    m = tube(np.concatenate([stem, left[::-1], left, right]), 4.0)
    # flat caps were cut at the concatenation's ends only; cut the right arm's end too
    tr = volrig.centerline_tree(m, root=[0, 0, 0])
    assert len(tr) == 3, tr.lengths
    assert list(tr.generations) == [0, 1, 1]
    assert list(tr.parents) == [-1, 0, 0]
    bp = tr.branch_points
    assert len(bp) == 1 and np.linalg.norm(bp[0] - [0, 0, 40]) < 4.0     # within a radius of the true fork
    assert distances(tr.branches[0].points, stem).mean() < 0.5
    for b in tr.branches[1:]:
        arm = left if b.points[-1][0] < 0 else right
        far = np.linalg.norm(b.points - [0, 0, 40], axis=1) > 8.0          # away from the fork itself
        assert distances(b.points[far], arm).mean() < 0.5
    cl = volrig.centerline(m, start=[0, 0, 0], end=[25, 0, 70])
    assert distances(cl.points, np.concatenate([stem, right])).mean() < 0.5


def test_bad_input_is_a_clear_error(helix_tube):
    c, m = helix_tube
    with pytest.raises(volrig.VolrigError, match="empty"):
        volrig.centerline(np.zeros((5, 5, 5), bool))
    with pytest.raises(volrig.VolrigError, match="not on the object"):
        volrig.centerline(m, start=[500.0, 0, 0])
    with pytest.raises(volrig.VolrigError, match="not on the object"):
        volrig.centerline(m, start=c[100], end=[0.0, 0.0, 15.0])   # the helix's axis: outside the tube
    with pytest.raises(volrig.VolrigError, match="finite"):
        volrig.centerline(m, start=[np.nan, 0, 0])
    with pytest.raises(volrig.VolrigError, match="NaN"):
        volrig.centerline(np.full((4, 4, 4), np.nan))
    two = np.zeros((5, 5, 20), bool)
    two[1:4, 1:4, 1:8] = two[1:4, 1:4, 12:19] = True
    with pytest.raises(volrig.VolrigError, match="different parts"):
        volrig.centerline(two, start=[2, 2, 2], end=[15, 2, 2])
    with pytest.raises(volrig.VolrigError, match="empty"):
        volrig.centerline_tree(np.zeros((5, 5, 5), bool))
    cl = volrig.centerline(m)
    with pytest.raises(volrig.VolrigError, match="radius"):
        volrig.straighten(m, cl, float("nan"))


def test_straightened_helix_is_a_straight_tube(helix_tube):
    c, m = helix_tube
    cl = volrig.centerline(m)
    vol = volrig.Volume(m.array.astype(np.float32), m.spacing, m.origin)
    straight, where = volrig.straighten(vol, cl, radius=8.0)
    a = straight.array
    assert a.shape == (len(cl), 2 * where.half + 1, 2 * where.half + 1)
    inside = a >= 0.5
    area = inside.sum(axis=(1, 2)) * where.step ** 2
    full = area > 0.5 * np.pi * 16
    r = np.sqrt(area[full] / np.pi)
    assert np.abs(r - 4.0).max() < 1.0, r                  # same radius, within a voxel, all along
    length = full.sum() * cl.step
    assert abs(length - arc(c)) < 0.02 * arc(c), (length, arc(c))
    # straight: the tube's cross-sections are centred on the axis
    b, x = np.mgrid[0:a.shape[1], 0:a.shape[2]] - where.half
    cx = (inside * x).sum(axis=(1, 2))[full] / inside.sum(axis=(1, 2))[full]
    cy = (inside * b).sum(axis=(1, 2))[full] / inside.sum(axis=(1, 2))[full]
    off = np.hypot(cx, cy) * where.step
    assert off[4:-4].max() < 0.75 and off.max() < 1.5, off  # the last few slices hold the cap
    # the map back: the axis lands on the centerline, an off-axis sample where it was taken
    k = np.arange(len(cl))
    axis = where.to_world(np.stack([0 * k + where.half, 0 * k + where.half, k], 1))
    assert np.allclose(axis, cl.points)
    p = where.to_world([[where.half + 3, where.half, 10]])[0]
    assert abs(np.linalg.norm(p - cl.points[10]) - 3 * where.step) < 1e-9
    assert abs(np.dot(p - cl.points[10], cl.tangents()[10])) < 0.05


def test_airway_tree():
    v = volrig.load(str(shared("airway/Patient1_bronchialTree.nii.gz")))
    m = volrig.Volume(v.array != 0, v.spacing, v.origin)
    t0 = time.perf_counter()
    tr = volrig.centerline_tree(m)
    elapsed = time.perf_counter() - t0
    print(f"airway tree: {len(tr)} branches in {elapsed:.2f} s")
    trachea = tr.branches[0]
    assert tr.parents[0] == -1 and tr.generations[0] == 0
    assert trachea.length > 60.0                           # mm
    assert np.median(trachea.radii) == max(np.median(b.radii) for b in tr.branches)
    top = np.array(m.origin) + np.array(m.spacing) * np.array(m.dims)
    assert trachea.points[0][2] > top[2] - 10.0             # it starts where the scan cuts the trachea (top)
    mains = tr.children(0)
    assert len(mains) == 2, mains                          # both main bronchi
    for k in mains:
        b = tr.branches[k]
        assert b.length > 15.0 and np.median(b.radii) > 3.0, (b.length, np.median(b.radii))
        assert len(tr.children(k)) >= 2
    sides = [tr.branches[k].points[-1][0] for k in mains]
    assert min(sides) < trachea.points[-1][0] < max(sides)  # one to each side of the carina
    assert len(tr) >= 20 and tr.generations.max() >= 4
    # every branch point lies inside the lumen
    ijk = np.round((tr.branch_points - np.array(m.origin)) / np.array(m.spacing)).astype(int)
    assert m.array[ijk[:, 2], ijk[:, 1], ijk[:, 0]].all()
    # so does every centerline sample, nearly
    pts = np.concatenate([b.points for b in tr.branches])
    ijk = np.round((pts - np.array(m.origin)) / np.array(m.spacing)).astype(int)
    assert m.array[ijk[:, 2], ijk[:, 1], ijk[:, 0]].mean() > 0.98
    # the root given where the automatic one is: a trachea and two main bronchi again; the carina (where the minimal
    # paths merge) may move up to two radii
    again = volrig.centerline_tree(m, root=tr.root)
    assert len(again.children(0)) == 2
    assert abs(again.branches[0].length - trachea.length) < 2 * np.median(trachea.radii) + 1
    assert abs(len(again) - len(tr)) <= 3


def test_cli_writes_csv(tmp_path, helix_tube, capsys):
    from volrig.cli import main
    c, m = helix_tube
    src = tmp_path / "tube.nrrd"
    volrig.Volume(m.array.astype(np.uint8), m.spacing, m.origin).save(str(src))
    out = tmp_path / "line.csv"
    assert main(["centerline", str(src), "--start", *map(str, c[1000]), "--end", *map(str, c[-1000]),
                 "-o", str(out)]) == 0
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert open(out).readline().strip() == "branch,parent,generation,index,x,y,z,radius,arc_length"
    assert distances(rows[:, 4:7], c).mean() < 0.5
    assert np.all(rows[:, 0] == 0) and np.all(np.diff(rows[:, 8]) > 0)
    assert main(["centerline", str(src), "--tree", "-o", str(tmp_path / "tree.csv")]) == 0
    assert main(["centerline", str(src), "--start", "900", "0", "0", "-o", str(out)]) == 2
    assert "not on the object" in capsys.readouterr().err
    assert main(["centerline", str(src), "-o", str(tmp_path / "line.txt")]) == 2

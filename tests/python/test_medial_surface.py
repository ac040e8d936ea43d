"""volrig.medial_surface: plates, shells and bent sheets of known area and thickness on anisotropic grids (area
within 5%, thickness within a voxel, a manifold with the plate's Euler characteristic), a plate with a rod, the
skeleton's topology against scipy's component counts, world positions with an origin."""
import numpy as np
import pytest
from scipy import ndimage

import volrig


def field(shape, spacing):
    z, y, x = np.indices(shape).astype(float)
    return x * spacing[0], y * spacing[1], z * spacing[2]


def disc(spacing=(1.0, 0.9, 1.5), R=30.0, r=3.0, origin=(0.0, 0.0, 0.0)):
    n = (int((2 * r + 12) / spacing[2]) + 1, int((2 * R + 12) / spacing[1]) + 1, int((2 * R + 12) / spacing[0]) + 1)
    X, Y, Z = field(n, spacing)
    c = (R + 6.13, R + 6.21, r + 6.07)
    rho, dz = np.hypot(X - c[0], Y - c[1]), Z - c[2]
    d = np.where(rho <= R, np.abs(dz), np.hypot(rho - R, dz))
    return volrig.Volume(d < r, spacing, origin), c


def shell(spacing=(1.0, 1.2, 1.4), R=20.0, r=2.5):
    n = [int((2 * (R + r) + 8) / s) + 1 for s in spacing][::-1]
    X, Y, Z = field(n, spacing)
    c = (R + r + 4.1, R + r + 4.2, R + r + 4.05)
    d = np.abs(np.sqrt((X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2) - R)
    return volrig.Volume(d < r, spacing), c


def bent(spacing=(1.0, 1.3, 0.9), R=24.0, angle=2.0, H=40.0, r=3.0):
    ext = (2 * R + 2 * r + 8, H + 2 * r + 8, R + 2 * r + 8)
    n = [int(e / s) + 1 for e, s in zip(ext, spacing)][::-1]
    X, Y, Z = field(n, spacing)
    cx, y0, cz = R + r + 4.1, r + 4.0, -R * np.cos(angle / 2) + r + 4.1
    x, z = X - cx, Z - cz
    phi = np.clip(np.arctan2(x, z), -angle / 2, angle / 2)
    yc = np.clip(Y - y0, 0, H)
    d = np.sqrt((x - R * np.sin(phi)) ** 2 + (z - R * np.cos(phi)) ** 2 + (Y - y0 - yc) ** 2)
    return volrig.Volume(d < r, spacing), R * angle * H


def check_manifold(s, chi):
    f = np.asarray(s.faces)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() <= 2, "an edge with more than two faces"
    assert len(np.unique(np.sort(f, axis=1), axis=0)) == len(f), "duplicate faces"
    assert np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])), "degenerate faces"
    # Consistent orientation: every interior edge is used once in each direction.
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed), "two faces traverse an edge the same way"
    assert s.euler_characteristic() == chi


def skeleton_topology(mask):
    """Components of the object (26-connected) and of the padded background (6-connected)."""
    objects = ndimage.label(mask, structure=np.ones((3, 3, 3)))[1]
    back = ndimage.label(np.pad(~mask, 1, constant_values=True), structure=ndimage.generate_binary_structure(3, 1))[1]
    return objects, back


def test_api_types_and_disc_plate():
    m, c = disc()
    s = volrig.medial_surface(m, t=5.0)
    assert isinstance(s, volrig.MedialSurface)
    assert s.vertices.shape[1] == 3 and s.vertices.dtype == np.float64
    assert s.faces.shape[1] == 3 and np.issubdtype(s.faces.dtype, np.integer)
    assert s.thickness.shape == (len(s.vertices),)
    assert s.faces.max() < len(s.vertices)
    assert s.rods == [] and s.rod_radii == []
    assert abs(s.area / (np.pi * 30.0 ** 2) - 1) < 0.05
    assert abs(np.median(s.thickness) - 6.0) <= 1.5
    assert np.abs(s.vertices[:, 2] - c[2]).max() < 0.75
    check_manifold(s, 1)
    sk = s.skeleton.array
    assert set(np.unique(sk)) <= {0, 1, 2, 3}
    assert skeleton_topology(sk > 0) == skeleton_topology(m.array)


def test_world_positions_follow_origin_and_spacing():
    m, c = disc(R=12.0, origin=(10.0, -5.0, 2.5))
    s = volrig.medial_surface(m, t=5.0)
    assert np.abs(s.vertices[:, 2] - (c[2] + 2.5)).max() < 0.75
    centre = s.vertices[:, :2].mean(axis=0)
    assert np.allclose(centre, (c[0] + 10.0, c[1] - 5.0), atol=0.5)


def test_spherical_shell_is_a_closed_sphere():
    m, c = shell()
    s = volrig.medial_surface(m, 5.0)
    assert abs(s.area / (4 * np.pi * 20.0 ** 2) - 1) < 0.05
    assert abs(np.median(s.thickness) - 5.0) <= 1.4
    check_manifold(s, 2)
    radius = np.linalg.norm(s.vertices - np.asarray(c), axis=1)
    assert np.abs(radius - 20.0).max() < 1.0
    assert skeleton_topology(s.skeleton.array > 0) == skeleton_topology(m.array)


def test_bent_sheet():
    m, area = bent()
    s = volrig.medial_surface(m, 5.0)
    assert abs(s.area / area - 1) < 0.05
    assert abs(np.median(s.thickness) - 6.0) <= 1.3
    check_manifold(s, 1)


def test_plate_with_rod_is_surface_and_rod():
    sp = (1.0, 1.0, 1.4)
    R, r, rod, length = 16.0, 2.5, 2.0, 14.0
    n = (int((2 * r + length + 12) / sp[2]) + 1, int((2 * R + 12) / sp[1]) + 1, int((2 * R + 12) / sp[0]) + 1)
    X, Y, Z = field(n, sp)
    cx, cy, cz = R + 6.13, R + 6.21, r + 4.0
    rho, dz = np.hypot(X - cx, Y - cy), Z - cz
    plate = np.where(rho <= R, np.abs(dz), np.hypot(rho - R, dz)) < r
    rod_mask = (np.hypot(X - cx - 5, Y - cy) < rod) & (Z > cz) & (Z < cz + r + length)
    m = volrig.Volume(plate | rod_mask, sp)
    s = volrig.medial_surface(m, 5.0)
    classes = np.bincount(s.skeleton.array.ravel(), minlength=4)
    assert classes[1] > 300 and classes[2] >= 5 and classes[3] >= 1
    assert len(s.rods) == 1
    line, radii = s.rods[0], s.rod_radii[0]
    assert line.shape[1] == 3 and len(line) == len(radii) >= 6
    assert np.all(np.hypot(line[:, 0] - cx - 5, line[:, 1] - cy) < 1.5)
    assert np.all(np.abs(radii - rod) <= 1.0)
    check_manifold(s, 1)
    assert skeleton_topology(s.skeleton.array > 0) == skeleton_topology(m.array)


def test_random_blobs_keep_their_topology():
    rng = np.random.default_rng(3)
    for _ in range(5):
        shape = (10, 12, 14)
        z, y, x = np.indices(shape)
        mask = np.zeros(shape, bool)
        for k in range(6):
            c, rad = rng.uniform(0, 1, 3) * (9, 11, 13), rng.uniform(1.5, 4.5)
            ball = (z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2 < rad * rad
            mask = (mask & ~ball) if k >= 4 else (mask | ball)
        s = volrig.medial_surface(volrig.Volume(mask, (1.0, 1.1, 1.3)), 5.0)
        skel = s.skeleton.array > 0
        assert not np.any(skel & ~mask)
        assert skeleton_topology(skel) == skeleton_topology(mask)


def test_errors_and_empty():
    with pytest.raises(volrig.VolrigError):
        volrig.medial_surface(np.ones((4, 4, 4), bool), t=0)
    s = volrig.medial_surface(np.zeros((5, 6, 7), bool))
    assert s.vertices.shape == (0, 3) and s.faces.shape == (0, 3) and s.area == 0.0
    with pytest.raises(volrig.VolrigError):
        volrig.medial_surface(np.ones((4, 4), bool))


def test_t_junction_of_plates_is_cut_into_two_manifold_sheets():
    """A plate standing on another (rounded rims, 6 thick): at the junction the mesh keeps the two best-joined faces
    of each edge, so the standing plate's sheet comes loose: two discs (Euler characteristic 2), a manifold."""
    sp = (1.0, 1.1, 1.3)
    X, Y, Z = field((int(50 / sp[2]), int(60 / sp[1]), int(60 / sp[0])), sp)

    def box_distance(lo, hi):
        d = [np.maximum(np.maximum(lo[i] - P, P - hi[i]), 0) for i, P in enumerate((X, Y, Z))]
        return np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)

    floor = box_distance((8, 8, 10.1), (52, 52, 10.1)) < 3
    wall = box_distance((8, 30.2, 10.1), (52, 30.2, 42)) < 3
    m = volrig.Volume(floor | wall, sp)
    s = volrig.medial_surface(m, 5.0)
    check_manifold(s, 2)
    # the analytic medial surface: the floor's 44 x 44 and the wall's 44 x 31.9 above it; the junction loses some
    assert abs(s.area / (44 * 44 + 44 * 31.9) - 1) < 0.10
    assert skeleton_topology(s.skeleton.array > 0) == skeleton_topology(m.array)


def test_progress_and_cancel():
    m, _ = disc(R=10.0)
    seen = []
    volrig.medial_surface(m, 5.0, progress=lambda f: seen.append(f) or True)
    assert seen == sorted(seen) and seen[-1] == 1.0
    with pytest.raises(volrig.Cancelled):
        volrig.medial_surface(m, 5.0, progress=lambda f: False)


def read_ply(path):
    """(vertices (V, 4): x, y, z, thickness; faces (F, 3); edges (E, 2)) of a PLY save_ply wrote."""
    data = open(path, "rb").read()
    head, body = data.split(b"end_header\n", 1)
    counts = {l.split()[1].decode(): int(l.split()[2]) for l in head.splitlines() if l.startswith(b"element")}
    v = np.frombuffer(body, "<f4", counts["vertex"] * 4).reshape(-1, 4)
    body = body[v.nbytes:]
    f = np.frombuffer(body, dtype=[("n", "u1"), ("i", "<i4", 3)], count=counts["face"])
    body = body[f.nbytes:]
    e = np.frombuffer(body, "<i4", counts["edge"] * 2).reshape(-1, 2)
    assert len(body) == e.nbytes and np.all(f["n"] == 3)
    return v, f["i"], e


def test_cli_writes_the_medial_surface_as_ply(tmp_path):
    import subprocess
    import sys
    sp = (1.0, 1.0, 1.4)
    X, Y, Z = field((30, 44, 44), sp)
    rho, dz = np.hypot(X - 22.13, Y - 22.21), Z - 7.0
    plate = np.where(rho <= 16.0, np.abs(dz), np.hypot(rho - 16.0, dz)) < 3.0
    rod = (np.hypot(X - 27.13, Y - 22.21) < 2.0) & (Z > 7.0) & (Z < 27.0)
    vol = volrig.Volume(np.where(plate | rod, 200, 0).astype(np.uint8), sp, (5.0, -3.0, 2.0))
    src, out = tmp_path / "plate.nrrd", tmp_path / "plate.ply"
    vol.save(str(src))
    r = subprocess.run([sys.executable, "-m", "volrig", "medial", str(src), "--lo", "100", "-o", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "triangles" in r.stdout and "rods" in r.stdout
    want = volrig.medial_surface(volrig.Volume(vol.array >= 100, sp, vol.origin), 5.0)
    v, f, e = read_ply(out)
    nv = len(want.vertices)
    np.testing.assert_allclose(v[:nv, :3], want.vertices, atol=1e-4)
    np.testing.assert_allclose(v[:nv, 3], want.thickness, rtol=1e-5)
    np.testing.assert_array_equal(f, want.faces)
    assert len(v) == nv + sum(len(r) for r in want.rods) and len(e) == sum(len(r) - 1 for r in want.rods) > 0
    np.testing.assert_allclose(v[nv:, 3], 2 * np.concatenate(want.rod_radii), rtol=1e-5)
    bad = subprocess.run([sys.executable, "-m", "volrig", "medial", str(src), "-o", str(tmp_path / "m.obj")],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and "must be .ply" in bad.stderr

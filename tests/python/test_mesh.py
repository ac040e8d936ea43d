"""Meshes in through the Python API: read_mesh (OBJ, PLY, OFF, STL, Medit) / read_tgf / voxelize, their errors, the
arm, knight, cow, lion and hand in ../shared/data, and `python -m volrig rig` on a mesh.

Run: PYTHONPATH=python /usr/bin/python3 -m pytest tests/python/test_mesh.py
"""
from __future__ import annotations

import os
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

import volrig
from conftest import REPO, shared
from volrig.segment import label_components

# ---- meshes made here ------------------------------------------------------------------------------------------

BOX_QUADS = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]


def box(lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)):
    """The box [lo, hi]: 8 vertices and the 12 triangles the readers make of its 6 quads."""
    v = np.array([[hi[0] if (k & 1) ^ ((k >> 1) & 1) else lo[0], hi[1] if k & 2 else lo[1],
                   hi[2] if k & 4 else lo[2]] for k in range(8)], float)
    f = np.array([t for q in BOX_QUADS for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))], np.int64)
    return v, f


def icosphere(levels=3, radius=1.0, centre=(0.0, 0.0, 0.0)):
    t = (1 + 5 ** 0.5) / 2
    v = [np.array(p, float) for p in [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                                      (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    v = [p / np.linalg.norm(p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid, g = {}, []

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = v[a] + v[b]
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]

        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            g += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = g
    return np.array(v) * radius + np.asarray(centre), np.array(f, np.int64)


def mesh_volume(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6


def write_obj(path, v, f, quads=False):
    lines = ["# test mesh", "o thing"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()] + ["vn 0 0 1", "vt 0 0"]
    if quads:
        lines += ["f " + " ".join(f"{i + 1}/1/1" for i in q) for q in BOX_QUADS]
    else:
        lines += [f"f {a + 1}//1 {b + 1}//1 {c + 1}//1" for a, b, c in f.tolist()]
    path.write_text("\n".join(lines) + "\n")


def write_ply(path, v, f, encoding):
    head = ["ply", f"format {encoding} 1.0", f"element vertex {len(v)}", "property double x", "property double y",
            "property double z", "property uchar red", f"element face {len(f)}",
            "property list uchar int vertex_indices", "end_header"]
    body = b""
    if encoding == "ascii":
        body = ("\n".join(f"{x!r} {y!r} {z!r} 7" for x, y, z in v.tolist()) + "\n"
                + "\n".join(f"3 {a} {b} {c}" for a, b, c in f.tolist()) + "\n").encode()
    else:
        e = "<" if encoding == "binary_little_endian" else ">"
        body = b"".join(struct.pack(e + "dddB", *p, 7) for p in v.tolist())
        body += b"".join(struct.pack(e + "Biii", 3, *t) for t in f.tolist())
    path.write_bytes(("\n".join(head) + "\n").encode() + body)


def write_off(path, v, f, quads=False):
    faces = [f"4 {' '.join(map(str, q))} 0.5 0.5 0.5" for q in BOX_QUADS] if quads else \
        [f"3 {a} {b} {c}" for a, b, c in f.tolist()]
    path.write_text(f"COFF\n# test mesh\n{len(v)} {len(faces)} 0\n" +
                    "".join(f"{x!r} {y!r} {z!r} 255 255 255 255\n" for x, y, z in v.tolist()) + "\n".join(faces) + "\n")


def write_medit(path, v, f, quads=False):
    cells = ("Quadrilaterals\n6\n" + "".join(" ".join(str(i + 1) for i in q) + " 1\n" for q in BOX_QUADS)) if quads \
        else f"Triangles\n{len(f)}\n" + "".join(f"{a + 1} {b + 1} {c + 1} 0\n" for a, b, c in f.tolist())
    path.write_text(f"MeshVersionFormatted 2\nDimension 3\nVertices\n{len(v)}\n" +
                    "".join(f"{x!r} {y!r} {z!r} 0\n" for x, y, z in v.tolist()) + cells + "End\n")


def write_stl(path, v, f, binary, header=b"binary STL from test_mesh.py"):
    if binary:
        records = b"".join(struct.pack("<12fH", 0, 0, 1, *v[t].ravel(), 0) for t in f)
        path.write_bytes(header.ljust(80, b" ") + struct.pack("<I", len(f)) + records)
        return
    facets = "".join("facet normal 0 0 0\n outer loop\n" + "".join(f"  vertex {x!r} {y!r} {z!r}\n" for x, y, z in
                                                                     v[t].tolist()) + " endloop\nendfacet\n" for t in f)
    path.write_text(f"solid test\n{facets}endsolid test\n")


def boundary_edges(f):
    """Edges used by exactly one triangle."""
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    edges, uses = np.unique(e, axis=0, return_counts=True)
    return edges[uses == 1]


# ---- reading ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fmt", ["obj", "obj-quads", "ascii", "binary_little_endian", "binary_big_endian", "off",
                                 "off-quads", "mesh", "mesh-quads"])
def test_read_mesh_round_trip(tmp_path, fmt):
    v, f = box((-1.5, 0.25, 2.0), (3.125, 1e-3, 7.5))
    writers = {"obj": write_obj, "off": write_off, "mesh": write_medit}
    if fmt.split("-")[0] in writers:
        path = tmp_path / f"box.{fmt.split('-')[0]}"
        writers[fmt.split("-")[0]](path, v, f, quads=fmt.endswith("-quads"))
    else:
        path = tmp_path / "box.ply"
        write_ply(path, v, f, fmt)
    rv, rf = volrig.read_mesh(path)
    assert rv.dtype == np.float64 and rv.shape == (8, 3)
    assert rf.dtype == np.int64 and rf.shape == (12, 3)
    np.testing.assert_array_equal(rv, v)
    np.testing.assert_array_equal(rf, f)


def test_read_errors_name_the_file_and_line(tmp_path):
    p = tmp_path / "bad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n# faces\nf 1 2 9000\n")
    with pytest.raises(volrig.FileFormatError, match=r"bad\.obj: line 5: face index 9000 out of range \(3 vertices\)"):
        volrig.read_mesh(p)
    p.write_text("v 0 0 0\nv 1 nan 0\n")
    with pytest.raises(ValueError, match=r"line 2: vertex y 'nan' is not finite"):  # FileFormatError is a ValueError
        volrig.read_mesh(p)
    q = tmp_path / "huge.ply"
    q.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
                  b"property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                  b"end_header\n" + bytes(1000))
    start = time.perf_counter()
    with pytest.raises(volrig.FileFormatError, match="header declares 1,000,000,000,000 vertex elements"):
        volrig.read_mesh(q)
    assert time.perf_counter() - start < 1.0
    with pytest.raises(FileNotFoundError):
        volrig.read_mesh(tmp_path / "missing.obj")
    with pytest.raises(volrig.FileFormatError,
                       match=r"unknown mesh format \(known endings: .obj .ply .off .stl .mesh\)"):
        volrig.read_mesh(tmp_path / "mesh.3ds")
    with pytest.raises(volrig.FileFormatError, match=r"binary Medit meshes \(.meshb\) are not supported"):
        volrig.read_mesh(tmp_path / "mesh.meshb")
    assert volrig.mesh.MESH_EXTENSIONS == (".obj", ".ply", ".off", ".stl", ".mesh")


@pytest.mark.parametrize("name, text, message", [
    ("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
     r"bad\.off: line 6: face index 3 out of range \(3 vertices"),
    ("bad.off", "OFF\n3000000000 1 0\n0 0 0\n", r"line 2: 3,000,000,000 vertices declared \(at least 6 bytes each\)"),
    ("bad.stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\n",
     r"bad\.stl: line 4: vertex z 'nan' is not finite"),
    ("bad.stl", b"solid but binary".ljust(80, b"\0") + struct.pack("<I", 2) + bytes(60),
     r"84 \+ 50 x 2 = 184 bytes, but the file holds 144"),
    ("bad.mesh", "MeshVersionFormatted 1\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n0 1 0 0\nTriangles 1\n1 2 4 0\n",
     r"bad\.mesh: line 8: Triangles 1: vertex index 4 out of range \(3 vertices, numbered from 1\)"),
    ("bad.mesh", "MeshVersionFormatted 1\nDimension 2\n", r"line 2: Dimension 2: only 3-D meshes are read"),
])
def test_new_formats_name_the_file_line_and_problem(tmp_path, name, text, message):
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(volrig.FileFormatError, match=message):
        volrig.read_mesh(p)


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_stl_round_trip_welds_a_closed_surface(tmp_path, binary):
    v, f = icosphere(3, 2.5, (1.0, -3.0, 0.5))
    v = v.astype(np.float32).astype(np.float64)  # exact in binary STL's float32 too
    p = tmp_path / "ball.stl"
    write_stl(p, v, f, binary, header=b"solid ball (binary all the same)")
    rv, rf = volrig.read_mesh(p)
    assert rv.shape == v.shape and rf.shape == f.shape  # every corner welded onto its one vertex
    np.testing.assert_array_equal(rv[rf], v[f])  # the same triangles, corner for corner
    assert len(boundary_edges(rf)) == 0
    np.testing.assert_array_equal(volrig.voxelize(rv, rf, 0.2).array, volrig.voxelize(v, f, 0.2).array)


def test_read_tgf(tmp_path):
    p = tmp_path / "s.tgf"
    p.write_text("1 0 0 0 5 5\n2 0 1 0\n3 0 2 0.5\n#\n1 2 1 0\n2 3\n#\n")
    joints, edges = volrig.read_tgf(p)
    np.testing.assert_array_equal(joints, [[0, 0, 0], [0, 1, 0], [0, 2, 0.5]])
    assert edges.dtype == np.int64
    np.testing.assert_array_equal(edges, [[0, 1], [1, 2]])
    p.write_text("1 0 0 0\n2 0 1 0\n#\n1 3\n")
    with pytest.raises(volrig.FileFormatError, match=r"s\.tgf: line 4: edge joint 3 out of range \(2 joints"):
        volrig.read_tgf(p)


# ---- voxelizing ------------------------------------------------------------------------------------------------

def test_voxelize_box_geometry():
    v, f = box((10.0, -5.0, 3.0), (11.0, -4.0, 4.0))
    m = volrig.voxelize(v, f, 0.05)
    assert isinstance(m, volrig.Volume)
    assert m.array.dtype == np.bool_  # a mask, as segment() gives
    assert m.dims == (24, 24, 24) and m.spacing == (0.05, 0.05, 0.05)
    assert m.origin == pytest.approx((10 - 0.075, -5 - 0.075, 3 - 0.075))
    z, y, x = np.indices(m.shape)
    centres = m.world(np.stack([z, y, x], -1))
    inside = ((centres > [10, -5, 3]) & (centres < [11, -4, 4])).all(-1)
    np.testing.assert_array_equal(m.array, inside)
    assert m.array.sum() == 8000
    assert volrig.voxelize(v, f, 0.05, padding=0).dims == (20, 20, 20)
    # any integer / float dtypes and array-likes are accepted
    m2 = volrig.voxelize(v.astype(np.float32).tolist(), f.astype(np.uint16), 0.05)
    np.testing.assert_array_equal(m2.array, m.array)


def test_voxelize_sphere_volume_and_the_skeleton_pipeline():
    v, f = icosphere(3, radius=0.8)
    h = 0.04
    m = volrig.voxelize(v, f, h)
    assert m.array.sum() == pytest.approx(mesh_volume(v, f) / h ** 3, rel=0.01)
    # the mask feeds the skeleton directly
    sk = volrig.skeletonize(m)
    assert sk.object_count == m.array.sum()
    assert sk.dt.max() == pytest.approx(0.8, abs=1.5 * h)


def test_mesh_skeleton_moves_its_lattice_by_a_lattice_phase():
    """pipeline.mesh_skeleton's lattice_phase: the voxel lattice moved by fractions of a voxel from its place (for
    measuring how a rig depends on where the samples fall; benchmarks/rig_characters.py --phase)."""
    from volrig import pipeline as P
    v, f = icosphere(3, radius=0.8)
    base, h, _, _ = P.mesh_skeleton(v, f, 0.05, min_radius_voxels=0)
    moved, _, _, _ = P.mesh_skeleton(v, f, 0.05, min_radius_voxels=0, lattice_phase=(0.5, 0.0, 0.25))
    shift = (np.asarray(moved.origin) - np.asarray(base.origin)) / h
    assert shift - np.floor(shift) == pytest.approx([0.5, 0.0, 0.25], abs=1e-9)
    assert moved.array.sum() == pytest.approx(base.array.sum(), rel=0.02)  # the same sphere, sampled elsewhere
    same, _, _, _ = P.mesh_skeleton(v, f, 0.05, min_radius_voxels=0, lattice_phase=(0, 0, 0))
    k = np.round((np.asarray(same.origin) - np.asarray(base.origin)) / h).astype(int)  # phase 0: the same lattice
    assert np.allclose(np.asarray(same.origin), np.asarray(base.origin) + k * h)
    assert same.array.sum() == base.array.sum()


def test_voxelize_closes_small_holes():
    v, f = icosphere(3)  # edges ~0.15: 5 voxels at 0.03
    rng = np.random.default_rng(5)
    used, drop = set(), []
    for i in rng.permutation(len(f)):
        if not used & set(f[i].tolist()):
            used |= set(f[i].tolist())
            drop.append(i)
        if len(drop) == 6:
            break
    holed = np.delete(f, drop, axis=0)
    closed = volrig.voxelize(v, f, 0.03).array
    filled = volrig.voxelize(v, holed, 0.03).array
    assert (closed & filled).sum() >= 0.98 * closed.sum()
    assert (filled & ~closed).sum() <= 0.01 * closed.sum()
    # OpenVDB's own inside/outside (closing_radius=0) loses the interior through these holes
    try:
        leaky = volrig.voxelize(v, holed, 0.03, closing_radius=0).array
        assert (leaky & closed).sum() < 0.5 * closed.sum()
    except ValueError as e:
        assert "encloses no voxel centre" in str(e)


def test_voxelize_progress_and_cancel():
    v, f = icosphere(2)
    seen = []
    volrig.voxelize(v, f, 0.05, progress=lambda x: seen.append(x) or True)
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen == sorted(seen)
    with pytest.raises(volrig.Cancelled):
        volrig.voxelize(v, f, 0.05, progress=lambda x: x < 0.5)


@pytest.mark.parametrize("kwargs, message", [
    (dict(voxel_size=0), "voxel_size must be positive"),
    (dict(voxel_size=-1), "voxel_size must be positive"),
    (dict(voxel_size=float("nan")), "voxel_size must be finite"),
    (dict(voxel_size="0.1"), "voxel_size must be a number"),
    (dict(voxel_size=True), "voxel_size must be a number"),
    (dict(voxel_size=0.1, padding=-1), "padding must be between 0 and 1000"),
    (dict(voxel_size=0.1, padding=float("inf")), "padding must be finite"),
    (dict(voxel_size=0.1, closing_radius=0.2), "closing_radius must be 0 or between 0.5 and 4"),
    (dict(voxel_size=1e-4), "exceeds the limit"),
    (dict(voxel_size=1e-12), "limit is 2\\^28"),
])
def test_voxelize_bad_arguments(kwargs, message):
    v, f = box()
    with pytest.raises(ValueError, match=message):
        volrig.voxelize(v, f, **kwargs)


def test_voxelize_bad_meshes():
    v, f = box()
    with pytest.raises(ValueError, match=r"vertices must have shape \(V, 3\)"):
        volrig.voxelize(v[:, :2], f, 0.1)
    with pytest.raises(ValueError, match=r"faces must have shape \(F, 3\)"):
        volrig.voxelize(v, np.zeros((2, 4), int), 0.1)
    with pytest.raises(ValueError, match="faces must be integer"):
        volrig.voxelize(v, f.astype(float), 0.1)
    with pytest.raises(ValueError, match="vertices must be real numbers"):
        volrig.voxelize(v.astype(complex), f, 0.1)
    with pytest.raises(ValueError, match="faces is empty"):
        volrig.voxelize(v, f[:0], 0.1)
    with pytest.raises(ValueError, match="vertices is empty"):
        volrig.voxelize(v[:0], f, 0.1)
    bad = v.copy()
    bad[5, 1] = np.inf
    with pytest.raises(ValueError, match=r"vertices must be finite: vertex 5"):
        volrig.voxelize(bad, f, 0.1)
    with pytest.raises(ValueError, match="faces index vertex 8, out of range for 8 vertices"):
        volrig.voxelize(v, np.where(f == 7, 8, f), 0.1)
    with pytest.raises(ValueError, match="faces index vertex -1"):
        volrig.voxelize(v, np.where(f == 7, -1, f), 0.1)
    with pytest.raises(ValueError, match="encloses no voxel centre"):  # an open surface
        volrig.voxelize(v, f[:2], 0.1)


# ---- the arm (libigl sample data) ------------------------------------------------------------------------------

def test_arm_voxelized_at_0_01():
    v, f = volrig.read_mesh(shared("meshes/arm.obj"))
    assert v.shape == (8311, 3) and f.shape == (16618, 3)
    joints, edges = volrig.read_tgf(shared("meshes/arm.tgf"))
    assert joints.shape == (5, 3)
    np.testing.assert_array_equal(edges, [[0, 1], [1, 2], [2, 3], [3, 4]])
    start = time.perf_counter()
    m = volrig.voxelize(v, f, 0.01)
    seconds = time.perf_counter() - start
    count = int(m.array.sum())
    print(f"\narm.obj at 0.01: grid {m.dims[0]} x {m.dims[1]} x {m.dims[2]}, {count} object voxels, {seconds:.2f} s")
    assert m.dims == (187, 77, 47)
    assert count == pytest.approx(mesh_volume(v, f) / 0.01 ** 3, rel=0.01)
    # the skeleton's joints lie in the arm: each within 3 voxels of an object voxel
    obj = m.world(np.argwhere(m.array))
    for j in joints:
        assert np.min(np.linalg.norm(obj - j, axis=1)) <= 0.03


# ---- the OFF and Medit meshes of ../shared/data (libigl's tutorial data) ------------------------------------------

# name: vertices, triangles, boundary edges, voxel size (~1/100 of the longest side)
REAL_MESHES = {
    "decimated-knight.off": (502, 1000, 0, 0.009),
    "cow.off": (2762, 5520, 0, 0.0105),
    "lion.off": (8356, 16674, 36, 0.0097),
    "hand.mesh": (7234, 9556, 0, 0.0157),
}


def cap_holes(v, f):
    """Closes each boundary loop with a fan from its centroid (enough for lion.off's one open back)."""
    edges = boundary_edges(f)
    if len(edges) == 0:
        return v, f
    nxt = {}
    for a, b, c in f.tolist():  # boundary edges in the direction their triangle uses them
        for x, y in ((a, b), (b, c), (c, a)):
            if (min(x, y), max(x, y)) in {tuple(e) for e in edges.tolist()}:
                nxt[x] = y
    v, caps = list(v), []
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        while nxt[loop[-1]] != start:
            loop.append(nxt.pop(loop[-1]))
        nxt.pop(loop[-1])
        v.append(np.mean([v[i] for i in loop], axis=0))
        caps += [(len(v) - 1, b, a) for a, b in zip(loop, loop[1:] + loop[:1])]
    return np.array(v), np.concatenate([f, np.array(caps, np.int64)])


@pytest.mark.parametrize("name", sorted(REAL_MESHES))
def test_real_meshes_read_and_voxelize_into_one_solid(name):
    nv, nf, open_edges, h = REAL_MESHES[name]
    v, f = volrig.read_mesh(shared(f"meshes/{name}"))
    lo, hi = v.min(axis=0), v.max(axis=0)
    print(f"\n{name}: {len(v)} vertices, {len(f)} triangles, {len(boundary_edges(f))} boundary edges, "
          f"box {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()} (size {np.round(hi - lo, 3).tolist()})")
    assert v.shape == (nv, 3) and f.shape == (nf, 3)
    assert len(boundary_edges(f)) == open_edges
    if open_edges:  # lion.off is a lion's head with an open back (one loop): voxelize cannot fill it as it is
        assert len(label_components(volrig.voxelize(v, f, h))[1]) > 1
        v, f = cap_holes(v, f)
        assert len(boundary_edges(f)) == 0
    m = volrig.voxelize(v, f, h)
    sizes = label_components(m)[1]
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    volume = abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6
    print(f"  at voxel {h}: grid {m.dims}, {int(sizes.sum())} voxels in {len(sizes)} component(s); "
          f"the surface encloses {volume / h ** 3:.0f} voxels' worth")
    assert len(sizes) == 1
    assert sizes[0] == pytest.approx(volume / h ** 3, rel=0.03)


@pytest.mark.parametrize("name, low, high", [("decimated-knight.off", 2, 1), ("cow.off", 4, 1), ("hand.mesh", 1, 3)])
def test_real_meshes_are_y_up(name, low, high):
    """+Y is up in these files: the lowest tenth (in y) of the knight is its two feet, of the cow its four hooves;
    the hand points its fingers to +Y (several separate fingertips in the top fifth, one palm at the bottom)."""
    nv, nf, open_edges, h = REAL_MESHES[name]
    m = volrig.voxelize(*volrig.read_mesh(shared(f"meshes/{name}")), h)
    ny = m.array.shape[1]
    k = ny // 10 if low > 1 else ny // 5
    assert len(label_components(m.array[:, :k])[1]) == low
    assert len(label_components(m.array[:, ny - k:])[1]) >= high


def test_rig_command_reads_an_off_mesh(tmp_path):
    out = tmp_path / "knight.vrig"
    env = dict(os.environ, PYTHONPATH=str(REPO / "python"))
    r = subprocess.run([sys.executable, "-m", "volrig", "rig", str(shared("meshes/decimated-knight.off")),
                        "--voxel-size", "0.008", "--count", "4000", "-o", str(out)], capture_output=True, text=True,
                       env=env)
    assert r.returncode == 0, r.stderr
    assert "humanoid, fit " in r.stdout
    saved = volrig.load_rig(out)
    assert len(saved.points) == 4000 and saved.rig.kind == "humanoid"
    assert {"head", "upper_arm.L", "forearm.R", "thigh.L", "shin.R"} <= set(saved.rig.names)  # (+ armour spikes)

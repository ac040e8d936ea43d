"""The command line: python -m volrig info / skeletonize / demo."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import volrig

REPO = Path(__file__).resolve().parents[2]


def run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(REPO / "python"))
    return subprocess.run([sys.executable, "-m", "volrig", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd)


@pytest.fixture
def cube_file(tmp_path):
    a = np.zeros((20, 18, 16), np.uint8)
    a[3:17, 3:15, 3:13] = 200
    p = tmp_path / "cube.nrrd"
    volrig.Volume(a, spacing=(0.5, 0.5, 1.0), origin=(1, 2, 3)).save(p)
    return p


def test_info(cube_file):
    r = run("info", cube_file, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["dims_xyz"] == [16, 18, 20] and info["spacing"] == [0.5, 0.5, 1.0]
    assert info["nonzero"] == 14 * 12 * 10 and info["values"] == {"0": 20 * 18 * 16 - 1680, "200": 1680}


def test_skeletonize_writes_points(cube_file, tmp_path):
    out = tmp_path / "pts.npz"
    r = run("skeletonize", cube_file, "--lo", 100, "--thinness", 0.3, "-o", out)
    assert r.returncode == 0, r.stderr
    d = np.load(out)
    mask = volrig.segment(volrig.load(cube_file), lo=100)
    ref = volrig.skeletonize(mask).at(0.3)
    np.testing.assert_array_equal(d["ijk"], ref.ijk)
    np.testing.assert_allclose(d["centers"], ref.centers)
    assert str(d["metric"]) == "euclidean" and float(d["thinness"]) == 0.3
    assert [f for f in os.listdir(tmp_path) if ".tmp" in f] == []
    r = run("skeletonize", cube_file, "--count", 5, "--metric", "chamfer345", "-o", out)
    assert r.returncode == 0 and len(np.load(out)["ijk"]) == 5
    # neither: half a voxel, as the add-on's slider (Euclidean scores are in world units: 0.5 x the spacing 0.5)
    r = run("skeletonize", cube_file, "--lo", 100, "-o", out)
    assert r.returncode == 0, r.stderr
    d = np.load(out)
    assert float(d["thinness"]) == 0.25 and "thinness 0.25" in r.stdout
    np.testing.assert_array_equal(d["ijk"], volrig.skeletonize(mask).at(0.25).ijk)
    assert not np.array_equal(d["ijk"], ref.ijk)
    r = run("skeletonize", cube_file, "--lo", 100, "--count", 5, "-t", 0.3, "-o", out)
    assert r.returncode == 2 and "not allowed with" in r.stderr


def test_clear_errors(tmp_path, cube_file):
    r = run("info", tmp_path / "missing.nrrd")
    assert r.returncode == 2 and "missing.nrrd" in r.stderr and "Traceback" not in r.stderr
    bad = tmp_path / "bad.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100 100 100\nencoding: raw\n\nshort")
    r = run("info", bad)
    assert r.returncode == 2 and "bad.nrrd" in r.stderr and "Traceback" not in r.stderr
    r = run("skeletonize", cube_file, "--lo", 250, "-t", 0.3, "-o", tmp_path / "x.npz")
    assert r.returncode == 2 and "empty" in r.stderr


def test_demo(tmp_path):
    r = run("demo", "--scale", 0.25, "-o", tmp_path / "demo")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "demo" / "report.json").read_text())
    assert report["skeleton"]["points"] > 0 and report["reconstruction"]["percent_lost"] < 1.0
    png = (tmp_path / "demo" / "skeleton.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20000


def test_rig_writes_a_rig_file(tmp_path):
    ph = volrig.phantom.humanoid(0.25)
    src = tmp_path / "phantom.nrrd"
    ph.volume.save(src)
    out = tmp_path / "phantom.vrig"
    r = run("rig", src, "--lo", 1, "--count", 4000, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "humanoid, fit " in r.stdout and ": 21 bones" in r.stdout
    loaded = volrig.load_rig(out)
    assert loaded.rig.kind == "humanoid" and len(loaded.points) == 4000 and 0 < loaded.rig.fit <= 1
    assert loaded.binding.mode == "smooth" and loaded.source == str(src)
    r = run("rig", src, "--lo", 1, "--count", 4000, "--no-roles", "--bones", 12, "-o", out)
    assert r.returncode == 0, r.stderr
    loaded = volrig.load_rig(out)
    assert loaded.rig.kind == "chains" and len(loaded.rig) <= 12
    r = run("rig", src, "--lo", 1, "--count", 4000, "--kind", "quadruped", "-o", out)
    assert r.returncode == 0 and volrig.load_rig(out).rig.kind == "quadruped"  # forced, whatever its fit
    r = run("rig", src, "--lo", 1, "--count", 4000, "--up", "0,0,1", "-o", out)
    assert r.returncode == 0, r.stderr
    loaded = volrig.load_rig(out)
    assert loaded.rig.kind == "humanoid" and loaded.rig.up_confidence == 1.0 and list(loaded.rig.up) == [0, 0, 1]
    r = run("rig", src, "--lo", 1, "--count", 4000, "--rig-kept-points", "-o", out)
    assert r.returncode == 0, r.stderr
    loaded = volrig.load_rig(out)  # joints on the kept points themselves (end joints aside)
    on = loaded.rig.joint_points >= 0
    assert on.any() and np.allclose(loaded.rig.joints[on], loaded.points.centers[loaded.rig.joint_points[on]])
    # rigid tissue: the bone (220) bound as volrig.bind(..., rigid=) binds it; it is the bone the limb joints are
    # placed on too (issue 54), parted into its segments, each moving whole; none of a label: a clear error
    r = run("rig", src, "--lo", 1, "--count", 4000, "--rigid-labels", 220, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "from the bones: " in r.stdout
    loaded = volrig.load_rig(out)
    mask = volrig.segment(ph.volume, lo=1)
    expected = volrig.bind(loaded.points, loaded.rig, mask, mode="smooth", rigid=loaded.binding.rigid)
    assert np.array_equal(loaded.binding.weights.tocsr().indptr, expected.weights.tocsr().indptr)
    on_bone = loaded.binding.rigid[tuple(np.asarray(loaded.points.ijk).T)]
    assert on_bone.any() and (np.diff(loaded.binding.weights.tocsr().indptr)[on_bone] == 1).all()
    bone = ph.volume.array == 220  # bake-mocap's Deformer draws its layer: the bone, segments parted
    assert loaded.binding.rigid_whole and not (loaded.binding.rigid & ~bone).any()
    assert loaded.binding.rigid.sum() >= 0.8 * bone.sum()
    r = run("rig", src, "--lo", 1, "--count", 4000, "--rigid-range", 200, 255, "-o", out)
    assert r.returncode == 0, r.stderr
    rigid = volrig.load_rig(out).binding.rigid
    assert not (rigid & ~(ph.volume.array >= 200)).any() and rigid.sum() >= 0.8 * (ph.volume.array >= 200).sum()
    r = run("rig", src, "--lo", 1, "--count", 4000, "--bone-labels", 220, "-o", out)
    assert r.returncode == 0 and "from the bones: " in r.stdout, r.stderr
    assert volrig.load_rig(out).binding.rigid is None  # bone places joints; only rigid tissue binds rigidly
    r = run("rig", src, "--lo", 1, "--count", 4000, "--bone-range", 5000, 6000, "-o", out)
    assert r.returncode == 2 and "bone: no voxel has the given values" in r.stderr and "Traceback" not in r.stderr
    r = run("rig", src, "--lo", 1, "--count", 4000, "--rigid-labels", 7, "-o", out)
    assert r.returncode == 2 and "no voxel has the given labels" in r.stderr and "Traceback" not in r.stderr
    r = run("rig", src, "--lo", 1, "--count", 4000, "--up", "sideways", "-o", out)
    assert r.returncode == 2 and "sideways" in r.stderr
    bad = run("rig", src, "--lo", 1, "--count", 4000, "-o", tmp_path / "x.npz")
    assert bad.returncode == 2 and ".vrig" in bad.stderr
    mesh = run("rig", tmp_path / "arm.obj", "--count", 100, "-o", out)
    assert mesh.returncode == 2 and "arm.obj" in mesh.stderr and "Traceback" not in mesh.stderr


def test_rig_of_a_mesh_has_defaults(tmp_path):
    """A mesh needs neither --voxel-size (the longest side / 160, as rig_mesh and the add-on) nor a point choice
    (half a voxel's thinness)."""
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 0.5) for z in (0, 4)], dtype=float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    obj = tmp_path / "bar.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in corners)
                   + "".join(f"f {a + 1} {b + 1} {c + 1} {d + 1}\n" for a, b, c, d in quads))
    out = tmp_path / "bar.vrig"
    r = run("rig", obj, "-o", out)
    assert r.returncode == 0, r.stderr
    loaded = volrig.load_rig(out)
    size = 4 / 160
    assert loaded.points.spacing == pytest.approx((size,) * 3)
    mask = volrig.voxelize(*volrig.read_mesh(str(obj)), size)
    np.testing.assert_array_equal(loaded.points.ijk, volrig.skeletonize(mask).at(0.5 * size).ijk)
    assert len(loaded.rig) > 0


def test_bake_finds_the_addon_as_a_package(tmp_path, monkeypatch):
    """`volrig bake` hands Blender the folder holding volrig_addon: given (a folder, the package, the zip), else
    wherever Python's import system finds it; never a path relative to the volrig package."""
    import sys
    import zipfile
    from volrig.cli import addon_folder
    addon = REPO / "addon"
    assert addon_folder(str(addon)) == str(addon)
    assert addon_folder(str(addon / "volrig_addon")) == str(addon)
    zip_path = tmp_path / "volrig_addon.zip"
    with zipfile.ZipFile(zip_path, "w") as z:
        for f in sorted((addon / "volrig_addon").glob("*.py")):
            z.write(f, f"volrig_addon/{f.name}")
    unpacked = tmp_path / "unpacked"
    assert addon_folder(str(zip_path), str(unpacked)) == str(unpacked)
    assert (unpacked / "volrig_addon" / "bake.py").read_bytes() == (addon / "volrig_addon" / "bake.py").read_bytes()
    with pytest.raises(FileNotFoundError, match="neither the add-on zip nor a folder holding volrig_addon"):
        addon_folder(str(tmp_path))
    monkeypatch.setattr(sys, "path", [p for p in sys.path if os.path.abspath(p) != str(addon)] + [str(addon)])
    assert addon_folder() == str(addon)  # found as an importable package (PYTHONPATH=python:addon)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if os.path.abspath(p) != str(addon)])
    assert addon_folder() == ""  # not installed for Python: left to the add-ons installed in Blender


def test_cli_errors_are_volrigs_or_os_errors(tmp_path, cube_file):
    """User mistakes exit 2 with the message; the frame syntax is the add-on's."""
    r = run("skeletonize", cube_file, "--lo", 100, "--hi", 50, "-t", 0.3, "-o", tmp_path / "x.npz")
    assert r.returncode == 2 and "lo (100) is above hi (50)" in r.stderr
    r = run("skeletonize", cube_file, "--dims", 4, 4, 4, "-t", 0.3, "-o", tmp_path / "x.npz")
    assert r.returncode == 2 and "element type" in r.stderr and "Traceback" not in r.stderr
    r = run("bake", tmp_path / "none.blend", "--blender", "/bin/true")
    assert r.returncode == 2 and "none.blend: no such file" in r.stderr

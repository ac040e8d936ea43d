"""The extension's wheels are self-contained (scripts/extension, scripts/wheel_libs.py): every library the compiled
module needs but glibc, libstdc++ and libgcc_s is inside the wheel's volrig.libs/, renamed, and found there; the
cp313 wheel's come from the Debian 13 root it was built in. The last test unpacks the cp311 wheel into a bare
Debian 12 root (scripts/bare_root: minbase, python3 and python3-numpy only: no OpenVDB, TBB, Boost, GDCM, libtiff,
libpng, scipy) and runs volrig there: phantom -> skeletonize -> autorig -> bind -> deformed frame -> VDB."""
import os
import re
import shutil
import subprocess
import sys
import zipfile

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "scripts"))
import wheel_libs  # noqa: E402

MODULE = os.path.join(REPO, "python", "volrig", "_volrig.cpython-311-x86_64-linux-gnu.so")
TRIXIE = os.environ.get("VOLRIG_TRIXIE_ROOT", os.path.expanduser("~/.cache/volrig/trixie"))
MODULE313 = os.path.join(REPO, "python", "volrig", "_volrig.cpython-313-x86_64-linux-gnu.so")

pytestmark = pytest.mark.skipif(sys.version_info[:2] != (3, 11) or not os.path.exists(MODULE),
                                reason="the cp311 wheel is made from Debian 12's Python 3.11 module (scripts/setup)")


def make_wheel(tmp, tag):
    out = subprocess.run([sys.executable, os.path.join(REPO, "scripts", "extension"), "--wheels-only", str(tmp),
                          "--only", tag, "--require", tag], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    (whl,) = [p for p in os.listdir(tmp) if p.endswith(".whl") and f"-{tag}-" in p]
    unpacked = tmp / "unpacked"
    with zipfile.ZipFile(tmp / whl) as z:
        z.extractall(unpacked)
        for info in z.infolist():  # zipfile drops the executable bits
            os.chmod(unpacked / info.filename, (info.external_attr >> 16) or 0o644)
    return tmp / whl, unpacked


@pytest.fixture(scope="module")
def wheel311(tmp_path_factory):
    return make_wheel(tmp_path_factory.mktemp("wheel311"), "cp311")


def bundled_names(libs):
    """{original SONAME: bundled file name} from the hashed names (libfoo-1a2b3c4d.so.1 <- libfoo.so.1)."""
    names = {}
    for f in os.listdir(libs):
        m = re.fullmatch(r"(.+)-([0-9a-f]{8})(\.so.*)", f)
        assert m, f"{f}: not renamed with a hash"
        names[m.group(1) + m.group(3)] = f
    return names


def test_wheel_bundles_every_library_and_finds_them_there(wheel311):
    whl, root = wheel311
    size = os.path.getsize(whl)
    libs = root / "volrig.libs"
    module = root / "volrig" / os.path.basename(MODULE)
    print(f"cp311 wheel: {whl.name}, {size / 1e6:.1f} MB, {len(os.listdir(libs))} libraries, "
          f"{sum(p.stat().st_size for p in libs.iterdir()) / 1e6:.0f} MB unpacked")
    assert re.search(r"-cp311-cp311-manylinux_2_\d+_x86_64\.whl$", whl.name)
    assert size < 40e6, f"the wheel grew to {size / 1e6:.1f} MB"
    names = bundled_names(libs)
    assert {"libopenvdb.so.10.0", "libtbb.so.12", "libz.so.1", "libpng16.so.16", "libtiff.so.6",
            "libgdcmMSFF.so.3.0", "libboost_iostreams.so.1.74.0"} <= set(names), sorted(names)
    assert not set(names) & wheel_libs.SYSTEM
    # the loader, with no LD_LIBRARY_PATH, resolves every dependency: the bundled ones inside volrig.libs
    out = subprocess.run(["ldd", str(module)], env={"PATH": os.environ.get("PATH", "/usr/bin:/bin")},
                         capture_output=True, text=True, check=True).stdout
    assert "not found" not in out, out
    resolved = dict(re.findall(r"^\s*(\S+) => (\S+)", out, re.M))
    for name, path in resolved.items():
        if name in wheel_libs.SYSTEM:
            assert "volrig.libs" not in path, (name, path)
        else:
            assert os.path.dirname(os.path.realpath(path)) == str(libs.resolve()), (name, path)
            assert name in names.values(), (name, path)
    assert set(names.values()) <= set(resolved), "bundled libraries nothing loads: " + \
        str(sorted(set(names.values()) - set(resolved)))
    # every file's names point inside the wheel: SONAME = file name, DT_NEEDED bundled or system, RPATH $ORIGIN
    assert wheel_libs.dynamic(str(module))[2] == ["$ORIGIN/../volrig.libs"]
    for f in os.listdir(libs):
        soname, needed, rpath = wheel_libs.dynamic(str(libs / f))
        assert soname == f and rpath == ["$ORIGIN"], (f, soname, rpath)
        assert set(needed) <= wheel_libs.SYSTEM | set(names.values()), (f, needed)
    # Debian 12's own files (the hash is of the original), stripped
    host = wheel_libs.closure(MODULE, "/")
    for orig, f in names.items():
        assert f == wheel_libs.hashed_name(orig, open(host[orig], "rb").read()), f
    sections = subprocess.run(["readelf", "-S", "-W", str(libs / names["libopenvdb.so.10.0"])],
                              capture_output=True, text=True, check=True).stdout
    assert ".debug_" not in sections and ".symtab" not in sections


@pytest.mark.skipif(not os.path.exists(MODULE313) or not os.path.isdir(os.path.join(TRIXIE, "usr")),
                    reason="no cp313 module or no Debian 13 root (scripts/blender43 makes both)")
def test_cp313_wheel_takes_debian_13_libraries(tmp_path):
    whl, root = make_wheel(tmp_path, "cp313")
    names = bundled_names(root / "volrig.libs")
    assert "libboost_iostreams.so.1.83.0" in names and "libboost_iostreams.so.1.74.0" not in names  # Debian 13's
    trixie = wheel_libs.closure(MODULE313, TRIXIE)
    for orig, f in names.items():
        assert trixie[orig].startswith(TRIXIE), trixie[orig]
        assert f == wheel_libs.hashed_name(orig, open(trixie[orig], "rb").read()), f"{f} is not Debian 13's {orig}"
    if os.geteuid() != 0:
        pytest.skip("running it in the Debian 13 root needs root (chroot)")
    # made (stripped, patched) by this machine's binutils and patchelf: it loads and runs in Debian 13's Python
    # 3.13 (numpy 2), its libraries from volrig.libs, scipy hidden (the root has Debian's)
    out = run_in(TRIXIE, [os.path.join(REPO, "scripts", "trixie_root"), "run"], root,
                 "import sys\nsys.modules['scipy'] = None\n" + PIPELINE, ldd=True)
    assert out.count("/volrig.libs/") >= len(names) and "not found" not in out, out[-3000:]
    check_pipeline(out)


PIPELINE = r"""
import os, sys, tempfile
import numpy as np
import volrig
from volrig import _optional
assert not _optional.have_scipy(), "scipy is importable here"
ph = volrig.phantom.humanoid(scale=0.25)
mask = volrig.segment(ph.volume, lo=1.0)
pts = volrig.skeletonize(mask).top(3000)
tree = volrig.skeleton_tree(pts, mask, alpha=0.9)
rig = volrig.autorig(pts, tree, mask)
binding = volrig.bind(pts, rig, mask, mode="smooth")
assert type(binding.weights).__name__ == "CSR", type(binding.weights)
w = binding.weights.tocsr()
rows = np.repeat(np.arange(len(pts)), np.diff(w.indptr))
assert np.allclose(np.bincount(rows, w.data, len(pts)), 1, atol=1e-5)
binding = binding.reassign([0, 1, 2], rig.names[0])
again = volrig.Binding.from_groups(dict(zip(rig.names, binding.groups())), rig.names, len(binding))
assert np.array_equal(again.bone, binding.bone)
d = tempfile.mkdtemp()
volrig.save_rig(os.path.join(d, "p.vrig"), pts, tree, rig, binding)
r = volrig.load_rig(os.path.join(d, "p.vrig"))
assert np.array_equal(r.binding.weights.indptr, binding.weights.indptr)
deformer = volrig.Deformer(ph.volume, pts, r.binding)
M = volrig.rest_pose(len(rig.bones))
rest = deformer.frame(M).values
moved = M.copy()
moved[:, :3, 3] += [5.0, 0.0, 0.0]
frame = deformer.frame(moved).values
volrig.write_vdb(os.path.join(d, "f.vdb"), {"density": frame})
back = volrig.load(os.path.join(d, "f.vdb"))
print("RESULT", len(rig.bones), rig.kind, len(pts), float(np.asarray(rest.array).sum()),
      float(np.asarray(frame.array).sum()), float(np.asarray(back.array).sum()),
      *np.round(np.subtract(frame.origin, rest.origin), 3))
try:
    volrig.inflate(np.zeros((8, 8, 3), np.uint8))
except volrig.VolrigError as e:
    assert isinstance(e, ImportError) and "needs scipy" in str(e), e
    print("SCIPY", e)
maps = [l.split()[-1] for l in open("/proc/self/maps") if ".so" in l.split()[-1]]
print("LIBS", " ".join(sorted(set(maps))))
"""


def run_in(root, enter, unpacked, script, ldd=False):
    """stdout of ``script`` run by python3 inside ``root`` (entered with ``enter`` + command) with the unpacked
    wheel on PYTHONPATH; after `ldd` of the module (no LD_LIBRARY_PATH) when ``ldd``."""
    inside = f"/tmp/volrig-wheel-{os.getpid()}"
    shutil.rmtree(root + inside, ignore_errors=True)
    shutil.copytree(unpacked, root + inside, symlinks=True)
    open(os.path.join(root + inside, "pipeline.py"), "w").write(script)
    cmd = f"PYTHONPATH={inside} python3 {inside}/pipeline.py"
    if ldd:
        cmd = f"ldd {inside}/volrig/_volrig.*.so && " + cmd
    try:
        run = subprocess.run(enter + ["/bin/sh", "-c", cmd], capture_output=True, text=True, timeout=900)
    finally:
        shutil.rmtree(root + inside, ignore_errors=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return run.stdout.replace(inside, "<wheel>")


def check_pipeline(stdout):
    """The checks of PIPELINE's output: a humanoid rig, a frame moved whole, scipy's absence reported, OpenVDB,
    TBB, Imath, GDCM, libtiff, libpng, Boost and blosc loaded from the wheel's volrig.libs only."""
    result = next(ln for ln in stdout.splitlines() if ln.startswith("RESULT")).split()
    bones, kind, points, rest, frame, back, dx, dy, dz = result[1:]
    assert int(bones) >= 15 and kind == "humanoid" and int(points) == 3000, result
    assert float(rest) > 0 and float(frame) == float(rest) and float(back) == float(frame), result  # moved whole
    assert (float(dx), float(dy), float(dz)) == (5.0, 0.0, 0.0), result
    assert "volrig.drawing" in stdout and "needs scipy" in stdout
    libs = next(ln for ln in stdout.splitlines() if ln.startswith("LIBS")).split()[1:]
    for base in ("libopenvdb", "libtbb", "libImath", "libgdcm", "libtiff", "libpng16", "libboost", "libblosc"):
        loaded = [p for p in libs if os.path.basename(p).startswith(base)]
        assert loaded and all(p.startswith("<wheel>/volrig.libs/") for p in loaded), (base, libs)


@pytest.mark.skipif(os.geteuid() != 0, reason="the bare Debian 12 root needs root (debootstrap, chroot)")
def test_wheel_runs_the_pipeline_in_a_bare_debian_12_root(wheel311):
    _, unpacked = wheel311
    root = subprocess.run([os.path.join(REPO, "scripts", "bare_root")], capture_output=True, text=True,
                          timeout=1200)
    assert root.returncode == 0, root.stderr[-3000:]
    root = root.stdout.strip().splitlines()[-1]
    for lib in ("libopenvdb.so.10.0", "libtbb.so.12", "libboost_iostreams.so.1.74.0", "libgdcmMSFF.so.3.0",
                "libpng16.so.16", "libtiff.so.6"):
        assert not os.path.exists(os.path.join(root, "usr/lib/x86_64-linux-gnu", lib)), f"the root has {lib}"
    check_pipeline(run_in(root, [os.path.join(REPO, "scripts", "bare_root"), "run"], unpacked, PIPELINE))


@pytest.mark.skipif(os.geteuid() != 0, reason="the bare Debian 12 root needs root (debootstrap, chroot)")
def test_pip_install_of_the_wheel_gives_the_volrig_command(wheel311):
    """`pip install volrig-*.whl` in a bare Debian 12 root (no PYTHONPATH, nothing but python3, numpy and pip)
    installs the `volrig` command (console script volrig.cli:main); `volrig --help` and `volrig rig` work."""
    whl, _ = wheel311
    root = subprocess.run([os.path.join(REPO, "scripts", "bare_root")], capture_output=True, text=True,
                          timeout=1200)
    assert root.returncode == 0, root.stderr[-3000:]
    root = root.stdout.strip().splitlines()[-1]
    with zipfile.ZipFile(whl) as z:
        assert z.read(f"volrig-{whl.name.split('-')[1]}.dist-info/entry_points.txt").decode() == \
            "[console_scripts]\nvolrig = volrig.cli:main\n"
        assert "License: GPL-3.0-or-later" in z.read(f"volrig-{whl.name.split('-')[1]}.dist-info/METADATA").decode()
    inside = f"/tmp/volrig-pip-{os.getpid()}"
    os.makedirs(root + inside, exist_ok=True)
    shutil.copy(whl, root + inside)
    pip = "python3 -m pip --disable-pip-version-check -q"
    script = (f"set -e; cd {inside}; {pip} install --no-index --break-system-packages {whl.name}; "
              "command -v volrig; volrig --help | head -3; "
              "python3 -c \"import volrig; volrig.phantom.humanoid(scale=0.25).volume.save('p.nrrd')\"; "
              "volrig rig p.nrrd --lo 1 -o p.vrig; ls -l p.vrig")
    try:
        run = subprocess.run([os.path.join(REPO, "scripts", "bare_root"), "run", "/bin/sh", "-c", script],
                             capture_output=True, text=True, timeout=900)
    finally:
        subprocess.run([os.path.join(REPO, "scripts", "bare_root"), "run", "/bin/sh", "-c",
                        f"{pip} uninstall -y --break-system-packages volrig"], capture_output=True, timeout=300)
        shutil.rmtree(root + inside, ignore_errors=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "/usr/local/bin/volrig" in run.stdout, run.stdout
    assert "usage: volrig" in run.stdout and "humanoid" in run.stdout, run.stdout[-3000:]
    assert os.path.exists(root + inside) is False  # cleaned up

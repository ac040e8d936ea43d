"""The Blender 4.2+ extension (scripts/extension): Blender installs it from the file into a clean user folder
with `blender --command extension install-file`, takes the volrig wheel for its own Python, enables it, and its
operators work on the volrig it carries (not the checkout). Runs in Blender 4.2 and newer (scripts/test runs
these tests in Debian 13's Blender 4.3 too); the legacy zip for 3.x is test_packaging's."""
import os
import subprocess
import sys

import pytest

bpy = pytest.importorskip("bpy", reason="these tests run inside Blender: see tests/blender/run.py")

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

pytestmark = pytest.mark.skipif(bpy.app.version < (4, 2, 0),
                                reason=f"extensions need Blender 4.2+ (this is {bpy.app.version_string}; "
                                       "scripts/test runs these in Blender 4.3)")

CHECK = """
import os, sys, bpy, addon_utils
name = "bl_ext.user_default.volrig"
enabled = name in bpy.context.preferences.addons      # enabled by install-file -e, saved in the user preferences
import volrig
from bl_ext.user_default import volrig as addon
out, nrrd = sys.argv[-2], os.path.join(sys.argv[-2], "phantom.nrrd")
volrig.phantom.humanoid(scale=0.25).volume.save(nrrd)
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "scene.blend"))  # the cache goes beside it
assert bpy.ops.volrig.import_volume(filepath=nrrd, unit="MM") == {"FINISHED"}
vol = bpy.context.active_object
vol.volrig.low = 1.0
assert bpy.ops.volrig.skeletonize() == {"FINISHED"}
vol.volrig.thinness = 0.3
assert bpy.ops.volrig.rig() == {"FINISHED"}
rig = [o for o in bpy.data.objects if o.type == "ARMATURE"]
bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 2
bpy.ops.wm.save_mainfile()
bundled = sorted({l.split()[-1].rsplit("/", 1)[-1] for l in open("/proc/self/maps") if "/volrig.libs/" in l})
print("EXTINFO", enabled, volrig.__file__, addon.__file__, len(rig[0].data.bones) if rig else 0,
      ",".join(bundled), sys.version_info[:2])
print("SCIPY", volrig._optional.have_scipy())
sys.stdout.flush()
os._exit(0)
"""


def blender(*args, env, timeout=600):
    return subprocess.run([bpy.app.binary_path, *args], env=env, capture_output=True, text=True, timeout=timeout)


def test_extension_installs_from_file_enables_and_runs_operators(tmp_path):
    zip_path = str(tmp_path / "volrig.zip")
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    out = subprocess.run(["python3", os.path.join(REPO, "scripts", "extension"), "-o", zip_path, "--require", tag],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    env0 = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    valid = blender("--command", "extension", "validate", zip_path, env=env0, timeout=120)
    assert valid.returncode == 0 and "FATAL" not in valid.stdout + valid.stderr, valid.stdout + valid.stderr
    user = tmp_path / "user"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BLENDER_USER_SCRIPTS",
                                                           "BLENDER_USER_CONFIG", "BLENDER_USER_EXTENSIONS")}
    env["BLENDER_USER_RESOURCES"] = str(user)  # a clean user folder: config, scripts, extensions
    inst = blender("--command", "extension", "install-file", "-r", "user_default", "-e", zip_path, env=env)
    assert inst.returncode == 0, inst.stdout[-3000:] + inst.stderr[-3000:]
    installed = list(user.rglob("blender_manifest.toml"))
    assert installed and str(user) in str(installed[0]), inst.stdout[-2000:]
    wheels_out = list(user.rglob(f"_volrig.cpython-{tag[2:]}*.so"))
    assert wheels_out, "the wheel for this Python was not unpacked: " + inst.stdout[-2000:]
    assert list(user.rglob("volrig.libs/libopenvdb-*.so*")), "the wheel's bundled libraries were not unpacked"
    work = tmp_path / "work"
    work.mkdir()
    run = blender("-b", "--python-exit-code", "1", "--python-expr", CHECK, "--", str(work), "x", env=env)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    line = next(ln for ln in run.stdout.splitlines() if ln.startswith("EXTINFO"))
    _, enabled, volrig_file, addon_file, bones, bundled, _ = line.split(" ", 6)
    assert enabled == "True"
    assert volrig_file.startswith(str(user)) and addon_file.startswith(str(user)), line  # not the checkout
    assert int(bones) >= 5, line
    # the wheel is self-contained: the module loaded its own, renamed OpenVDB and TBB from the wheel's volrig.libs
    # (Blender may have loaded the system's as well: they do not clash)
    assert any(n.startswith("libopenvdb-") for n in bundled.split(",")), line
    assert any(n.startswith("libtbb-") for n in bundled.split(",")), line
    assert "SCIPY True" in run.stdout  # Debian's Blender sees python3-scipy
    # Blender's own builds have numpy but no scipy: the same run with scipy hidden (a sitecustomize that blocks it)
    hide = tmp_path / "noscipy"
    hide.mkdir()
    (hide / "sitecustomize.py").write_text("import sys\nsys.modules['scipy'] = None\n")
    work2 = tmp_path / "work2"
    work2.mkdir()
    run2 = blender("-b", "--python-use-system-env", "--python-exit-code", "1", "--python-expr", CHECK, "--",
                   str(work2), "x", env=dict(env, PYTHONPATH=str(hide)))
    assert run2.returncode == 0, run2.stdout[-4000:] + run2.stderr[-4000:]
    assert "SCIPY False" in run2.stdout, run2.stdout[-2000:]
    line2 = next(ln for ln in run2.stdout.splitlines() if ln.startswith("EXTINFO"))
    assert line2.split(" ")[4] == bones, (line, line2)  # the same rig without scipy
    # `volrig bake` (headless Blender) finds the add-on as the extension when no volrig_addon is importable
    cli_env = dict(env, PYTHONPATH=os.path.join(REPO, "python"))
    bake = subprocess.run(["python3", "-m", "volrig", "bake", str(work / "scene.blend"), "--frames", "1-2",
                           "--blender", bpy.app.binary_path], env=cli_env, capture_output=True, text=True,
                          timeout=600, cwd=str(tmp_path))
    assert bake.returncode == 0, bake.stdout[-3000:] + bake.stderr[-3000:]
    assert "baked 2 frame(s) of scene.blend" in bake.stdout, bake.stdout[-3000:]
    assert len(list(work.rglob("*_000[12].vdb"))) == 2

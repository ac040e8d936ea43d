"""The add-on zip (scripts/addon_zip) installs into a clean Blender and finds the volrig package it carries."""
import os
import subprocess

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

CHECK = """
import os, sys, bpy, addon_utils
bpy.ops.preferences.addon_install(filepath=sys.argv[-1])
addon_utils.enable("volrig_addon", default_set=True)
import volrig, volrig_addon
assert volrig.__file__.startswith(os.path.dirname(volrig_addon.__file__)), volrig.__file__
assert hasattr(bpy.ops.volrig, "import_volume") and hasattr(bpy.types.Object, "volrig")
print("BLINFO", volrig_addon.bl_info["blender"], volrig.__file__)
sys.stdout.flush()
os._exit(0)
"""


def test_addon_zip_installs_and_carries_volrig(tmp_path):
    # scripts/test has run scripts/setup already (and in the Debian 13 root it must not: Debian 12's packages)
    subprocess.run([os.path.join(REPO, "scripts", "addon_zip")], check=True, capture_output=True, timeout=900,
                   env=dict(os.environ, VOLRIG_SKIP_SETUP="1"))
    zip_path = os.path.join(REPO, "dist", "volrig_addon.zip")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "config")
    out = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", CHECK,
                          "--", zip_path], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert "BLINFO (3, 4, 0)" in out.stdout
    assert str(tmp_path / "scripts") in out.stdout  # the installed copy, not the checkout

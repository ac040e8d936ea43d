"""The Flamenco job type (farm/flamenco/volrig_bake_render.js) run for real on one machine: node compiles the job
against the stand-in of Flamenco's API (tests/farm/run_job_type.js), then every task's commands run in an order
its dependencies allow, as a worker would run them (`exec` as is, `blender-render` as `{blender} -b blendfile
args`): the prepare bake saves the .blend, the chunks bake every frame, and the render tasks render them."""
import json
import os
import shutil
import subprocess

import pytest

import bpy
from test_bake import REPO, _cli_env, posed  # noqa: F401 (the fixture)

NODE = shutil.which("node") or shutil.which("nodejs")


@pytest.mark.skipif(NODE is None, reason="node is not installed (scripts/setup installs nodejs on the host; the "
                                         "Debian 13 root has none: this runs in Blender 3.4)")
def test_flamenco_job_bakes_and_renders_a_saved_scene(posed, tmp_path):  # noqa: F811
    from volrig_addon import bake, staging
    vol = posed
    scene = bpy.context.scene
    staging.stage(scene, vol, resolution=(32, 32), samples=1)
    blend = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    assert not os.path.exists(bake.frame_path(vol, 1))
    out = str(tmp_path / "render" / "f_####")
    settings = {"blendfile": blend, "frames": "1-3", "chunk_size": 2, "render_output_path": out,
                "volrig_cmd": "/usr/bin/python3 -m volrig"}
    compiled = subprocess.run([NODE, os.path.join(REPO, "tests", "farm", "run_job_type.js"),
                               os.path.join(REPO, "farm", "flamenco", "volrig_bake_render.js"), json.dumps(settings)],
                              capture_output=True, text=True, timeout=60)
    assert compiled.returncode == 0, compiled.stdout + compiled.stderr
    tasks = json.loads(compiled.stdout)["tasks"]
    assert [t["name"] for t in tasks] == ["prepare", "bake-1-2", "render-1-2", "bake-3", "render-3"]
    done = set()
    env = _cli_env()
    for t in tasks:
        assert set(t["dependencies"]) <= done, t["name"]
        for c in t["commands"]:
            p = c["parameters"]
            if c["name"] == "exec":
                cmd = [p["exe"]] + [bpy.app.binary_path if a == "{blender}" else a for a in p["args"]]
            else:
                assert c["name"] == "blender-render" and p["exe"] == "{blender}"
                cmd = [bpy.app.binary_path, "-b"] + p["argsBefore"] + [p["blendfile"]] + p["args"]
            run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
            assert run.returncode == 0, f"{t['name']}: {cmd}\n" + run.stdout[-3000:] + run.stderr[-3000:]
        done.add(t["name"])
    for f in (1, 2, 3):
        assert os.path.exists(bake.frame_path(vol, f)), f
        png = str(tmp_path / "render" / f"f_{f:04d}.png")
        assert os.path.getsize(png) > 0, png

"""The Flamenco 3 job type farm/flamenco/volrig_bake_render.js, compiled by node (Debian's nodejs, installed by
scripts/setup) against a stand-in of Flamenco's job-compiler API (tests/farm/run_job_type.js): bake tasks per
chunk of frames after one preparing bake, render tasks each depending on its own bake, and bake commands that
volrig's command line accepts."""
import json
import os
import shutil
import subprocess

import pytest

from volrig import cli

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
JOB = os.path.join(REPO, "farm", "flamenco", "volrig_bake_render.js")
RUNNER = os.path.join(REPO, "tests", "farm", "run_job_type.js")
NODE = shutil.which("node") or shutil.which("nodejs")

pytestmark = pytest.mark.skipif(NODE is None, reason="node is not installed (scripts/setup installs nodejs)")


def compile_job(**settings):
    out = subprocess.run([NODE, RUNNER, JOB, json.dumps(settings)], capture_output=True, text=True, timeout=60)
    result = json.loads(out.stdout)
    assert (out.returncode == 3) == ("error" in result), out.stderr
    if out.returncode not in (0, 3):
        raise AssertionError(out.stderr)
    return result


def by_name(result):
    return {t["name"]: t for t in result["tasks"]}


def test_chunks_bake_then_render_with_dependencies():
    r = compile_job(blendfile="/farm/walk.blend", frames="1-25", chunk_size=10, render_output_path="/farm/out/####")
    assert r["job_type"]["label"] == "volrig Bake + Render"
    assert {"blendfile", "frames", "chunk_size", "bake_mode"} <= set(r["job_type"]["settings"])
    names = [t["name"] for t in r["tasks"]]
    assert names == ["prepare", "bake-1-10", "render-1-10", "bake-11-20", "render-11-20", "bake-21-25",
                     "render-21-25"]
    tasks = by_name(r)
    assert tasks["prepare"]["dependencies"] == []
    for span in ("1-10", "11-20", "21-25"):
        bake, render = tasks[f"bake-{span}"], tasks[f"render-{span}"]
        assert bake["dependencies"] == ["prepare"]
        assert render["dependencies"] == [f"bake-{span}"]  # only its own bake: chunks render as they finish
        assert bake["type"] == "misc" and render["type"] == "blender"
        (cmd,) = bake["commands"]
        assert cmd["name"] == "exec" and cmd["parameters"]["exe"] == "python3"
        args = cmd["parameters"]["args"]
        assert args[:4] == ["-m", "volrig", "bake", "/farm/walk.blend"]
        assert args[args.index("--frames") + 1] == span and "--no-save" in args  # bakes run at once: never save
        (rc,) = render["commands"]
        assert rc["name"] == "blender-render" and rc["parameters"]["blendfile"] == "/farm/walk.blend"
        ra = rc["parameters"]["args"]
        assert ra[ra.index("--render-frame") + 1] == span.replace("-", "..")
        assert ra[ra.index("--render-output") + 1] == "/farm/out/####"
    prep = tasks["prepare"]["commands"][0]["parameters"]["args"]
    assert prep[prep.index("--frames") + 1] == "1" and "--no-save" not in prep  # saves: volumes play the sequence


def test_lists_single_frames_mode_force_and_own_command():
    r = compile_job(blendfile="/s/a.blend", frames="7, 1-3,2-4, 10", chunk_size=2, bake_mode="dual_quaternion",
                    force=True, volrig_cmd="/opt/volrig/bin/volrig", addon="/farm/volrig_addon.zip")
    tasks = by_name(r)
    assert [t["name"] for t in r["tasks"] if t["name"].startswith("bake")] == ["bake-1-2", "bake-3-4", "bake-7",
                                                                               "bake-10"]
    assert tasks["render-7"]["commands"][0]["parameters"]["args"] == ["--render-frame", "7"]  # no output override
    cmd = tasks["bake-3-4"]["commands"][0]["parameters"]
    assert cmd["exe"] == "/opt/volrig/bin/volrig"
    assert cmd["args"][:2] == ["bake", "/s/a.blend"]
    assert cmd["args"][cmd["args"].index("--mode") + 1] == "dual_quaternion" and "--force" in cmd["args"]
    assert cmd["args"][cmd["args"].index("--addon") + 1] == "/farm/volrig_addon.zip"
    assert tasks["prepare"]["commands"][0]["parameters"]["args"][3] == "1"


@pytest.mark.parametrize("frames", ["", "5-1", "1-x", "a"])
def test_bad_frames_are_refused_with_a_message(frames):
    r = compile_job(blendfile="/s/a.blend", frames=frames)
    assert "volrig:" in r["error"] and "frame" in r["error"]


def test_bake_commands_parse_in_volrigs_command_line(monkeypatch, tmp_path):
    """Every authored `volrig bake` command line is one volrig's own parser accepts, meaning what the job says."""
    r = compile_job(blendfile=str(tmp_path / "a.blend"), frames="1-5", chunk_size=3, bake_mode="rigid",
                    addon="/farm/addon.zip")
    seen = []
    monkeypatch.setattr(cli, "cmd_bake", lambda args: seen.append(args) or 0)
    for t in r["tasks"]:
        if t["type"] == "misc":
            args = t["commands"][0]["parameters"]["args"]
            assert args[:2] == ["-m", "volrig"]
            assert cli.main(args[2:]) == 0
    assert [(a.frames, a.no_save, a.mode, a.blender, a.addon) for a in seen] == [
        (f, save, "rigid", "{blender}", "/farm/addon.zip") for f, save in (("1", False), ("1-3", True), ("4-5", True))]

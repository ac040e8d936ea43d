"""scripts/showcase_plan.py (the showcase's choices that need no Blender): the labels of a resolution, the walk's
frames (half a stride, a whole cycle), a video's contact sheet frames and the ffmpeg command; with ffmpeg, the
command encodes a PNG sequence that ffprobe reads back."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "scripts"))

import showcase_plan as plan  # noqa: E402


def test_labels_for_each_resolution_and_a_refused_one():
    assert plan.labels_for(1, "/d") == "/d/visible-human/austinman_1mm_labels.nii.gz"
    assert plan.labels_for(4, "/d").endswith("austinman_4mm_labels.nii.gz")
    with pytest.raises(SystemExit, match="4, 2, 1 mm"):
        plan.labels_for(3, "/d")


def walk(period=84.0, phase=20.0, span=300):
    """A walk's ``ahead`` every 2 BVH frames: one foot ahead (+), then the other (-), ``period`` frames a cycle."""
    c = np.arange(0, span, 2)
    amplitude = 300.0 * (1 - ((c - 100) / 600.0) ** 2)  # (longest steps near frame 100: one farthest turn)
    return np.sin(2 * np.pi * (c - phase) / period) * amplitude, list(c)


def test_half_a_stride_goes_from_one_turn_to_the_other_both_included():
    ahead, candidates = walk()
    frames = plan.walk_frames(ahead, candidates, 4)
    assert len(frames) == 4
    assert abs(frames[-1] - frames[0] - 42) <= 2  # half of the 84-frame cycle
    assert frames == sorted(frames)


def test_a_whole_cycle_spans_two_steps_and_leaves_the_last_turn_out():
    ahead, candidates = walk()
    half = plan.walk_frames(ahead, candidates, 4)
    frames = plan.walk_frames(ahead, candidates, 48, cycle=True)
    assert len(frames) == 48 and frames == sorted(frames) and len(set(frames)) == 48
    assert frames[0] == half[0]  # from the half stride's first turn
    step = (frames[-1] - frames[0]) / 47
    assert abs(frames[-1] + step - frames[0] - 84) <= 3  # the next frame would be the first pose again
    # the poses of the cycle: both feet's turns inside it, at its start and halfway
    t = np.interp(frames, candidates, ahead)
    assert abs(t[0]) > 280 and abs(t[24]) > 280 and np.sign(t[0]) == -np.sign(t[24])


def test_a_cycle_near_the_half_strides_start_when_none_follows_it():
    # the farthest turns sit near the span's end: the cycle starts at a turn before them, within the span
    ahead, candidates = walk(span=300)
    ahead = ahead * np.where(np.array(candidates) > 240, 1.2, 1.0)
    half = plan.walk_frames(ahead, candidates, 4)
    assert half[0] > 240
    frames = plan.walk_frames(ahead, candidates, 12, cycle=True)
    assert frames is not None and len(frames) == 12
    assert frames[0] < half[0] and frames[0] + (frames[-1] - frames[0]) * 12 / 11 <= 300


def test_feet_that_do_not_turn_give_none():
    candidates = list(range(0, 300, 2))
    assert plan.walk_frames(np.zeros(len(candidates)), candidates, 4) is None
    assert plan.walk_frames(np.linspace(-1, 1, len(candidates)), candidates, 8, cycle=True) is None
    assert plan.spread(300, 4) == [0, 75, 150, 224]


def test_extremes_alternate():
    ahead, _ = walk()
    kinds = [k for _, k in plan.extremes(ahead)]
    assert len(kinds) >= 6 and all(a == -b for a, b in zip(kinds, kinds[1:]))


def test_sheet_subset():
    assert plan.sheet_subset(48, 12) == list(range(0, 48, 4))
    assert plan.sheet_subset(3, 12) == [0, 1, 2]
    assert len(plan.sheet_subset(50, 12)) == 12


def test_ffmpeg_command():
    c = plan.ffmpeg_command("/f/frame_%03d.png", "/o/v.mp4", fps=24, crf=30, loops=3, ffmpeg="/usr/bin/ffmpeg")
    assert c[0] == "/usr/bin/ffmpeg" and c[-1] == "/o/v.mp4"
    for a, b in (("-c:v", "libx264"), ("-pix_fmt", "yuv420p"), ("-crf", "30"), ("-movflags", "+faststart"),
                 ("-framerate", "24"), ("-stream_loop", "2"), ("-i", "/f/frame_%03d.png")):
        assert c[c.index(a) + 1] == b
    assert c.index("-stream_loop") < c.index("-i")  # (an input option)
    with pytest.raises(SystemExit, match="at least 1"):
        plan.ffmpeg_command("a", "b", loops=0)


def test_a_missing_ffmpeg_says_how_to_install_it(monkeypatch):
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(SystemExit, match="apt-get install -y ffmpeg"):
        plan.ffmpeg_path()


@pytest.mark.skipif(shutil.which("ffmpeg") is None or shutil.which("ffprobe") is None,
                    reason="ffmpeg/ffprobe not installed (apt-get install -y ffmpeg)")
def test_the_command_encodes_frames_that_ffprobe_reads_back(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    for k in range(1, 6):  # odd sizes: the pad keeps yuv420p's even width and height
        img = np.zeros((45, 81, 3))
        img[:, 10 * k:10 * k + 8] = 1.0
        plt.imsave(tmp_path / f"frame_{k:03d}.png", img)
    out = tmp_path / "v.mp4"
    c = plan.ffmpeg_command(str(tmp_path / "frame_%03d.png"), str(out), fps=12, loops=2,
                            ffmpeg=plan.ffmpeg_path())
    r = subprocess.run(c, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 0
    probe = subprocess.run(["ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
                            "stream=codec_name,width,height,pix_fmt,nb_read_frames", "-of", "csv=p=0", str(out)],
                           capture_output=True, text=True)
    assert probe.stdout.strip().split(",") == ["h264", "82", "46", "yuv420p", "10"]


def test_a_video_sheet_crops_to_the_body_in_rows_as_even_as_they_go(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    pick = []
    for k in range(8):  # a wide dark frame, a bright body in columns 90-108 (moving by a column a frame)
        img = np.full((60, 200, 3), 0.15)
        img[10:50, 90 + k:102 + k] = 0.8
        plt.imsave(tmp_path / f"f{k}.png", img)
        pick.append((str(tmp_path / f"f{k}.png"), f"frame {k}"))
    assert plan.body_columns([p for p, _ in pick]) == (90 - 1, 108 + 1)  # (8% of 19 columns each side: 1)
    out = tmp_path / "sheet.png"
    plan.video_sheet(pick, str(out), "title")
    sheet = mpimg.imread(str(out))
    assert sheet.shape[0] > sheet.shape[1] * 0.5  # two rows of four, not a row of six and one of two
    assert plan.sheet_subset(8, 6) == [0, 1, 3, 4, 5, 7]

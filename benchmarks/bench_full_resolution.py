#!/usr/bin/env python3
"""Benchmark: the Visible Human walking at full resolution (issue 56), one run: the rig (``volrig rig``), then plain
frames and tissue frames (``--tissues``: the ``tissue`` grid of class indices) of the same mocap poses, each in a
process of its own: seconds a frame (the bake loop with its file writes, over the frames), peak memory (the child's
ru_maxrss, and how much of it the bake added to the loaded source and rig) and file sizes; the tissue/plain ratios
(target: at most 1.5x).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_full_resolution.py [--mm 2] [--frames 140-141]
Needs ../shared/data/visible-human/austinman_<mm>mm_labels.nii.gz, austinman_tissues.tsv and
../shared/data/bvh/131_01.bvh (skips with a message without them). At 1 mm keep to one or two frames on a shared
24 GB machine.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "python"))
sys.path.insert(0, os.path.join(REPO, "tests", "support"))  # volrig_support: data_root

from volrig_support import data_root  # noqa: E402


def _hwm_bytes() -> int:
    """This process's peak resident set so far (VmHWM)."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))


def child_bake(a) -> None:
    """One bake in this process (plain, or with tissues): prints its figures as JSON on the last line."""
    import volrig
    from volrig import pipeline
    from volrig.mocap import read_bvh
    source = volrig.load(a.labels)
    saved = pipeline.load_rigged(a.rig, binding=True)
    motion = read_bvh(a.clip)
    frames = pipeline.clip_frames(motion.frame_count, a.frames)
    _, matrices = pipeline.mocap_poses(saved.rig, motion, frames)
    loaded = _hwm_bytes()
    tissues = ()
    if a.child == "tissue":  # (as `volrig bake-mocap --tissues` finds them)
        table = volrig.read_tissue_table(a.tissues)
        tissues = volrig.tissue_classes(table, present=volrig.tissues.codes_present(source.array))
    bake = pipeline.FolderBake(source, saved.points, saved.binding, a.out, "vhm", sampling="nearest",
                               tissues=tissues, frames=len(frames))
    t = time.perf_counter()
    seconds = []
    for k, m in enumerate(matrices):
        started = time.perf_counter()
        bake.bake(k + 1, m)
        seconds.append(time.perf_counter() - started)
    bake.finish()
    total = time.perf_counter() - t
    sizes = [os.path.getsize(bake.path(k + 1)) for k in range(len(frames))]
    print(json.dumps({"seconds": total / len(frames), "frames": seconds, "loaded": loaded, "bytes": sizes,
                      "classes": len(tissues)}))


def run_child(args):
    """Runs ``args`` as a child process: (its stdout, wall seconds, peak RSS in bytes: its own ru_maxrss)."""
    t = time.perf_counter()
    p = subprocess.Popen(args, stdout=subprocess.PIPE, text=True,
                         env=dict(os.environ, PYTHONPATH=os.path.join(REPO, "python")))
    out = p.stdout.read()
    _, status, usage = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode:
        raise SystemExit(f"{' '.join(args[:4])}...: exit status {p.returncode}")
    return out, time.perf_counter() - t, usage.ru_maxrss * 1024


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mm", type=int, default=2, choices=(1, 2, 4))
    ap.add_argument("--frames", default="140-141", help="BVH frames (1-based, as volrig bake-mocap --frames)")
    ap.add_argument("--child", choices=("plain", "tissue"), help=argparse.SUPPRESS)
    for name in ("labels", "rig", "clip", "tissues", "out"):
        ap.add_argument("--" + name, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child_bake(a)
        return 0
    data = data_root()
    labels = data / "visible-human" / f"austinman_{a.mm}mm_labels.nii.gz"
    tissues, clip = data / "visible-human" / "austinman_tissues.tsv", data / "bvh" / "131_01.bvh"
    missing = [str(p) for p in (labels, tissues, clip) if not p.exists()]
    if missing:
        print(f"skipped: {', '.join(missing)} absent")
        return 0
    gb = 1024 ** 3
    with tempfile.TemporaryDirectory(prefix="volrig_full_res_") as work:
        rig = os.path.join(work, "vhm.vrig")
        _, rig_s, rig_rss = run_child([sys.executable, "-m", "volrig", "rig", str(labels), "-o", rig, "--up", "+z",
                                       "--bind", "smooth"])
        print(f"Visible Human {a.mm} mm, BVH frames {a.frames} of {clip.name}; rig {rig_s:.1f} s, "
              f"peak {rig_rss / gb:.2f} GB")
        got = {}
        for kind in ("plain", "tissue"):
            out, _, rss = run_child([sys.executable, os.path.abspath(__file__), "--child", kind, "--labels",
                                     str(labels), "--rig", rig, "--clip", str(clip), "--tissues", str(tissues),
                                     "--frames", a.frames, "--out", os.path.join(work, kind)])
            got[kind] = dict(json.loads(out.strip().splitlines()[-1]), rss=rss)
        print("| frame | s / frame | frames (s) | peak RSS | above source + rig | file |")
        print("|---|---|---|---|---|---|")
        for kind, g in got.items():
            what = kind if kind == "plain" else f"tissue ({g['classes']} classes)"
            print(f"| {what} | {g['seconds']:.2f} | {', '.join(f'{s:.2f}' for s in g['frames'])} | "
                  f"{g['rss'] / gb:.2f} GB | {(g['rss'] - g['loaded']) / gb:.2f} GB | "
                  f"{max(g['bytes']) / 1e6:.1f} MB |")
        p, t = got["plain"], got["tissue"]
        print(f"tissue / plain: time {t['seconds'] / p['seconds']:.2f}x, peak RSS {t['rss'] / p['rss']:.2f}x "
              f"(above source + rig {(t['rss'] - t['loaded']) / max(p['rss'] - p['loaded'], 1):.2f}x), "
              f"file {max(t['bytes']) / max(p['bytes']):.2f}x (target: time at most 1.5x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

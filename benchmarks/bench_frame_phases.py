#!/usr/bin/env python3
"""Benchmark: where a bake's frame of the Visible Human goes (issue 56), phase by phase, in one process: loading
the source and the rig, the Deformer's construction, then per frame the deformation (``Deformer.frame``: the first
also builds the spheres' fields), building the VDB grids (``frame.vdb``) and writing the file (a bake writes it on
a thread of its own while the next frame computes). Wall and CPU seconds (all threads) of each phase, each frame.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_frame_phases.py --mm 2 --frames 140-142 --rig /tmp/vhm2.vrig
The rig is made once (``volrig rig --up +z --bind smooth``) when the file is absent, and reused after. To compare
two builds, run it under each one's PYTHONPATH in turn, in the same minutes. Needs
../shared/data/visible-human/austinman_<mm>mm_labels.nii.gz and ../shared/data/bvh/131_01.bvh.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests", "support"))  # volrig_support: data_root

from volrig_support import data_root  # noqa: E402


class Phases:
    """Wall and CPU seconds per named phase, in the order first seen."""

    def __init__(self):
        self.wall, self.cpu = {}, {}

    def timed(self, name, f, *args, **kw):
        w, c = time.perf_counter(), time.process_time()
        out = f(*args, **kw)
        self.wall.setdefault(name, []).append(time.perf_counter() - w)
        self.cpu.setdefault(name, []).append(time.process_time() - c)
        return out

    def report(self):
        for name, walls in self.wall.items():
            print(f"{name:>22}: wall {', '.join(f'{s:.2f}' for s in walls)} s; "
                  f"cpu {', '.join(f'{s:.2f}' for s in self.cpu[name])} s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mm", type=int, default=2, choices=(1, 2, 4))
    ap.add_argument("--frames", default="140-142", help="BVH frames (1-based, as volrig bake-mocap --frames)")
    ap.add_argument("--rig", required=True, help="the saved rig (made here when absent)")
    ap.add_argument("--lattice-tables", action="store_true", help="the bones' lattice tables (lattice_after 0)")
    a = ap.parse_args()
    data = data_root()
    labels, clip = data / "visible-human" / f"austinman_{a.mm}mm_labels.nii.gz", data / "bvh" / "131_01.bvh"
    if not (labels.exists() and clip.exists()):
        print(f"skipped: {labels} or {clip} absent")
        return 0
    if not os.path.exists(a.rig):
        subprocess.run([sys.executable, "-m", "volrig", "rig", str(labels), "-o", a.rig, "--up", "+z", "--bind",
                        "smooth"], check=True)
    import volrig
    from volrig import pipeline
    from volrig.mocap import read_bvh
    p = Phases()
    source = p.timed("load source", volrig.load, str(labels))
    saved = p.timed("load rig", pipeline.load_rigged, a.rig, binding=True)
    motion = read_bvh(str(clip))
    frames = pipeline.clip_frames(motion.frame_count, a.frames)
    _, matrices = p.timed("pose matrices", pipeline.mocap_poses, saved.rig, motion, frames)
    with tempfile.TemporaryDirectory(prefix="volrig_phases_") as out:
        bake = p.timed("Deformer", pipeline.FolderBake, source, saved.points, saved.binding, out, "vhm",
                       sampling="nearest", frames=len(frames), lattice_after=0 if a.lattice_tables else -1)
        for k, m in enumerate(matrices):  # FolderBake.bake's steps, the write not on its own thread
            frame = p.timed("deform", bake.deformer.frame, m, mode=bake.mode, sampling="nearest", bricks=True,
                            half=True)
            grids = p.timed("build VDB grids", frame.vdb, bake.path(k + 1), half=True)
            del frame
            p.timed("write VDB", grids.write, bake.path(k + 1))
            del grids
    print(f"Visible Human {a.mm} mm, BVH frames {a.frames}, {len(saved.points.radii)} spheres, "
          f"{len(saved.binding.bone_names)} bones, lattice tables {'at once' if a.lattice_tables else 'never'}")
    p.report()
    return 0


if __name__ == "__main__":
    sys.exit(main())

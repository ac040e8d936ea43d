#!/usr/bin/env python3
"""Compare two builds of volrig by interleaved runs: this VM's speed drifts by +-20% from minute to minute, so a
before/after comparison is only fair when the two alternate, process by process, in the same minutes.

    # a copy of the package before the change (python/volrig with its compiled module), then after it
    cp -r python/volrig /tmp/before/volrig        (on the old commit, after scripts/setup)
    cp -r python/volrig /tmp/after/volrig         (on the new commit)
    /usr/bin/python3 benchmarks/interleaved.py /tmp/before /tmp/after [--rounds 4] [--scale 1.0] [--modes rigid]

Each round runs one fresh process per build: the phantom at --scale, its rig from a rig file made once (so both
builds deform the very same spheres), a Deformer, the build + first frame, then the best and median of --repeat
rigid frames (and of the --modes given) in the walking stride of bench_deform. Prints every process's figures and,
per build, the median over the rounds of the best times.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))

PROBE = r"""
import json, statistics, sys, time
sys.path.insert(0, sys.argv[1])
import volrig
from volrig import phantom
sys.path.insert(0, sys.argv[2])
from bench_deform import walking_pose
scale, rig_file, repeat, modes = float(sys.argv[3]), sys.argv[4], int(sys.argv[5]), sys.argv[6].split(",")
ph = phantom.humanoid(scale)
r = volrig.load_rig(rig_file)
M = walking_pose(r.rig)
d = volrig.Deformer(ph.volume, r.points, r.binding)
if hasattr(d, "lattice_after"):  # (packages from before 2026-11-29 build the bones' lattice tables at the first frame)
    d.lattice_after = 0
t = time.perf_counter(); f = d.frame(M, mode=modes[0]); out = {"build+first": time.perf_counter() - t}; del f
for mode in modes:
    ts = []
    for _ in range(repeat):
        t = time.perf_counter(); f = d.frame(M, mode=mode); ts.append(time.perf_counter() - t); del f
    out[mode] = [min(ts), statistics.median(ts)]
print(json.dumps(out))
"""


def make_rig(package: str, scale: float, points: int, path: str) -> None:
    code = (f"import sys; sys.path.insert(0, {package!r}); import volrig; from volrig import phantom\n"
            f"ph = phantom.humanoid({scale}); mask = volrig.segment(ph.volume)\n"
            f"pts = volrig.skeletonize(mask).top({points}); tree = volrig.skeleton_tree(pts, mask)\n"
            f"rig = volrig.autorig(pts, tree, mask)\n"
            f"volrig.save_rig({path!r}, pts, tree, rig, volrig.bind(pts, rig, mask, mode='smooth'))\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("builds", nargs=2, help="two folders, each holding a volrig package (folder/volrig)")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--points", type=int, default=40000)
    ap.add_argument("--modes", default="rigid", help="comma-separated deform modes (first: the one built)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rig_file = os.path.join(tmp, "phantom.vrig")
        make_rig(args.builds[0], args.scale, args.points, rig_file)
        results = {b: [] for b in args.builds}
        for k in range(args.rounds):
            for b in args.builds:
                out = subprocess.run([sys.executable, "-c", PROBE, b, HERE, str(args.scale), rig_file,
                                      str(args.repeat), args.modes], capture_output=True, text=True, check=True)
                fig = __import__("json").loads(out.stdout.strip().splitlines()[-1])
                results[b].append(fig)
                print(f"round {k + 1} {b}: " + ", ".join(
                    f"{m} {v[0]:.3f}/{v[1]:.3f} s" if isinstance(v, list) else f"{m} {v:.3f} s" for m, v in fig.items()),
                    flush=True)
    print("median over the rounds (best / median of each process):")
    for b, figs in results.items():
        parts = [f"build+first {statistics.median(f['build+first'] for f in figs):.3f} s"]
        for m in args.modes.split(","):
            parts.append(f"{m} {statistics.median(f[m][0] for f in figs):.4f} / "
                         f"{statistics.median(f[m][1] for f in figs):.4f} s")
        print(f"  {b}: " + ", ".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())

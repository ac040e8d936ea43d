#!/usr/bin/env python3
"""Benchmark: feature tracking by skeletons against full-volume tracking (thesis 9.1, Table 9.1; issue 57).

One run over a time series (default: the shared viscous-fingering run, 30 steps of 64³ from the Nested Tracking
Graphs data): the steps are prepared once (features, their runs along x, one skeletonization each), tracked by the
whole features (thinness 0: their exact overlaps from the runs, Silver and Wang's volume test) and by skeletons at
thinness 0.5, 1 and 2 (<3,4,5> chamfer units, as the thesis). For each: the points looked up (share of the feature
voxels), the agreement with full-volume tracking (matched pairs and events equal, as shares of those either
finds), the overlap test's time and the whole tracking's (events and ids too; best of --repeat) and their
speed-ups over thinness 0 in the same run; the time to take the skeletons at the thinness (select in index order,
sum the weights: the skeletonization's part); and the preparation (labelling, runs and one skeletonization a step)
the skeletons' tracking amortises.

Two feature sets of the run: salt above 20 in the whole box (large fingers joined at the source), and above 30
below the source layer (z < 52: separate fingers, more events). A third, synthetic, stands in for the thicker
features of the thesis' vortices (its Table 9.1, 128³): ten bent tubes of radius 3 to 9 voxels drifting through a
128³ box for 12 steps (Gaussian profiles, above 0.5; some merge). It is no simulation and not the issue's held-out
data: it shows how the speed-up grows as thinness 1 keeps fewer of the voxels.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_track.py [--repeat 20] [FOLDER --lo X]
"""
import argparse
import importlib
import glob
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
trackmod = importlib.import_module("volrig.track")  # the module (volrig.track is the function)

FINGERS = os.path.join(HERE, "..", "..", "shared", "data", "timevarying", "viscous_fingers_run01")


def steps_of(folder, zmax=None):
    files = sorted(glob.glob(os.path.join(folder, "*.vti"))) or trackmod._step_files(folder)
    return [volrig.load(f).array[:zmax] for f in files]


def vortex_tubes(n=128, steps=12, tubes=10, seed=1):
    """The synthetic stand-in: per step a float32 [z, y, x] field, the largest of `tubes` Gaussian tubes along an
    axis, each bent by a sine, drifting and swaying from step to step."""
    rng = np.random.default_rng(seed)
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float32)
    axes = ((z, (y, x)), (y, (z, x)), (x, (z, y)))
    tube = [(rng.uniform(15, n - 15, 2), rng.uniform(3, 9), rng.integers(0, 3), rng.uniform(-1.5, 1.5, 2),
             rng.uniform(0.02, 0.06), rng.uniform(5, 15)) for _ in range(tubes)]
    out = []
    for t in range(steps):
        f = np.zeros((n, n, n), np.float32)
        for centre, r, axis, drift, k, sway in tube:
            along, (u, v) = axes[axis]
            c = centre + drift * t
            du = u - (c[0] + sway * np.sin(k * along + 0.3 * t))
            dv = v - (c[1] + sway * np.cos(k * along))
            np.maximum(f, np.exp(-(du * du + dv * dv) / (2 * r * r)), out=f)
        out.append(f)
    return out


def best_of(full, tp, repeat):
    runs = [full.at(tp) for _ in range(repeat)]
    return (runs[0], min(r.seconds for r in runs), min(r.overlap_seconds for r in runs),
            min(r.points_seconds for r in runs))


def table(name, steps, lo, repeat):
    t = time.perf_counter()
    full = volrig.track(steps, lo=lo, thinness=0)
    prepare = time.perf_counter() - t
    voxels = sum(len(s.voxels) for s in full._steps)
    _, whole0, over0, _ = best_of(full, 0, repeat)
    counts = ", ".join(f"{n} {k}" for k, n in full.event_counts().items() if n)
    print(f"\n{name}: {full.steps} steps, {sum(len(v) for v in full.volumes)} features ({voxels:,} voxels), "
          f"events {counts}; prepared in {prepare:.2f} s (labels and one skeletonization a step)")
    print("| thinness | points | matches equal | events equal | overlap test | speed-up | whole tracking | speed-up "
          "| skeleton at thinness |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| 0 (full volume) | 100% | 100% | 100% | {over0 * 1e3:.2f} ms | 1 | {whole0 * 1e3:.2f} ms | 1 | - |")
    for tp in (0.5, 1.0, 2.0):
        tr, whole, over, points = best_of(full, tp, repeat)
        pts = sum(trackmod._count_above(s.scores, tp) for s in full._steps)
        agree = tr.agreement(full)
        print(f"| {tp:g} | {100 * pts / voxels:.1f}% | {100 * agree['matches']:.1f}% | {100 * agree['events']:.1f}% "
              f"| {over * 1e3:.2f} ms | {over0 / over:.1f}x | {whole * 1e3:.2f} ms | {whole0 / whole:.1f}x "
              f"| {points * 1e3:.2f} ms |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", nargs="?", help="a folder of time steps (default: the shared viscous-fingering run)")
    ap.add_argument("--lo", type=float, help="with FOLDER: the features' threshold")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    if args.folder:
        table(args.folder, steps_of(args.folder), args.lo, args.repeat)
        return 0
    if os.path.isdir(FINGERS):
        table("viscous fingers, salt >= 20", steps_of(FINGERS), 20, args.repeat)
        table("viscous fingers below the source (z < 52), salt >= 30", steps_of(FINGERS, 52), 30, args.repeat)
    else:
        print(f"skipped the viscous fingers: {FINGERS} is absent (the shared data)")
    table("synthetic vortex tubes (not a simulation), 128³, field >= 0.5", vortex_tubes(), 0.5, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Benchmark: skeletonization of the humanoid phantom (issue: foundation).

Measures, in one run on this machine:
  * volrig: Euclidean DT + thinness scores + sorted order (``volrig.skeletonize``), best of --repeat runs;
  * the reference: ``scipy.ndimage.distance_transform_edt`` alone on the same mask (one run), and the ratio;
  * re-thresholding at a new thinness (``Skeleton.at``), median over many thinness values;
  * peak memory of skeletonize, in bytes per grid voxel (measured in a child process from ru_maxrss).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_skeleton.py [--scale 1.0] [--repeat 3]
Targets (scale 1, 2 cores): skeletonize <= 1.5 s and >= 6x faster than scipy's EDT; at() <= 20 ms;
peak memory <= 12 bytes per voxel.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import volrig  # noqa: E402
from volrig import phantom  # noqa: E402


def peak_memory_child(mask_path: str) -> dict:
    """Runs skeletonize in a fresh process; reports the growth of its peak RSS (VmHWM, which unlike ru_maxrss is
    not inherited from the forking parent) over the baseline with the mask loaded."""
    code = f"""
import sys, json, numpy as np
sys.path.insert(0, {os.path.join(HERE, '..', 'python')!r})
import volrig
def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
mask = np.load({mask_path!r})
base = hwm()
sk = volrig.skeletonize(mask)
peak = hwm()
print(json.dumps({{"base_kib": base, "peak_kib": peak, "object": sk.object_count}}))
"""
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-scipy", action="store_true", help="skip the scipy reference")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    ph = phantom.humanoid(scale=args.scale)
    mask = volrig.segment(ph.volume).array
    voxels = mask.size
    x, y, z = ph.volume.dims
    print(f"phantom scale {args.scale}: {x} x {y} x {z} = {voxels:,} voxels, {mask.sum():,} object "
          f"({100 * mask.mean():.1f}%), {os.cpu_count()} CPUs")

    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        sk = volrig.skeletonize(mask)
        times.append(time.perf_counter() - t)
    t_volrig = min(times)
    print(f"volrig.skeletonize (EDT + scores + sorted order): best {t_volrig:.3f} s of {args.repeat} "
          f"({', '.join(f'{t:.3f}' for t in times)})")

    def median_ms(fn, reps=15):
        ts = []
        for _ in range(reps):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
        return 1000 * statistics.median(ts)

    t_count = median_ms(lambda: sk.count(0.3))
    print(f"re-threshold: Skeleton.count(tp) {1000 * t_count:.1f} us; Skeleton.at(tp) with its point arrays:")
    at_ms = {}
    for tp in (0.1, 0.2, 0.3, 0.5, 0.8):
        n = sk.count(tp)
        at_ms[tp] = median_ms(lambda: sk.at(tp))
        print(f"  TP {tp}: {n:>9,} points ({100 * n / sk.object_count:5.2f}% of the object) in {at_ms[tp]:7.2f} ms")
    n03 = sk.count(0.3)
    result = {"scale": args.scale, "voxels": voxels, "object_voxels": int(mask.sum()),
              "skeletonize_s": t_volrig, "count_ms": t_count, "at_ms": at_ms,
              "points_at_0.3": n03}

    if not args.no_scipy:
        from scipy import ndimage
        t = time.perf_counter()
        ndimage.distance_transform_edt(mask)
        t_scipy = time.perf_counter() - t
        print(f"scipy.ndimage.distance_transform_edt alone: {t_scipy:.3f} s  ->  volrig is "
              f"{t_scipy / t_volrig:.1f}x faster (and also computes scores and the order)")
        result.update(scipy_edt_s=t_scipy, speedup_vs_scipy=t_scipy / t_volrig)

    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "mask.npy")
        np.save(p, mask)
        sk = None  # (freed before the child measures: pyflakes reads a del of a closure name as undefined)
        mem = peak_memory_child(p)
    grown = (mem["peak_kib"] - mem["base_kib"]) * 1024
    print(f"peak memory of skeletonize: {grown / 2**20:.0f} MiB above the loaded mask = "
          f"{grown / voxels:.2f} bytes per voxel (mask itself: 1 byte per voxel)")
    result["peak_bytes_per_voxel"] = grown / voxels

    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

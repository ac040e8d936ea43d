#!/usr/bin/env python3
"""Benchmark: volrig.pore_network on the Berea sandstone (issue 57, thesis 9.4): time, peak memory against the
image's bytes, and the network's figures against the direct numerical simulation's.

The image: ../shared/data/rock/berea_100_to_300.npz (key im, 200³, True = pore, 5.345 µm voxels; skipped with a
message when absent). Its reference figures (PoreSpyIO_on_Berea.py beside it) name the array's axes 0, 1, 2 x, y,
z, as PoreSpy does; volrig's x, y, z are the array's axes 2, 1, 0, so both readings are printed.

Peak memory: the process's peak resident set (VmHWM) during the call less its resident set before it (the image
loaded), over the image's bytes (one byte a voxel), for the first call (the later ones, timed, run on a heap the
earlier ones grew).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_pores.py [--repeat 3]
"""
import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))

import volrig  # noqa: E402
from volrig.pores import MILLIDARCY  # noqa: E402
from volrig_support import data_root  # noqa: E402

K_MD = (1360.0, 1304.0, 1193.0)  # the simulation's x, y, z = the array's axes 0, 1, 2
F = (23.12, 23.99, 25.22)


def status_kb(key: str) -> int:
    """A /proc/self/status figure in kB: VmRSS (resident now) or VmHWM (the process's own high-water mark, which
    ru_maxrss is not: it carries the forking parent's resident set)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    path = data_root() / "rock" / "berea_100_to_300.npz"
    if not path.exists():
        print(f"skipped: {path} is absent (the ../shared/data folder sits beside the checkout)")
        return
    im = np.load(path)["im"]
    before = status_kb("VmRSS")
    times = []
    for run in range(args.repeat):
        t = time.perf_counter()
        net = volrig.pore_network(im, voxel=5.345e-6)
        times.append(time.perf_counter() - t)
        if run == 0:  # the first call's peak: later calls run on a heap the earlier ones grew
            peak = status_kb("VmHWM") - before
    print(f"Berea {im.shape[0]}x{im.shape[1]}x{im.shape[2]}: porosity {net.porosity:.5f} (mask mean "
          f"{im.mean():.5f}); {net.pore_count} pores, {net.throat_count} throats, mean coordination "
          f"{net.coordination.mean():.2f}")
    print(f"time best {min(times):.2f} s, median {sorted(times)[len(times) // 2]:.2f} s; peak memory "
          f"{peak / 1024:.0f} MB = {peak * 1024 / im.size:.1f}x the image's {im.size / 2 ** 20:.0f} MB")
    print()
    print("| array axis (simulation's name) | volrig axis | K mD | simulation | error | F | simulation | error |")
    print("|---|---|---|---|---|---|---|---|")
    for a in range(3):
        v = 2 - a
        k, f = net.permeability[v] / MILLIDARCY, net.formation_factor[v]
        print(f"| {a} ({'xyz'[a]}) | {'xyz'[v]} | {k:.0f} | {K_MD[a]:.0f} | {100 * (k / K_MD[a] - 1):+.1f}% | "
              f"{f:.2f} | {F[a]:.2f} | {100 * (f / F[a] - 1):+.1f}% |")
    print()
    print("Read by name instead (volrig's x against the simulation's x):")
    for a in range(3):
        k, f = net.permeability[a] / MILLIDARCY, net.formation_factor[a]
        print(f"  {'xyz'[a]}: K {k:.0f} mD ({100 * (k / K_MD[a] - 1):+.1f}%), F {f:.2f} ({100 * (f / F[a] - 1):+.1f}%)")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Benchmark: local thickness, the plane-like skeleton and the medial surface against the Euclidean distance
transform (issue 22).

For each case, best and median of --repeat runs (the ratio of the bests is the steadier on a busy machine):
volrig.distance_transform (the exact EDT), volrig.local_thickness (EDT + ridge centres + painting their balls) and
volrig.plane_like at t = 5 voxels (feature transform + boundary geodesics) and volrig.medial_surface at t = 5
(plane_like's edges + EDT + thinning + mesh + rods), each with its ratio to the EDT. Cases:
  * shells: a 256^3 grid holding nested spherical shells 3, 6 and 12 voxels thick (plate-like);
  * rods and plates: a 256^3 frame of plates 8 voxels thick and rods of radius 4-16 (mixed);
  * the Visible Human Male's bone (labels 84, 92) at 2 mm, 342 x 187 x 939 (../shared/data; skipped when absent);
  * the lidc2 chest CT's bone (>= 200 of 255: ribs, spine, scapulae), 256 x 256 x 133 (skipped when absent).

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_thickness.py [--repeat 3] [--only shells]
Targets (issue 22, 2 cores): local thickness within 3x of the EDT measured in the same run; the medial surface of
a 256^3 scan within 5 s.
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))  # volrig_support: data_root, subjects

import volrig  # noqa: E402
from volrig_support import data_root  # noqa: E402
from bench_centerline import timed  # noqa: E402  (best, median, last result of repeated calls)

DATA = str(data_root())


def shells(n=256):
    z, y, x = np.ogrid[:n, :n, :n]
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2)
    return volrig.Volume((np.abs(r - 40) < 1.5) | (np.abs(r - 70) < 3) | (np.abs(r - 110) < 6), (1.0, 1.0, 1.0))


def rods_and_plates(n=256):
    m = np.zeros((n, n, n), bool)
    m[20:28, 20:236, 20:236] = True        # floor plate
    m[20:236, 20:236, 20:28] = True        # wall plate
    m[20:236, 228:236, 20:236] = True      # back plate
    z, y, x = np.ogrid[:n, :n, :n]
    for k, r in enumerate((4, 8, 12, 16)):
        cx, cy = 70 + 45 * k, 80 + 30 * k
        m |= ((x - cx) ** 2 + (y - cy) ** 2 < r * r) & (z >= 28) & (z < 236)
    return volrig.Volume(m, (1.0, 1.0, 1.0))


def vhm_bone():
    path = os.path.join(DATA, "visible-human", "austinman_2mm_labels.nii.gz")
    if not os.path.exists(path):
        return None
    v = volrig.load(path)
    return volrig.Volume(np.isin(v.array, (84, 92)), v.spacing, v.origin)


def lidc_bone():
    path = os.path.join(DATA, "lidc2", "LIDC2.mha")
    if not os.path.exists(path):
        return None
    v = volrig.load(path)
    return volrig.Volume(v.array >= 200, v.spacing, v.origin)


CASES = {"shells": shells, "rods-and-plates": rods_and_plates, "vhm2-bone": vhm_bone, "lidc2-bone": lidc_bone}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", choices=sorted(CASES), help="one case")
    args = ap.parse_args()
    print(f"local thickness, plane_like and medial_surface (t = 5) vs the EDT, best / median of {args.repeat}, "
          f"{os.cpu_count()} cores")
    print(f"  {'case':<16} {'grid':>12} {'object':>10} {'EDT s':>13} {'thickness s':>13} {'ratio':>12}"
          f" {'plane_like s':>13} {'ratio':>12} {'medial s':>13} {'ratio':>12}")
    for name, make in CASES.items():
        if args.only and name != args.only:
            continue
        mask = make()
        if mask is None:
            print(f"  {name:<16} skipped: data not in ../shared/data")
            continue
        e_best, e_med, _ = timed(args.repeat, lambda: volrig.distance_transform(mask))
        t_best, t_med, _ = timed(args.repeat, lambda: volrig.local_thickness(mask))
        p_best, p_med, _ = timed(args.repeat, lambda: volrig.plane_like(mask, t=5.0))
        m_best, m_med, _ = timed(args.repeat, lambda: volrig.medial_surface(mask, t=5.0))
        grid = "x".join(str(d) for d in mask.dims)
        print(f"  {name:<16} {grid:>12} {int(np.count_nonzero(mask.array)):>10,} {e_best:6.3f}/{e_med:6.3f} "
              f"{t_best:6.3f}/{t_med:6.3f} {t_best / e_best:5.2f}x/{t_med / e_med:5.2f}x "
              f"{p_best:6.3f}/{p_med:6.3f} {p_best / e_best:5.2f}x/{p_med / e_med:5.2f}x "
              f"{m_best:6.3f}/{m_med:6.3f} {m_best / e_best:5.2f}x/{m_med / e_med:5.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())

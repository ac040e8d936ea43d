#!/usr/bin/env python3
"""Benchmark: volrig.inflate on large drawings (issue 55: "a 1000 x 1000 drawing inflates in a few seconds, or is
refused above a documented size").

For each drawing, best and median of --repeat runs of volrig.inflate, the solid's voxels, and the ratio of its time
to writing the same number of int32 voxels with numpy (np.full: the least an inflation that writes its labels can
cost), measured in the same run. Drawings (the procedural ones of the tests, volrig_support.sketches):
  * the character drawn with an arm over the belly at 400 and 1000 px tall (thin limbs, front parts);
  * a disc 500 and 680 px across (the deepest solid a drawing of that size gives: a ball);
  * a disc 1000 px across: refused at the default max_voxels (2^28), then inflated with max_voxels raised.

Run:  PYTHONPATH=python /usr/bin/python3 benchmarks/bench_inflate.py [--repeat 3]
Target: the 1000 px character within a few seconds; time linear in the voxels written (the ratio stays flat).
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))

import volrig  # noqa: E402
from volrig_support import sketches as K  # noqa: E402
from bench_centerline import timed  # noqa: E402  (best, median, last result of repeated calls)


def scaled(img, rows):
    """``img`` resized (nearest) to ``rows`` pixels tall."""
    f = rows / img.shape[0]
    r = np.minimum((np.arange(int(round(img.shape[0] * f))) / f).astype(int), img.shape[0] - 1)
    c = np.minimum((np.arange(int(round(img.shape[1] * f))) / f).astype(int), img.shape[1] - 1)
    return img[r][:, c]


def case(name, img, repeat, **options):
    best, median, v = timed(repeat, lambda: volrig.inflate(img, **options))
    n = int(np.prod(v.dims))
    ref, _, _ = timed(repeat, lambda: np.full(n, 1, np.int32))
    print(f"| {name} | {img.shape[1]} x {img.shape[0]} | {v.dims[0]} x {v.dims[1]} x {v.dims[2]} | "
          f"{n / 1e6:.0f} M | {best:.2f} / {median:.2f} | {best / ref:.1f}x |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print("| drawing | pixels | solid | voxels | inflate s (best / median) | / np.full of its voxels |")
    print("|---|---|---|---|---|---|")
    arm = K.character(arm_over=True)
    case("character, arm over the belly", scaled(arm, 400), args.repeat)
    case("character, arm over the belly", scaled(arm, 1000), args.repeat)
    case("disc", K.disc(r=230, pad=20), args.repeat)
    case("disc", K.disc(r=320, pad=20), args.repeat)
    disc = K.disc(r=480, pad=20)
    try:
        volrig.inflate(disc)
        raise SystemExit("the 1000 px disc was not refused at the default max_voxels")
    except volrig.VolrigError as e:
        print(f"\n1000 px disc at the default max_voxels: {e}\n")
    case("disc, max_voxels=10**9", disc, 1, max_voxels=10 ** 9)


if __name__ == "__main__":
    main()

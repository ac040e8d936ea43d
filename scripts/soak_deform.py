#!/usr/bin/env python3
"""Exactness soak of the deformation: thousands of random small rigs (tests/python/random_rigs.py: bent tubes on
anisotropic grids, rigid or smooth bindings of 30 to 1500 points, three random poses each in every mode, proximity
and sampling), each frame drawn with and without the bones' lattice tables and compared voxel for voxel with the
brute-force scatter. Prints every mismatch; exits 1 when there was one. With --collide, pairs of random tubes on one
grid instead: `volrig.collide` against the brute-force frames of both intersected, and `volrig.self_collide` of one
against its brute force.

Run:  PYTHONPATH=python /usr/bin/python3 scripts/soak_deform.py [--seeds 0-6000] [--jobs 2] [--extended | --collide]
(6000 rigs took 160 s on 2 cores.)
"""
import argparse
import multiprocessing
from functools import partial
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "python"))

from random_rigs import collide_mismatch, mismatch  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="0-6000", help="a range of seeds, first-last (exclusive)")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--extended", action="store_true",
                    help="also rigid tissue, per-point radius scales and frames in bricks (random_rigs.mismatch)")
    ap.add_argument("--collide", action="store_true",
                    help="volrig.collide of two random tubes against their frames intersected, and self_collide, "
                         "instead (random_rigs.collide_mismatch)")
    args = ap.parse_args()
    first, last = (int(v) for v in args.seeds.split("-"))
    check = collide_mismatch if args.collide else partial(mismatch, extended=args.extended)
    start, bad = time.time(), 0
    with multiprocessing.Pool(args.jobs) as pool:
        for k, found in enumerate(pool.imap_unordered(check, range(first, last), chunksize=8), start=1):
            if found:
                bad += 1
                print(found, flush=True)
            if k % 500 == 0:
                print(f"  {k} of {last - first} rigs, {bad} mismatches, {time.time() - start:.0f} s", flush=True)
    print(f"seeds {first}-{last}: {bad} mismatches in {time.time() - start:.0f} s")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

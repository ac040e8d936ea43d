#!/usr/bin/python3
"""Issue 55's measure: what decoding in a child process (io/isolate.cpp) costs. GDCM's JPEG-family decoders and
OpenVDB's reader run in a fork()ed child that sends the volume back through a pipe; VOLRIG_ISOLATE=0 turns that off
(for this measure only: a crashing file then kills the process). ../shared/data holds no DICOM series, so a real
chest CT (lidc2, 256 x 256 x 133) is written as a 512 x 512 x 133 uint16 series (each pixel repeated 2 x 2, values
x 8), each slice compressed to JPEG Lossless by gdcmconv; the VDB is the Visible Human at 2 mm (342 x 187 x 939,
60 M voxels) as a float grid. Each load runs in a fresh process, best of --repeat.

    PYTHONPATH=python /usr/bin/python3 benchmarks/bench_isolation.py [--repeat 5]
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "support"))
import volrig  # noqa: E402
from volrig_support import data_root  # noqa: E402

TIMED = """
import sys, time, volrig
t = time.perf_counter(); v = volrig.load(sys.argv[1]); print(time.perf_counter() - t, v.array.nbytes)
"""


def jpeg_series(folder):
    import pydicom
    sys.path.insert(0, os.path.join(HERE, "..", "tests", "python"))
    from test_io_dicom import write_slice
    from pydicom.uid import generate_uid
    ct = volrig.load(str(data_root() / "lidc2" / "LIDC2.mha")).array.astype(np.uint16) * 8
    raw = os.path.join(folder, "raw")
    os.makedirs(raw)
    os.makedirs(os.path.join(folder, "jpeg"))
    uid = generate_uid()
    for k, s in enumerate(ct):
        name = f"s{k:03d}.dcm"
        write_slice(os.path.join(raw, name), np.kron(s, np.ones((2, 2), np.uint16)), k, series_uid=uid)
        subprocess.run(["gdcmconv", "--jpeg", os.path.join(raw, name), os.path.join(folder, "jpeg", name)], check=True)
    assert pydicom.dcmread(os.path.join(folder, "jpeg", "s000.dcm")).file_meta.TransferSyntaxUID.is_compressed
    return os.path.join(folder, "jpeg")


def big_vdb(folder):
    vh = volrig.load(str(data_root() / "visible-human" / "austinman_2mm_labels.nii.gz"))
    path = os.path.join(folder, "vh.vdb")
    volrig.Volume(vh.array.astype(np.float32), vh.spacing, vh.origin).save(path)
    return path


def best(path, isolate, repeat):
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "python"))
    if not isolate:
        env["VOLRIG_ISOLATE"] = "0"
    times = []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", TIMED, path], env=env, capture_output=True, text=True, check=True)
        seconds, nbytes = out.stdout.split()
        times.append(float(seconds))
    return min(times), int(nbytes)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for label, make in (("JPEG Lossless DICOM series", jpeg_series), ("OpenVDB float grid", big_vdb)):
            path = make(tmp)
            (off, nbytes), (on, _) = best(path, False, args.repeat), best(path, True, args.repeat)
            print(f"{label}: {nbytes / 1e6:.0f} MB decoded; in process {off:.3f} s, in a child {on:.3f} s: "
                  f"+{on - off:.3f} s ({100 * (on - off) / off:+.1f} %)")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The call overhead of cairn.detect_points over its C++ work, on the RELLIS-3D scan.

    PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_overhead.py [--repeat 15]

For each call the module reports the wall time of its C++ work (Detection.cpp_seconds: layout,
range image, detection, rules, labels, segments.json, GIL released) and of the detection alone
(detect_seconds, what `cairn detect` prints and bench/detector_benchmark.cpp's Detect/rellis
measures). The overhead is the rest: argument checks, the copy of the array in, the result
object. Medians over --repeat calls; a benchmark, not a test: run it once on a quiet machine.
"""

import argparse
import pathlib
import statistics
import time

import numpy as np

import cairn

REPO = pathlib.Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--scan", default=REPO.parent / "shared/datasets/rellis3d-000104/os1_bin/000104.bin")
    parser.add_argument("--config", default=REPO / "config/sensors/os1-64.yaml")
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--threads", type=int, default=1, help="detector threads (0: every core)")
    args = parser.parse_args()

    settings = cairn.load_settings(str(args.config))
    settings.threads = args.threads
    scan = np.fromfile(args.scan, np.float32).reshape(-1, 4)
    cairn.detect_points(scan, sensor="OS1-64", settings=settings)  # warm-up
    wall, cpp, detect = [], [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        det = cairn.detect_points(scan, sensor="OS1-64", settings=settings)
        wall.append(time.perf_counter() - start)
        cpp.append(det.cpp_seconds)
        detect.append(det.detect_seconds)
        _ = det.point_labels, det.labels, det.classes  # zero-copy views
    w, c, d = (statistics.median(x) * 1000 for x in (wall, cpp, detect))
    print(f"RELLIS-3D 000104, {scan.shape[0]} points, {args.threads} thread(s), "
          f"median of {args.repeat}:")
    print(f"  cairn.detect_points   {w:8.2f} ms  (Python wall time of the call)")
    print(f"  C++ work of the call  {c:8.2f} ms  (Detection.cpp_seconds)")
    print(f"  detection alone       {d:8.2f} ms  (Detection.detect_seconds)")
    print(f"  overhead {w - c:.2f} ms = {100 * (w - c) / c:.1f}% of the C++ work; "
          f"ratio call / C++ work {w / c:.3f}, call / detection {w / d:.3f}")


if __name__ == "__main__":
    main()

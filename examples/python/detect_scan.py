#!/usr/bin/env python3
"""Detect obstacles in one LiDAR scan and plot a bird's-eye view (writes a PNG).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/detect_scan.py \
        ../shared/datasets/rellis3d-000104/os1_bin/000104.bin --out birds_eye.png

Every return is drawn in the level frame (z up along gravity, x the sensor's heading), seen
from above: ground grey, obstacle points of kept segments blue (their foot light blue),
rejected segments red. The same answer as `cairn detect --points`.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cairn  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scan", nargs="?",
                        default=REPO.parent / "shared/datasets/rellis3d-000104/os1_bin/000104.bin",
                        help="KITTI-layout .bin (float32 x, y, z, intensity per point)")
    parser.add_argument("--sensor", default="OS1-64", help="sensor preset (HDL-64E, VLP-16, ...)")
    parser.add_argument("--config", default=REPO / "config/sensors/os1-64.yaml")
    parser.add_argument("--half-extent", type=float, default=25.0, help="shown: |x|, |y| [m]")
    parser.add_argument("--out", default="birds_eye.png")
    args = parser.parse_args()

    settings = cairn.load_settings(str(args.config))
    scan = np.fromfile(args.scan, np.float32).reshape(-1, 4)
    det = cairn.detect_points(scan, sensor=args.sensor, settings=settings)
    print(f"{det}: {det.kept} kept, {det.rejected} rejected, "
          f"detection {1000 * det.detect_seconds:.1f} ms")

    returned = det.cell_of_point >= 0
    level = scan[returned, :3] @ det.R_level_sensor.T.astype(np.float32)  # [m], z up
    cls = cairn.label_class(det.point_labels[returned])
    foot = det.foot.ravel()[det.cell_of_point[returned]] != 0

    fig, ax = plt.subplots(figsize=(6, 6), dpi=100)
    groups = [
        (cls == cairn.CLASS_NONE, "#b0b0b0", "ground"),
        ((cls == cairn.CLASS_KEPT) & foot, "#78dcff", "foot of an obstacle"),
        (cls == cairn.CLASS_REJECTED, "#e02020", "rejected segment"),
        ((cls == cairn.CLASS_KEPT) & ~foot, "#0028ff", "obstacle"),
    ]
    for mask, colour, name in groups:  # obstacles last, so that the ground does not hide them
        # x forward is up the image, y left is to the left.
        ax.scatter(-level[mask, 1], level[mask, 0], s=0.3, c=colour, label=name, linewidths=0,
                   rasterized=True)
    ax.plot([0], [0], "k^", markersize=6)
    h = args.half_extent
    ax.set(xlim=(-h, h), ylim=(-h, h), aspect="equal", xlabel="right (-y) [m]",
           ylabel="x (forward) [m]",
           title=f"{pathlib.Path(args.scan).name}: {det.kept} obstacles kept")
    ax.legend(loc="lower right", markerscale=12, fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

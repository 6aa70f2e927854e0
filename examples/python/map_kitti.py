#!/usr/bin/env python3
"""Map a KITTI odometry sequence frame by frame and show the cost grid (writes a PNG).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/map_kitti.py \
        ../shared/datasets/kitti-seq00-0-10 --out cost_grid.png

Each scan goes in as a numpy array with its pose (velodyne in the z-up map frame, from
poses.txt) and its stamp; the Mapper detects, levels and fuses it, as `cairn map` does.
The picture shows the nav2 costs (free white to orange, lethal red, unknown grey) and the
sensor's path.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402

import cairn  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]


def cost_colours():
    """256 colours for nav2 costs: 0 white .. 252 orange, 253 purple, 254 red, 255 grey."""
    t = np.arange(256) / 252.0
    rgb = np.stack([np.ones(256), np.where(t <= 0.5, 1.0, 1.0 - (t - 0.5) * 2 * 135 / 255),
                    np.clip(1.0 - 2 * t, 0, 1)], axis=1)
    rgb[253], rgb[254], rgb[255] = (0.55, 0.16, 0.63), (0.86, 0.0, 0.0), (0.5, 0.5, 0.5)
    return ListedColormap(rgb)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", nargs="?", default=REPO.parent / "shared/datasets/kitti-seq00-0-10")
    parser.add_argument("--range", default="", help="scans A:B (inclusive); default all")
    parser.add_argument("--config", default=REPO / "config/sensors/hdl-64e.yaml")
    parser.add_argument("--out", default="cost_grid.png")
    args = parser.parse_args()

    settings = cairn.load_settings(str(args.config))
    mapper = cairn.Mapper(settings)
    path = []
    for scan in cairn.open_kitti(str(args.sequence), range=args.range):
        points = cairn.read_points(scan.path)  # or np.fromfile(...).reshape(-1, 4)
        record = mapper.add_points(points, scan.T_map_velodyne, stamp=scan.stamp_s,
                                   sensor="HDL-64E", source=scan.path)
        path.append(record["T_world_sensor"][:2, 3])
        print(f"scan {scan.index}: {record['kept']} obstacles kept, "
              f"detect {record['detect_s']:.2f} s, fuse {record['fuse_s']:.2f} s")
    grid = mapper.cost_grid()
    lethal = int((grid.cost == 254).sum())
    print(f"{grid}: {lethal} lethal cells, {len(mapper.obstacles())} obstacles")

    fig, ax = plt.subplots(figsize=(7, 5), dpi=100)
    ax.imshow(grid.cost, cmap=cost_colours(), vmin=0, vmax=255, extent=grid.extent,
              interpolation="nearest")
    path = np.array(path)
    ax.plot(path[:, 0], path[:, 1], "b.-", linewidth=1, markersize=4, label="sensor path")
    ax.set(xlabel="world x [m]", ylabel="world y [m]",
           title=f"cost grid after {mapper.frames_fused} scans ({grid.resolution:.1f} m cells)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""The Mapper from Python equals `cairn map` of the same build over KITTI 00 (its first two
scans, to keep the run short): the same cost grid, elevation and map files."""

import numpy as np
import pytest

import cairn
from conftest import KITTI, REPO, need, run_cli

HDL_CONFIG = REPO / "config" / "sensors" / "hdl-64e.yaml"
RANGE = "0:1"


def read_pgm(path):
    """A binary (P5) 8-bit PGM as an (H, W) uint8 array."""
    data = open(path, "rb").read()
    fields, pos = [], 0
    while len(fields) < 4:  # magic, width, height, maxval; '#' comments skipped
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos)
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    assert fields[0] == b"P5" and fields[3] == b"255"
    width, height = int(fields[1]), int(fields[2])
    return np.frombuffer(data[pos + 1:pos + 1 + width * height], np.uint8).reshape(height, width)


def yaml_origin(path):
    for line in open(path):
        if line.startswith("origin:"):
            return [float(v) for v in line.split(":", 1)[1].strip(" []\n").split(",")]
    raise AssertionError(f"{path}: no origin")


@pytest.fixture(scope="module")
def cli_map(tmp_path_factory):
    kitti = need(KITTI / "poses.txt").parent
    out = tmp_path_factory.mktemp("kitti") / "out"
    run_cli("map", "--kitti", kitti, "--range", RANGE, "--config", HDL_CONFIG, "--out", out)
    return out


@pytest.fixture(scope="module")
def settings():
    return cairn.load_settings(str(HDL_CONFIG))


def test_frames_of_the_reader_give_the_cli_map(cli_map, settings, tmp_path):
    mapper = cairn.Mapper(settings)
    frames = cairn.kitti_frames(str(KITTI), range=RANGE, lidar="HDL-64E")
    assert len(frames) == 2
    records = [mapper.add_frame(frame) for frame in frames]
    assert all(r["used"] for r in records) and mapper.frames_fused == 2
    grid = mapper.cost_grid()
    assert grid.cost.dtype == np.uint8 and grid.elevation.dtype == np.float32
    assert grid.resolution == pytest.approx(settings.cell_size_m)
    # cost.pgm holds nav2's OccupancyGrid values (255 for unknown), top row first.
    pgm = read_pgm(cli_map / "cost.pgm")
    np.testing.assert_array_equal(grid.occupancy.astype(np.int16) % 256, pgm)
    assert (grid.cost == 254).any()  # lethal cells: the building fronts and cars
    # cost.yaml prints 12 significant digits.
    assert list(grid.origin) == pytest.approx(yaml_origin(cli_map / "cost.yaml")[:2], abs=1e-9)
    # The map files themselves, byte for byte.
    mapper.save(str(tmp_path))
    for name in ["cost.pgm", "cost.yaml", "elevation.tiff", "elevation.yaml", "obstacles.json"]:
        assert (tmp_path / name).read_bytes() == (cli_map / name).read_bytes(), name
    assert len(mapper.obstacles()) > 0


def test_numpy_scans_give_the_cli_cost_grid(cli_map, settings):
    mapper = cairn.Mapper(settings)
    for scan in cairn.open_kitti(str(KITTI), range=RANGE):
        points = cairn.read_points(scan.path)
        record = mapper.add_points(points, scan.T_map_velodyne, stamp=scan.stamp_s,
                                   sensor="HDL-64E")
        assert record["used"], record
    grid = mapper.cost_grid()
    np.testing.assert_array_equal(grid.occupancy.astype(np.int16) % 256,
                                  read_pgm(cli_map / "cost.pgm"))

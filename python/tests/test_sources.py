"""The readers of recorded sequences from Python give the frames `cairn map` reads: the
bundled rawlog (hill_drive, range camera with odometry and IMU) and a folder of depth PNGs
with TUM poses, written here from that rawlog's frames. Mapping their frames with the
Mapper gives `cairn map`'s files byte for byte."""

import numpy as np
import pytest
from PIL import Image

import cairn
from conftest import REPO, cli_error, run_cli

SEQUENCE = REPO / "datasets" / "sequences" / "hill_drive"
RAWLOG = SEQUENCE / "sequence.rawlog"
MAP_CONFIG = SEQUENCE / "map.yaml"
FRAMES = 8  # of the rawlog's 30, to keep the run short
MAP_FILES = ["cost.pgm", "cost.yaml", "elevation.tiff", "elevation.yaml", "obstacles.json"]
DEPTH_SCALE_M = 0.001


def quaternion_xyzw(rotation):
    """Unit quaternion (x, y, z, w) of a 3x3 rotation matrix (the largest-pivot method)."""
    r = np.asarray(rotation, float)
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * np.sqrt(1.0 + trace)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0] * 4
        q[i] = s / 4
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        q[3] = (r[k, j] - r[j, k]) / s
    return np.array(q) / np.linalg.norm(q)


def assert_same_map_files(mapper, cli_out, tmp_path):
    mapper.save(str(tmp_path))
    for name in MAP_FILES:
        assert (tmp_path / name).read_bytes() == (cli_out / name).read_bytes(), name


@pytest.fixture(scope="module")
def rawlog_frames():
    settings = cairn.load_settings(str(MAP_CONFIG))
    frames = list(cairn.rawlog_frames(str(RAWLOG), settings=settings))
    return settings, frames


def test_rawlog_frames_are_the_sequence(rawlog_frames):
    _, frames = rawlog_frames
    assert len(frames) == 30  # sequence.yaml: frames: 30
    assert all(f.used for f in frames)
    assert [f.index for f in frames] == list(range(30))
    stamps = np.array([f.stamp_s for f in frames])
    np.testing.assert_allclose(np.diff(stamps), 0.625, atol=1e-3)  # 1.6 Hz
    assert (frames[0].width, frames[0].height) == (320, 240)
    xyz = frames[0].xyz
    assert xyz.shape == (240, 320, 3) and xyz.dtype == np.float32
    valid = np.isfinite(xyz[..., 2])
    assert 0.3 < valid.mean() < 0.95  # no return above the horizon and beyond 30 m
    assert (xyz[..., 2][valid] > 0).all()  # optical frame: z forward
    # The odometry pose: the camera 1.6 m above the ground, its optical axis ahead (x), its
    # image y down; the drive runs along x.
    first, last = frames[0].T_world_sensor, frames[-1].T_world_sensor
    assert first[2, 3] == pytest.approx(1.6, abs=0.3)
    assert first[0, 2] > 0.9 and first[2, 1] < -0.9  # optical z ahead, y down
    assert last[0, 3] - first[0, 3] == pytest.approx(36.25, rel=0.05)


def test_mapping_rawlog_frames_gives_the_cli_map(rawlog_frames, tmp_path):
    settings, frames = rawlog_frames
    cli_out = tmp_path / "cli"
    run_cli("map", "--rawlog", RAWLOG, "--config", MAP_CONFIG, "--max-frames", FRAMES,
            "--out", cli_out)
    mapper = cairn.Mapper(settings)
    for frame in frames[:FRAMES]:
        assert mapper.add_frame(frame)["used"]
    assert mapper.frames_fused == FRAMES
    assert_same_map_files(mapper, cli_out, tmp_path / "py")


@pytest.fixture(scope="module")
def depth_folder(rawlog_frames, tmp_path_factory):
    """The first frames of the rawlog as 16-bit depth PNGs named by stamp, a TUM file of
    their odometry poses and a camera YAML: what `cairn map --frames` reads."""
    _, frames = rawlog_frames
    folder = tmp_path_factory.mktemp("depth")
    depths, poses = [], []
    with open(folder / "poses.tum", "w") as tum:
        tum.write("# timestamp tx ty tz qx qy qz qw\n")
        for frame in frames[:FRAMES]:
            z = np.nan_to_num(frame.xyz[..., 2], nan=0.0)
            units = np.round(z / DEPTH_SCALE_M).astype(np.uint16)
            Image.fromarray(units).save(folder / f"{frame.stamp_s:.6f}.png")
            depths.append(units.astype(np.float32) * DEPTH_SCALE_M)
            pose = frame.T_world_sensor
            t, q = pose[:3, 3], quaternion_xyzw(pose[:3, :3])
            tum.write(f"{frame.stamp_s:.6f} " + " ".join(f"{v:.9f}" for v in [*t, *q]) + "\n")
            poses.append(pose)
    # sequence.yaml: 320 x 240, fx = fy = 260 px; the principal point at the centre.
    (folder / "intrinsics.yaml").write_text(
        "width: 320\nheight: 240\nfx: 260\nfy: 260\ncx: 159.5\ncy: 119.5\n"
        f"depth_scale: {DEPTH_SCALE_M}\nup: [0, -1, 0]\n")
    return folder, depths, poses


def test_depth_frames_read_the_folder(depth_folder):
    folder, depths, poses = depth_folder
    frames = cairn.depth_frames(str(folder), str(folder / "poses.tum"))
    assert len(frames) == FRAMES
    frames = list(frames)
    assert all(f.used for f in frames)
    for frame, depth, pose in zip(frames, depths, poses):
        z = frame.xyz[..., 2]
        np.testing.assert_allclose(np.nan_to_num(z, nan=0.0), depth, atol=1e-6)
        np.testing.assert_allclose(frame.T_world_sensor, pose, atol=1e-6)
        # The pinhole model back-projects pixel (u, v) at z to x = (u - cx) z / fx.
        u = 200
        column = frame.xyz[:, u, :]
        ok = np.isfinite(column[:, 2])
        np.testing.assert_allclose(column[ok, 0], (u - 159.5) * column[ok, 2] / 260, rtol=1e-5)


def test_mapping_depth_frames_gives_the_cli_map(depth_folder, tmp_path):
    folder, _, _ = depth_folder
    cli_out = tmp_path / "cli"
    run_cli("map", "--frames", folder, "--poses", folder / "poses.tum", "--out", cli_out)
    mapper = cairn.Mapper(cairn.Settings())
    for frame in cairn.depth_frames(str(folder), str(folder / "poses.tum")):
        assert mapper.add_frame(frame)["used"]
    assert_same_map_files(mapper, cli_out, tmp_path / "py")
    assert len(mapper.obstacles()) > 0


def test_bad_sources_raise_the_cli_message(depth_folder, tmp_path):
    folder, _, _ = depth_folder
    missing = tmp_path / "none.rawlog"
    with pytest.raises(cairn.Error) as raised:
        cairn.rawlog_frames(str(missing))
    run = run_cli("map", "--rawlog", missing, "--out", tmp_path / "out", check=False)
    assert str(raised.value) == cli_error(run, "map")

    bad_poses = tmp_path / "bad.tum"
    bad_poses.write_text("1.0 0 0 0 0 0 0\n")  # seven numbers, eight expected
    with pytest.raises(cairn.Error) as raised:
        cairn.depth_frames(str(folder), str(bad_poses))
    run = run_cli("map", "--frames", folder, "--poses", bad_poses, "--out", tmp_path / "out2",
                  check=False)
    assert str(raised.value) == cli_error(run, "map")


def test_the_gravity_mode_reports_its_estimate(rawlog_frames):
    """The bundled drive has raw IMU samples: with tilt="gravity" every record carries the
    estimator's answer, and the fused tilt follows the accelerometer, not the biased IMU
    attitude (0.5 deg) of the odometry pose."""
    settings, frames = rawlog_frames
    mapper = cairn.Mapper(settings, tilt="gravity")
    records = [mapper.add_frame(f) for f in frames[:16]]  # accelerometer spans: 7 frames
    g = records[-1]["gravity"]
    assert any(r["gravity"]["accel_terms"] > 0 for r in records)  # one per 7-frame span
    assert g["verticals"] > 0
    assert np.shape(g["attitude_covariance"]) == (3, 3)
    assert all(r["tilt_applied"] for r in records)
    with pytest.raises(cairn.Error, match="prior, refine_to_map or gravity"):
        cairn.Mapper(settings, tilt="level")

"""Bad input raises cairn.Error with the message the command line prints."""

import numpy as np
import pytest

import cairn
from conftest import DEMO, KITTI, cli_error, need, run_cli


def test_error_is_a_value_and_runtime_error():
    assert issubclass(cairn.Error, ValueError) and issubclass(cairn.Error, RuntimeError)


@pytest.mark.parametrize("text", [
    "detector:\n  min_hieght: 0.3\n",         # a typo: unknown key
    "detector:\n  min_height: 2.0\n",         # above max_height
    "detector:\n  min_height: [0.3\n",        # not YAML
    "rules:\n  min_points: ten\n",            # wrong type
    "map:\n  cell_size: -1\n",                # the map stage's own loader
])
def test_bad_settings_raise_the_cli_message(tmp_path, text):
    config = tmp_path / "bad.yaml"
    config.write_text(text)
    with pytest.raises(cairn.Error) as raised:
        cairn.load_settings(str(config))
    subcommand = "map" if text.startswith("map") else "detect"
    if subcommand == "detect":
        run = run_cli("detect", "--depth", DEMO / "depth.png", "--intrinsics",
                      DEMO / "intrinsics.yaml", "--config", config, "--out", tmp_path / "out",
                      check=False)
    else:
        run = run_cli("map", "--frames", tmp_path, "--poses", tmp_path / "none.tum", "--config",
                      config, "--out", tmp_path / "out", check=False)
    assert str(raised.value) == cli_error(run, subcommand)


def test_missing_settings_file_names_it(tmp_path):
    with pytest.raises(cairn.Error, match="nothere.yaml"):
        cairn.load_settings(str(tmp_path / "nothere.yaml"))


@pytest.mark.parametrize("shape", [(5, 2), (5,), (2, 5, 3), (0, 3)])
def test_wrong_point_array_shapes_raise(shape):
    with pytest.raises(cairn.Error, match="points"):
        cairn.detect_points(np.zeros(shape, np.float32), sensor="OS1-64")


def test_wrong_depth_and_pose_shapes_raise():
    with pytest.raises(ValueError, match=r"\(H, W\)"):
        cairn.detect_depth(np.zeros((4, 4, 2), np.float32), fx=1, fy=1, cx=1, cy=1)
    mapper = cairn.Mapper()
    with pytest.raises(cairn.Error, match=r"\(4, 4\)"):
        mapper.add_points(np.ones((10, 4), np.float32), np.eye(3), stamp=0.0)
    with pytest.raises(cairn.Error, match="orthonormal"):
        mapper.add_points(np.ones((10, 4), np.float32), 2 * np.eye(4) - np.diag([0, 0, 0, 1]),
                          stamp=0.0)


def test_bad_sensor_name_raises_the_cli_message(tmp_path):
    kitti = need(KITTI / "poses.txt").parent
    run = run_cli("map", "--kitti", kitti, "--lidar", "OS2-128", "--out", tmp_path / "out",
                  check=False)
    message = cli_error(run, "map")  # "--lidar: unknown sensor preset ..."
    with pytest.raises(cairn.Error) as raised:
        cairn.kitti_frames(str(kitti), lidar="OS2-128")
    assert str(raised.value) == message
    with pytest.raises(cairn.Error) as raised:
        cairn.detect_points(np.ones((10, 4), np.float32), sensor="OS2-128")
    assert "--lidar: " + str(raised.value) == message


def test_bad_method_and_organised_raise():
    with pytest.raises(cairn.Error, match="cone or column"):
        cairn.detect_points(np.ones((10, 4), np.float32), method="grid")
    with pytest.raises(cairn.Error, match="auto, yes or no"):
        cairn.detect_points(np.ones((10, 4), np.float32), organised="maybe")

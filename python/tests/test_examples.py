"""The examples of examples/python/ run and write their pictures."""

import os
import subprocess
import sys

from conftest import KITTI, REPO, RELLIS_SCAN, need

EXAMPLES = REPO / "examples" / "python"


def run_example(name, *args):
    env = dict(os.environ, MPLBACKEND="Agg")
    run = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)],
                         capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr


def test_detect_scan_writes_a_birds_eye_view(tmp_path):
    out = tmp_path / "birds_eye.png"
    run_example("detect_scan.py", need(RELLIS_SCAN), "--out", out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_map_kitti_writes_a_cost_grid(tmp_path):
    out = tmp_path / "cost_grid.png"
    run_example("map_kitti.py", need(KITTI / "poses.txt").parent, "--range", "0:0", "--out", out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

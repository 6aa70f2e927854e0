"""Shared fixtures: the cairn command of the same build tree, the repository and the shared
data sets (../shared/datasets from the repository root, as the C++ tests find them)."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(os.environ.get("CAIRN_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DATASETS = pathlib.Path(os.environ.get("CAIRN_SHARED_DATASETS", REPO.parent / "shared" / "datasets"))
DEMO = REPO / "datasets" / "frames" / "demo"
RELLIS_SCAN = DATASETS / "rellis3d-000104" / "os1_bin" / "000104.bin"
KITTI = DATASETS / "kitti-seq00-0-10"


def cli_path():
    path = os.environ.get("CAIRN_CLI")
    if not path:
        pytest.skip("CAIRN_CLI is not set (ctest sets it to the cairn command of this build)")
    return path


def run_cli(*args, check=True):
    """Runs `cairn ARGS...`; returns the completed process (stdout, stderr as text)."""
    run = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    if check and run.returncode != 0:
        raise AssertionError(f"cairn {' '.join(map(str, args))} failed:\n{run.stderr}")
    return run


def cli_error(run, subcommand):
    """The library's message in `cairn SUBCOMMAND: error: MESSAGE`."""
    assert run.returncode != 0, run.stdout
    prefix = f"cairn {subcommand}: error: "
    lines = [line for line in run.stderr.splitlines() if line.startswith(prefix)]
    assert lines, run.stderr
    return lines[0][len(prefix):]


def need(path):
    if not pathlib.Path(path).exists():
        pytest.skip(f"{path} is absent (see ../shared/datasets/README.md)")
    return pathlib.Path(path)

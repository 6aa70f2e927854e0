"""Detection from Python equals `cairn detect` of the same build: per-point labels, classes,
segment ids and every measure of segments.json, on the RELLIS-3D scan and the demo frame."""

import json

import numpy as np
import pytest

import cairn
from conftest import DEMO, REPO, RELLIS_SCAN, need, run_cli

OS1_CONFIG = REPO / "config" / "sensors" / "os1-64.yaml"


def comparable(doc):
    """segments.json without what two equal runs may tell apart: the input file names (the
    module's inputs are arrays) and the work counters pairs_tested / pairs_found, which
    depend on how the detector's threads split the work (obstacle_points is a result)."""
    doc.pop("inputs")
    doc["stats"].pop("pairs_tested")
    doc["stats"].pop("pairs_found")
    return doc


def segments_doc(path):
    with open(path) as f:
        return comparable(json.load(f))


def python_doc(det):
    return comparable(json.loads(det.segments_json))


@pytest.fixture(scope="module")
def rellis(tmp_path_factory):
    scan_path = need(RELLIS_SCAN)
    out = tmp_path_factory.mktemp("rellis")
    run_cli("detect", "--points", scan_path, "--sensor", "OS1-64", "--config", OS1_CONFIG,
            "--out", out)
    settings = cairn.load_settings(str(OS1_CONFIG))
    scan = np.fromfile(scan_path, np.float32).reshape(-1, 4)
    det = cairn.detect_points(scan, sensor="OS1-64", settings=settings)
    return out, scan, det


def test_rellis_point_labels_equal_the_cli(rellis):
    out, scan, det = rellis
    expected = np.fromfile(out / "labels.label", np.uint32)
    assert det.point_labels.dtype == np.uint32
    assert det.point_labels.shape == (scan.shape[0],)
    np.testing.assert_array_equal(det.point_labels, expected)
    np.testing.assert_array_equal(cairn.read_labels(str(out / "labels.label")), expected)
    assert (cairn.label_class(det.point_labels) == cairn.CLASS_KEPT).any()


def test_rellis_cells_equal_the_cli(rellis):
    out, _, det = rellis
    assert det.labels.shape == (64, 2048) and det.labels.dtype == np.int32
    np.testing.assert_array_equal(det.labels, cairn.read_segments_png(str(out / "segments.png")))
    np.testing.assert_array_equal(det.classes, cairn.read_classes_png(str(out / "classes.png")))


def test_rellis_segments_equal_segments_json(rellis):
    out, _, det = rellis
    doc = segments_doc(out / "segments.json")
    assert python_doc(det) == doc
    assert det.segments == doc["segments"]
    assert det.kept == doc["summary"]["kept"] and det.rejected == doc["summary"]["rejected"]
    assert det.kept > 0


def test_results_are_read_only_views(rellis):
    _, _, det = rellis
    labels = det.labels
    assert labels.base is not None  # shares the C++ result's memory
    with pytest.raises(ValueError):
        labels[0, 0] = 1
    del det  # the view keeps the result alive
    assert int(labels.max()) > 0


@pytest.mark.parametrize("method", ["cone", "column"])
def test_demo_depth_frame_equals_the_cli(tmp_path, method):
    depth_png, intrinsics_yaml = DEMO / "depth.png", DEMO / "intrinsics.yaml"
    run_cli("detect", "--depth", depth_png, "--intrinsics", intrinsics_yaml, "--method", method,
            "--out", tmp_path)
    intrinsics = cairn.load_intrinsics(str(intrinsics_yaml))
    depth = cairn.read_depth(str(depth_png), intrinsics)
    assert depth.shape == (480, 640) and depth.dtype == np.float32
    det = cairn.detect_depth(depth, fx=intrinsics.fx, fy=intrinsics.fy, cx=intrinsics.cx,
                             cy=intrinsics.cy, up=intrinsics.up, method=method)
    assert det.point_labels is None
    np.testing.assert_array_equal(det.labels, cairn.read_segments_png(str(tmp_path / "segments.png")))
    np.testing.assert_array_equal(det.classes, cairn.read_classes_png(str(tmp_path / "classes.png")))
    assert python_doc(det) == segments_doc(tmp_path / "segments.json")
    assert len(det.segments) > 0


def test_demo_without_rules_and_feet_equals_the_cli(tmp_path):
    depth_png, intrinsics_yaml = DEMO / "depth.png", DEMO / "intrinsics.yaml"
    run_cli("detect", "--depth", depth_png, "--intrinsics", intrinsics_yaml, "--no-rules",
            "--no-feet", "--out", tmp_path)
    intrinsics = cairn.load_intrinsics(str(intrinsics_yaml))
    depth = cairn.read_depth(str(depth_png), intrinsics)
    det = cairn.detect_depth(depth, fx=intrinsics.fx, fy=intrinsics.fy, cx=intrinsics.cx,
                             cy=intrinsics.cy, up=intrinsics.up, rules=False, feet=False)
    assert det.rejected == 0
    np.testing.assert_array_equal(det.labels, cairn.read_segments_png(str(tmp_path / "segments.png")))
    assert python_doc(det) == segments_doc(tmp_path / "segments.json")

"""Scores from Python equal `cairn eval --labels`: per-point TP, FP, FN, TN and per-class
tallies of the RELLIS-3D scan against its labels, for the cone detector and the column
baseline; each count is checked against a count made here in numpy from the outcome."""

import csv

import numpy as np
import pytest

import cairn
from conftest import DATASETS, REPO, RELLIS_SCAN, cli_error, need, run_cli

OS1_CONFIG = REPO / "config" / "sensors" / "os1-64.yaml"
CLASSES = REPO / "config" / "classes" / "rellis3d.yaml"
RELLIS_LABELS = DATASETS / "rellis3d-000104" / "os1_label" / "000104.label"

# Python's (method, rules) and the key of the same method in `cairn eval --methods`.
METHODS = {("cone", True): "cone_exact_rules", ("column", True): "column_rules",
           ("cone", False): "cone_exact"}


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    need(RELLIS_SCAN)
    need(RELLIS_LABELS)
    out = tmp_path_factory.mktemp("eval")
    run_cli("eval", "--points", RELLIS_SCAN, "--labels", RELLIS_LABELS, "--classes", CLASSES,
            "--sensor", "OS1-64", "--config", OS1_CONFIG, "--methods", ",".join(METHODS.values()),
            "--report", out)
    with open(out / "results.csv") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def scan_and_truth():
    scan = np.fromfile(need(RELLIS_SCAN), np.float32).reshape(-1, 4)
    truth = cairn.read_labels(str(need(RELLIS_LABELS)))
    return scan, truth


def ratio3(value):
    return "nan" if np.isnan(value) else f"{value:.3f}"


@pytest.mark.parametrize("method,rules", list(METHODS))
def test_scores_equal_cairn_eval(cli_results, scan_and_truth, method, rules):
    scan, truth = scan_and_truth
    settings = cairn.load_settings(str(OS1_CONFIG))
    det = cairn.detect_points(scan, sensor="OS1-64", settings=settings, method=method,
                              rules=rules)
    class_map = cairn.load_class_map(str(CLASSES))
    score = cairn.score_labels(class_map, truth, det.point_labels,
                               has_return=det.cell_of_point >= 0)
    key = METHODS[(method, rules)]
    rows = [r for r in cli_results if r["method"] == key]
    total = next(r for r in rows if r["scope"] == "all")
    for field in ("tp", "fp", "fn", "tn", "ignored", "no_return"):
        assert getattr(score, field) == int(total[field]), field
    for field in ("precision", "recall", "f1", "iou"):
        assert ratio3(getattr(score, field)) == total[field], field
    cli_classes = {int(r["class_id"]): r for r in rows if r["scope"] == "class"}
    py_classes = {c["id"]: c for c in score.per_class if c["returns"] > 0}
    assert set(py_classes) == set(cli_classes)
    for cid, c in py_classes.items():
        for field in ("returns", "detected", "rejected"):
            assert c[field] == int(cli_classes[cid][field]), (cid, field)
        assert c["name"] == cli_classes[cid]["class"] and c["role"] == cli_classes[cid]["role"]
    assert score.tp > 0


def test_outcome_counts_agree_with_the_definition(scan_and_truth):
    """The outcome per point follows the header's definition, recounted here in numpy."""
    scan, truth = scan_and_truth
    det = cairn.detect_points(scan, sensor="OS1-64",
                              settings=cairn.load_settings(str(OS1_CONFIG)))
    class_map = cairn.load_class_map(str(CLASSES))
    has_return = det.cell_of_point >= 0
    score = cairn.score_labels(class_map, truth, det.point_labels, has_return=has_return)
    roles = {c["id"]: c["role"] for c in class_map.classes}
    role = np.array([roles[int(i)] for i in (truth & 0xFFFF)])
    detected = cairn.label_class(det.point_labels) == cairn.CLASS_KEPT
    scored = has_return & (role != "ignored")
    obstacle = role == "obstacle"
    expected = {
        "tp": scored & detected & obstacle,
        "fp": scored & detected & ~obstacle,
        "fn": scored & ~detected & obstacle,
        "tn": scored & ~detected & ~obstacle,
    }
    codes = {"tp": cairn.OUTCOME_TP, "fp": cairn.OUTCOME_FP, "fn": cairn.OUTCOME_FN,
             "tn": cairn.OUTCOME_TN}
    for name, mask in expected.items():
        assert getattr(score, name) == int(mask.sum()), name
        np.testing.assert_array_equal(score.outcome == codes[name], mask)
    assert score.no_return == int((~has_return).sum())
    assert score.ignored == int((has_return & (role == "ignored")).sum())
    assert score.precision == pytest.approx(score.tp / (score.tp + score.fp))


def test_bad_class_map_and_labels_raise_the_cli_message(tmp_path, scan_and_truth):
    bad = tmp_path / "classes.yaml"
    bad.write_text("classes:\n  4: {name: tree, role: obstacel}\n")
    with pytest.raises(cairn.Error) as raised:
        cairn.load_class_map(str(bad))
    run = run_cli("eval", "--points", RELLIS_SCAN, "--labels", RELLIS_LABELS, "--classes", bad,
                  "--sensor", "OS1-64", "--report", tmp_path / "out", check=False)
    assert str(raised.value) == cli_error(run, "eval")

    scan, truth = scan_and_truth
    class_map = cairn.load_class_map(str(CLASSES))
    with pytest.raises(cairn.Error, match="truth"):
        cairn.score_labels(class_map, truth[:-1], np.zeros(truth.shape, np.uint32))
    unknown = truth.copy()
    unknown[7] = 999
    with pytest.raises(cairn.Error, match="999"):
        cairn.score_labels(class_map, unknown, np.zeros(truth.shape, np.uint32))

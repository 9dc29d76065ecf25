"""The `lfsam metrics` command: JSON scores of a result file against ground truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.io import write_lightfield
from lfsam.lightfield import LightField
from lfsam.result import SegmentationResult, save_result

# The hand-worked 1 x 3 case of tests/test_metrics.py: views of 1 x 6 pixels at disparity 1;
# label 1 = object, 2 = background.
ROWS = np.array([[2, 2, 2, 1, 1, 2], [2, 2, 1, 1, 2, 2], [2, 1, 1, 2, 2, 2]])
KEYS = {"siou", "lpp", "aa", "ue", "coverage", "ms_per_mask_view", "num_masks"}
KEYS |= {"recall", "siou_center", "view_iou", "view_iou_worst"}


def as_field(rows: np.ndarray) -> np.ndarray:
    return np.asarray(rows)[None, :, None, :].astype(np.int32)


@pytest.fixture
def gt_path(tmp_path):
    labels = as_field(ROWS)
    lf = LightField(
        np.zeros((*labels.shape, 3), np.uint8),
        disparity=np.ones(labels.shape, np.float32),
        labels=labels,
    )
    return write_lightfield(lf, tmp_path / "gt.npz")


def run_json(argv, capsys):
    status = main(argv)
    captured = capsys.readouterr()
    assert status == 0, captured.err
    return json.loads(captured.out)


def test_prints_the_metrics_of_a_saved_result(gt_path, tmp_path, capsys):
    # The object relabelled 3 in view 2 (derivation in tests/test_metrics.py):
    # SIoU (1 + 3/4 + 0) / 3, LPP 8/6, AA 1, UE 0, C 1; T = 1000 * 0.9 s / (3 labels * 3 views).
    pred = ROWS.copy()
    pred[2][pred[2] == 1] = 3
    result = SegmentationResult(labels=as_field(pred), timings={"total": 0.9})
    path = save_result(result, tmp_path / "result.npz")
    metrics = run_json(["metrics", str(path), "--gt", str(gt_path), "--device", "cpu"], capsys)
    assert set(metrics) == KEYS
    assert metrics["siou"] == pytest.approx(1.75 / 3)
    assert metrics["lpp"] == pytest.approx(8 / 6)
    assert metrics["aa"] == pytest.approx(1.0)
    assert metrics["ue"] == pytest.approx(0.0)
    assert metrics["coverage"] == pytest.approx(1.0)
    assert metrics["ms_per_mask_view"] == pytest.approx(100.0)
    assert metrics["num_masks"] == 3
    # Per-view IoU, objects matched in the center view: 1 -> object (IoU 1, 1, then 0 where it
    # became 3), 2 -> background (1 everywhere), 3 covers nothing there (0 in view 2 only):
    # views score 1, 1 and (0 + 1 + 0) / 3.
    assert metrics["view_iou"] == pytest.approx((1 + 1 + 1 / 3) / 3)
    assert metrics["view_iou_worst"] == pytest.approx(1 / 3)


def test_any_npz_with_labels_is_accepted_and_undefined_is_null(gt_path, tmp_path, capsys):
    # An empty labeling in a bare .npz: SIoU, LPP, AA undefined (null); UE 0; C 0; no timings.
    path = tmp_path / "bare.npz"
    np.savez(path, labels=np.zeros_like(as_field(ROWS)))
    metrics = run_json(["metrics", str(path), "--gt", str(gt_path), "--device", "cpu"], capsys)
    assert metrics["siou"] is None and metrics["lpp"] is None and metrics["aa"] is None
    assert metrics["ue"] == 0.0 and metrics["coverage"] == 0.0
    assert metrics["ms_per_mask_view"] is None


def test_user_errors_are_one_line(gt_path, tmp_path, capsys):
    labels = as_field(ROWS)
    bare = tmp_path / "bare.npz"
    np.savez(bare, labels=labels)
    no_truth = write_lightfield(
        LightField(np.zeros((*labels.shape, 3), np.uint8)), tmp_path / "views.npz"
    )
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, labels=labels[:, :2])
    cases = [
        (["metrics", str(bare), "--gt", str(no_truth)], "disparity for every view"),
        (["metrics", str(wrong), "--gt", str(gt_path)], "has (1, 3, 1, 6)"),
        (["metrics", str(tmp_path / "none.npz"), "--gt", str(gt_path)], "not found"),
    ]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("lfsam: error:") and message in err
        assert "Traceback" not in err and err.count("\n") == 1


def test_help_explains_every_metric(capsys):
    with pytest.raises(SystemExit):
        main(["metrics", "--help"])
    text = capsys.readouterr().out
    for word in ("siou", "lpp", "aa", "ue", "coverage", "ms_per_mask_view", "examples:"):
        assert word in text

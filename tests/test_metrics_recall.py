"""Object recall and SIoU over center-present masks (docs/design.md section 8), on hand-made fields.

A 1 x 3 light field (views t = 0, 1, 2; center t = 1) of 4 x 6 pixels, disparity 0 everywhere
(every view projects onto the center unchanged). Ground truth (0 = no ground truth):

- object 5 ("A"): rows 0-1, columns 0-1 in every view (4 pixels each);
- object 7 ("B"): hidden in the center; rows 2-3, columns 3-5 in view 0 (6 pixels, its largest
  view) and rows 2-3, columns 4-5 in view 2 (4 pixels);
- object 9 ("C"): one pixel, (0, 5) of view 2.

Every expected number is worked out by hand in the comments.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from lfsam.cli.main import main
from lfsam.io import write_lightfield
from lfsam.lightfield import LightField
from lfsam.metrics import METRICS, OBJECT_METRICS, REPORT_METRICS, evaluate_labels
from lfsam.metrics.labelmap import compact_labels
from lfsam.metrics.recall import default_min_area, object_recall
from lfsam.metrics.report import format_metrics_table
from lfsam.result import SegmentationResult, save_result


def truth() -> np.ndarray:
    gt = np.zeros((1, 3, 4, 6), np.int32)
    gt[0, :, 0:2, 0:2] = 5
    gt[0, 0, 2:4, 3:6] = 7
    gt[0, 2, 2:4, 4:6] = 7
    gt[0, 2, 0, 5] = 9
    return gt


def make_gt(labels: np.ndarray) -> LightField:
    views = np.zeros((*labels.shape, 3), np.uint8)
    return LightField(views, disparity=np.zeros(labels.shape, np.float32), labels=labels)


def score(pred: np.ndarray, **kwargs) -> dict:
    return evaluate_labels(pred, make_gt(truth()), device="cpu", **kwargs)


def test_perfect_prediction_recalls_every_object():
    # min_area 1: A, B and C count; each predicted exactly (IoU 1) in its largest view.
    assert score(truth(), min_area=1)["recall"] == 1.0
    # Any renumbering of the predicted labels scores the same.
    pred = truth()
    pred[pred == 5], pred[pred == 7], pred[pred == 9] = 42, 3, 1000
    assert score(pred, min_area=1)["recall"] == 1.0


def test_half_and_none():
    gt = truth()
    # min_area 2: C (1 pixel) does not count; A found, B missed: 1 / 2.
    pred = np.where(gt == 5, 1, 0).astype(np.int32)
    assert score(pred, min_area=2)["recall"] == 0.5
    # min_area 1: C counts and is missed too: 1 / 3.
    assert score(pred, min_area=1)["recall"] == pytest.approx(1 / 3)
    # Nothing predicted: 0 (not NaN: there are objects to find).
    assert score(np.zeros_like(gt), min_area=2)["recall"] == 0.0
    # min_area above every object's largest area (6): nothing counts, recall undefined.
    assert math.isnan(score(gt, min_area=7)["recall"])


def test_iou_threshold_is_inclusive_at_one_half():
    gt = truth()
    pred = np.zeros_like(gt)
    pred[gt == 5] = 1
    # In A's largest view, view 0 (all its views have 4 pixels: the first one wins), add 4
    # pixels outside A: IoU 4 / 8 = 0.5, recalled.
    pred[0, 0, 0:2, 2:4] = 1
    assert score(pred, min_area=2)["recall"] == 0.5
    # One pixel more: IoU 4 / 9 < 0.5, not recalled (B is missed as well): 0.
    pred[0, 0, 3, 0] = 1
    assert score(pred, min_area=2)["recall"] == 0.0


def test_objects_are_judged_in_their_largest_view():
    gt = truth()
    # B exactly in view 2 but not in view 0 (its largest): not recalled.
    only_view2 = np.where((gt == 7) & (np.arange(3)[None, :, None, None] == 2), 1, 0)
    assert score(only_view2.astype(np.int32), min_area=2)["recall"] == 0.0
    # B exactly in view 0 only: recalled although the center view never shows it.
    only_view0 = np.where((gt == 7) & (np.arange(3)[None, :, None, None] == 0), 1, 0)
    assert score(only_view0.astype(np.int32), min_area=2)["recall"] == 0.5
    # A has 4 pixels in every view: the first view (row-major) is its largest.
    a_not_view0 = np.where((gt == 5) & (np.arange(3)[None, :, None, None] > 0), 1, 0)
    assert score(a_not_view0.astype(np.int32), min_area=2)["recall"] == 0.0


def test_detail_per_object():
    pred = torch.from_numpy(np.where(truth() == 7, 0, truth()).astype(np.int32))
    p, p_ids = compact_labels(pred)
    g, g_ids = compact_labels(torch.from_numpy(truth()))
    detail = object_recall(p, g, len(p_ids), len(g_ids), min_area=1)
    assert g_ids.tolist() == [0, 5, 7, 9]
    np.testing.assert_array_equal(detail.counted, [False, True, True, True])
    np.testing.assert_array_equal(detail.recalled, [False, True, False, True])
    np.testing.assert_array_equal(detail.best_view[1:], [[0, 0], [0, 0], [0, 2]])
    np.testing.assert_allclose(detail.best_iou[1:], [1.0, 0.0, 1.0])
    assert detail.recall == pytest.approx(2 / 3)


def test_siou_scores_a_mask_absent_from_the_center_zero():
    # The ground truth as the prediction. With disparity 0 the projections are the masks:
    # A: IoU 1 in views 0 and 2 -> 1. B: no center pixel, IoU 0 in views 0 and 2 -> 0.
    # C: seen in view 2 only, not in the center: IoU 0 -> 0. SIoU = (1 + 0 + 0) / 3.
    result = score(truth(), min_area=1)
    assert result["siou"] == pytest.approx(1 / 3)
    # Over the masks present in the center view, only A: 1.
    assert result["siou_center"] == 1.0
    assert result["recall"] == 1.0


def test_siou_center_equals_siou_when_every_mask_is_in_the_center():
    gt = truth()
    pred = np.where(gt == 5, 1, 0).astype(np.int32)
    pred[0, 2, 0:2, 0:2] = 0
    pred[0, 2, 0:2, 1:3] = 1  # A moved by one column in view 2: IoU 2 / 6 there
    # A: (1 + 1/3) / 2 = 2/3 in both.
    result = score(pred, min_area=2)
    assert result["siou"] == pytest.approx(2 / 3)
    assert result["siou_center"] == pytest.approx(2 / 3)
    assert math.isnan(score(np.zeros_like(gt))["siou_center"])


def test_default_min_area_scales_with_the_view():
    assert default_min_area((240, 320)) == 77  # ceil(76.8)
    assert default_min_area((4, 6)) == 4
    # Default on the 4 x 6 field: 4 pixels, so C (1 pixel) does not count: A, B found: 1.
    pred = np.where(truth() == 9, 0, truth()).astype(np.int32)
    assert score(pred)["recall"] == 1.0


def test_reported_beside_the_paper_columns(tmp_path, capsys):
    assert REPORT_METRICS[: len(METRICS)] == METRICS
    assert [m.key for m in OBJECT_METRICS] == [
        "recall", "siou_center", "view_iou", "view_iou_worst"
    ]
    table = format_metrics_table(
        [("x", {"recall": 0.5, "siou_center": 1.0})], metrics=REPORT_METRICS
    )
    assert table.startswith(
        "| Method | SIoU↑ | LPP↓ | AA↑ | UE↓ | C↑ | T↓ | Recall↑ | SIoU(c)↑ | vIoU↑ | vIoU(min)↑ |"
    )
    gt = write_lightfield(make_gt(truth()), tmp_path / "gt.npz")
    pred = np.where(truth() == 7, 0, truth()).astype(np.int32)
    path = save_result(SegmentationResult(labels=pred), tmp_path / "r.npz")
    argv = ["metrics", str(path), "--gt", str(gt), "--device", "cpu"]
    assert main([*argv, "--min-area", "1"]) == 0
    # A and C found, B missed: 2 / 3.
    assert json.loads(capsys.readouterr().out)["recall"] == pytest.approx(2 / 3)
    assert main(argv) == 0  # default 4 pixels: C does not count, 1 / 2
    assert json.loads(capsys.readouterr().out)["recall"] == 0.5
    with pytest.raises(SystemExit):
        main([*argv, "--min-area", "0"])

"""Hand-worked cases for the paper's metrics (section 4.1): SIoU, LPP, AA, UE, C, T.

Every expected number below is derived on paper in the comments, from the definitions in
lfsam.metrics.consistency / segmentation / performance, never from running the code.

Most cases use a 1 x 3 light field (views t = 0, 1, 2; center t_c = 1) of 1 x 6 pixels with
disparity 1 everywhere. By the package convention a pixel at column v of view t lands in the
center view at column v + d (t - t_c): view 0 shifts left by 1, view 2 right by 1.

Ground truth (label 1 = object, 2 = background), columns 0..5:
    view 0: 2 2 2 1 1 2       (center pixel c is seen in view 0 at c + 1)
    view 1: 2 2 1 1 2 2       (center)
    view 2: 2 1 1 2 2 2       (center pixel c is seen in view 2 at c - 1)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.metrics import (
    consistency_metrics,
    evaluate_labels,
    evaluate_result,
)
from lfsam.metrics.labelmap import compact_labels
from lfsam.metrics.projection import project_view_to_center
from lfsam.result import PackedMasks, SegmentationResult

ROWS = np.array([[2, 2, 2, 1, 1, 2], [2, 2, 1, 1, 2, 2], [2, 1, 1, 2, 2, 2]])


def make_gt(labels: np.ndarray, disparity: np.ndarray | float = 1.0) -> LightField:
    """A light field with black views and the given per-view ground truth."""
    disp = np.broadcast_to(np.asarray(disparity, np.float32), labels.shape).copy()
    views = np.zeros((*labels.shape, 3), np.uint8)
    return LightField(views, disparity=disp, labels=labels)


def horizontal(rows: np.ndarray) -> np.ndarray:
    """Views t = 0..2 of a 1 x 3 grid, each 1 x V: shape (1, 3, 1, V)."""
    return np.asarray(rows)[None, :, None, :].copy()


def vertical(rows: np.ndarray) -> np.ndarray:
    """The same scene turned 90 degrees: a 3 x 1 grid of V x 1 views, shape (3, 1, V, 1)."""
    return np.asarray(rows)[:, None, :, None].copy()


@pytest.fixture(params=[horizontal, vertical], ids=["horizontal", "vertical"])
def layout(request):
    return request.param


def scores(pred_rows, layout, gt_rows=ROWS, disparity=1.0, **kwargs):
    gt = make_gt(layout(gt_rows), layout(np.broadcast_to(disparity, np.shape(gt_rows))))
    return evaluate_labels(layout(pred_rows), gt, device="cpu", **kwargs)


def test_ground_truth_scores(layout):
    # SIoU: object (label 1) projects from view 0 (cols 3,4 -> 2,3) and view 2 (cols 1,2 -> 2,3)
    # exactly onto the center's {2,3}: IoU 1 and 1 -> 1.
    # Background: view 0 cols {0,1,2,5} -> {-1 (out), 0, 1, 4}; center bg = {0,1,4,5};
    # IoU = |{0,1,4}| / |{0,1,4,5}| = 3/4. View 2 cols {0,3,4,5} -> {1,4,5,6 (out)}: IoU 3/4.
    # SIoU = (1 + 3/4) / 2 = 0.875 (the frame border keeps the ground truth below 1).
    # LPP: every center pixel receives only its own label -> 1. AA 1, UE 0, C 18/18 = 1.
    m = scores(ROWS, layout)
    assert m["siou"] == pytest.approx(0.875)
    assert m["lpp"] == pytest.approx(1.0)
    assert m["aa"] == pytest.approx(1.0)
    assert m["ue"] == pytest.approx(0.0)
    assert m["coverage"] == pytest.approx(1.0)
    assert m["ms_per_mask_view"] is None


def test_mask_missing_in_one_view(layout):
    # The object is left unlabeled in view 2: its mask is compared in view 0 only (IoU 1), so
    # SIoU = (1 + 3/4) / 2 = 0.875 still; LPP 1; AA over pixels labeled in both: all right -> 1;
    # UE 0; C = (18 - 2) / 18.
    pred = ROWS.copy()
    pred[2][pred[2] == 1] = 0
    m = scores(pred, layout)
    assert m["siou"] == pytest.approx(0.875)
    assert m["lpp"] == pytest.approx(1.0)
    assert m["aa"] == pytest.approx(1.0)
    assert m["ue"] == pytest.approx(0.0)
    assert m["coverage"] == pytest.approx(16 / 18)


def test_inconsistent_label_in_one_view(layout):
    # The object is labeled 3 in view 2. Masks: 1 (view 0 IoU 1 -> 1), 2 (3/4 as before),
    # 3 (absent from the center, appears in view 2 -> IoU 0 -> 0). SIoU = (1 + 0.75 + 0) / 3.
    # LPP: center pixels 2 and 3 receive {1, 3}, the other four {2}: (4*1 + 2*2) / 6 = 8/6.
    # AA: label 3 maps to ground truth 1 (2 shared pixels), all right -> 1. UE: region 1 is
    # covered by p=1 (4 pixels, none outside) and p=3 (2, none outside) -> 0; region 2 -> 0.
    pred = ROWS.copy()
    pred[2][pred[2] == 1] = 3
    m = scores(pred, layout)
    assert m["siou"] == pytest.approx((1 + 0.75 + 0) / 3)
    assert m["lpp"] == pytest.approx(8 / 6)
    assert m["aa"] == pytest.approx(1.0)
    assert m["ue"] == pytest.approx(0.0)


def test_split_region(layout):
    # The object's left column is label 1 and its right column label 4, consistently in every
    # view (center cols 2 | 3; view 0 cols 3 | 4; view 2 cols 1 | 2). Both halves project
    # exactly: scores 1 and 1; background 3/4. SIoU = (1 + 1 + 0.75) / 3 = 2.75 / 3.
    # AA: 1 -> object, 4 -> object, 2 -> background: all right -> 1. UE: each half lies inside
    # the object (|p \ g| = 0) -> 0. A split costs nothing in AA and UE.
    pred = np.array([[2, 2, 2, 1, 4, 2], [2, 2, 1, 4, 2, 2], [2, 1, 4, 2, 2, 2]])
    m = scores(pred, layout)
    assert m["siou"] == pytest.approx(2.75 / 3)
    assert m["lpp"] == pytest.approx(1.0)
    assert m["aa"] == pytest.approx(1.0)
    assert m["ue"] == pytest.approx(0.0)


def test_merged_regions(layout):
    # One label over everything. SIoU: view 0 cols 0..5 -> -1..4 -> {0..4}: IoU 5/6; view 2 ->
    # {1..5}: 5/6 -> SIoU 5/6. LPP 1. AA: label 1 shares 6 pixels with the object and 12 with
    # the background -> mapped to the background: 12 of 18 right -> 2/3.
    # UE: object |g| = 6: min(|p∩g| = 6, |p\g| = 12) = 6 -> 6/6 = 1; background |g| = 12:
    # min(12, 6) = 6 -> 6/12 = 0.5. UE = (1 + 0.5) / 2 = 0.75.
    m = scores(np.ones_like(ROWS), layout)
    assert m["siou"] == pytest.approx(5 / 6)
    assert m["lpp"] == pytest.approx(1.0)
    assert m["aa"] == pytest.approx(2 / 3)
    assert m["ue"] == pytest.approx(0.75)
    assert m["coverage"] == pytest.approx(1.0)


def test_leak_onto_pixels_without_ground_truth():
    # Ground truth labels only the object (background 0 = no label). The prediction labels the
    # object plus one background pixel per view as 1. AA counts pixels labeled in both: the 6
    # object pixels, all right -> 1. UE: object |g| = 6, p = 1 has |p∩g| = 6 and |p\g| = 3
    # (the leaked pixels, though unlabeled in the truth) -> min = 3 -> 3/6 = 0.5.
    gt = np.where(ROWS == 1, 1, 0)
    pred = gt.copy()
    pred[:, 0] = 1
    m = scores(pred, horizontal, gt_rows=gt)
    assert m["aa"] == pytest.approx(1.0)
    assert m["ue"] == pytest.approx(0.5)
    assert m["coverage"] == pytest.approx(9 / 18)


def test_empty_prediction(layout):
    # No masks: SIoU, LPP and AA have nothing to average (NaN); no predicted segment leaks, so
    # UE = (0/6 + 0/12) / 2 = 0; C = 0; T undefined without masks.
    m = scores(np.zeros_like(ROWS), layout, timings={"total": 1.0})
    assert math.isnan(m["siou"]) and math.isnan(m["lpp"]) and math.isnan(m["aa"])
    assert m["ue"] == 0.0
    assert m["coverage"] == 0.0
    assert m["ms_per_mask_view"] is None


def test_mask_projecting_out_of_frame(layout):
    # Label 5 only at column 0 of view 0, which lands at column -1: outside the center frame.
    # Its projected masks are all empty, so it has nothing to compare and is left out of SIoU:
    # SIoU stays (1 + 3/4) / 2 = 0.875 and LPP stays 1 (no center pixel receives label 5).
    # AA: 5 maps to the background it covers -> still 1. C unchanged at 1.
    pred = ROWS.copy()
    pred[0, 0] = 5
    m = scores(pred, layout)
    assert m["siou"] == pytest.approx(0.875)
    assert m["lpp"] == pytest.approx(1.0)
    assert m["aa"] == pytest.approx(1.0)
    assert m["coverage"] == pytest.approx(1.0)


@pytest.mark.parametrize("dense_limit", [1 << 28, 0], ids=["dense", "merged"])
def test_occlusion_with_per_pixel_disparity(dense_limit):
    # 1 x 3 views of 8 columns. Background (label 2) at disparity 0, object (label 1) at
    # disparity 1 on center columns 3, 4. View 0 sees the object at columns 4, 5 and the
    # background at 0..3, 6, 7 (its column 3 is background hidden in the center); view 2 sees
    # the object at 2, 3 and the background at 0, 1, 4..7.
    # Projection: background stays put; object pixels move by d (t - t_c): view 0 {4,5} -> {3,4},
    # view 2 {2,3} -> {3,4}.
    # LPP: center 3 receives 1 (center, view 0, view 2) and 2 (view 0's background column 3);
    # center 4 receives 1 and 2 (view 2's column 4): (6*1 + 2*2) / 8 = 10/8.
    # SIoU: object 1 and 1 -> 1. Background: center {0,1,2,5,6,7}; view 0 {0,1,2,3,6,7}:
    # 5/7; view 2 {0,1,4,5,6,7}: 5/7 -> 5/7. SIoU = (1 + 5/7) / 2 = 6/7.
    labels = np.array(
        [[2, 2, 2, 2, 1, 1, 2, 2], [2, 2, 2, 1, 1, 2, 2, 2], [2, 2, 1, 1, 2, 2, 2, 2]]
    )
    disparity = (labels == 1).astype(np.float32)
    lab = torch.from_numpy(horizontal(labels)).long()
    disp = torch.from_numpy(horizontal(disparity))
    result = consistency_metrics(lab, disp, 3, dense_limit=dense_limit)
    assert result.lpp == pytest.approx(10 / 8)
    assert result.siou == pytest.approx(6 / 7)
    assert result.mask_siou[1] == pytest.approx(1.0)
    assert result.mask_siou[2] == pytest.approx(5 / 7)
    assert result.mask_views.tolist() == [0, 2, 2]


def test_batching_and_lpp_strategy_do_not_change_results():
    # Projecting one view at a time or all at once, and counting LPP with the dense table or by
    # merging sorted pairs, are implementation choices: the numbers must agree (up to the order
    # of floating-point sums).
    rng = np.random.default_rng(7)
    labels = torch.from_numpy(rng.integers(0, 6, (3, 3, 8, 10)))
    disparity = torch.from_numpy(rng.uniform(-2, 2, (3, 3, 8, 10)).astype(np.float32))
    reference = consistency_metrics(labels, disparity, 6)
    for batch_pixels, dense_limit in [(1, 1 << 28), (160, 0), (1 << 21, 0)]:
        other = consistency_metrics(labels, disparity, 6, dense_limit, batch_pixels)
        assert other.siou == pytest.approx(reference.siou, rel=1e-12)
        assert other.lpp == reference.lpp
        np.testing.assert_allclose(other.mask_siou, reference.mask_siou, rtol=1e-12)


def test_projection_rounds_to_nearest_and_drops_nan():
    # View offset dt = +1 lands column v at v + d. d = 0.4 at column 1 -> 1.4 -> 1;
    # d = 0.6 at column 2 -> 2.6 -> 3; d = 0.5 at column 0 -> 0.5 -> 1 (halves round up);
    # NaN disparity at column 3 is dropped. Pairs sorted by pixel then label.
    labels = torch.tensor([[1, 2, 3, 4]])
    disparity = torch.tensor([[0.5, 0.4, 0.6, float("nan")]])
    pixels, labs = project_view_to_center(labels, disparity, 0, 1, 5)
    assert pixels.tolist() == [1, 1, 3]
    assert labs.tolist() == [1, 2, 3]


def test_two_dimensional_grid_uses_both_axes():
    # 3 x 3 views of 4 x 4 pixels, disparity 1: a one-pixel object at center (1, 1) is seen in
    # view (s, t) at (1 - (s - 1), 1 - (t - 1)), i.e. rows/cols 2, 1, 0 as s, t = 0, 1, 2.
    # Drawn there in every view it projects back onto (1, 1): SIoU 1 for the object mask.
    labels = np.zeros((3, 3, 4, 4), np.int32)
    for s in range(3):
        for t in range(3):
            labels[s, t, 2 - s, 2 - t] = 1
    gt = make_gt(labels, 1.0)
    m = evaluate_labels(labels, gt, device="cpu")
    assert m["siou"] == pytest.approx(1.0)
    assert m["lpp"] == pytest.approx(1.0)
    # Drawn with the opposite sign (at (s, t) in view (s, t)) it projects to
    # (s + (s - 1), t + (t - 1)) = (2s - 1, 2t - 1): out of frame when s = 0 or t = 0, and at
    # (1, 3), (3, 1), (3, 3) from views (1, 2), (2, 1), (2, 2): IoU 0 in each -> SIoU 0.
    flipped = np.zeros_like(labels)
    for s in range(3):
        for t in range(3):
            flipped[s, t, s, t] = 1
    assert evaluate_labels(flipped, make_gt(flipped, 1.0), device="cpu")["siou"] == 0.0


def test_time_per_mask_per_view():
    # 2 masks, 1 x 3 views, 0.9 s: 1000 * 0.9 / (2 * 3) = 150 ms.
    m = scores(ROWS, horizontal, timings={"total": 0.9})
    assert m["ms_per_mask_view"] == pytest.approx(150.0)
    # A labels-only result with ids {2, 5}: N = 2 distinct labels, not the largest id 5:
    # 1000 * 0.3 / (2 * 3) = 50 ms.
    labels = horizontal(np.where(ROWS == 1, 5, 2))
    result = SegmentationResult(labels=labels, timings={"total": 0.3})
    m = evaluate_result(result, make_gt(horizontal(ROWS)), device="cpu")
    assert m["ms_per_mask_view"] == pytest.approx(50.0)
    assert m["num_masks"] == 2
    # With 3 stored masks (one hidden under the others in the label field), N = 3:
    # 1000 * 0.3 / (3 * 3) = 33.3 ms.
    result.masks = PackedMasks((3, *labels.shape))
    m = evaluate_result(result, make_gt(horizontal(ROWS)), device="cpu")
    assert m["ms_per_mask_view"] == pytest.approx(1000 * 0.3 / 9)


def test_compact_labels_keeps_zero_and_order():
    for big in (7, 1 << 30):  # lookup-table path and sorting path
        labels = torch.tensor([[0, big, 3], [3, 0, big]])
        compact, ids = compact_labels(labels)
        assert ids.tolist() == [0, 3, big]
        assert compact.tolist() == [[0, 2, 1], [1, 0, 2]]
    compact, ids = compact_labels(torch.tensor([4, 4]))
    assert ids.tolist() == [0, 4] and compact.tolist() == [1, 1]


def test_errors_name_the_problem():
    labels = horizontal(ROWS)
    views = np.zeros((*labels.shape, 3), np.uint8)
    center_only = LightField(views, disparity=np.ones((1, 6), np.float32), labels=labels)
    with pytest.raises(LfsamError, match="disparity for every view"):
        evaluate_labels(labels, center_only)
    no_labels = LightField(views, disparity=np.ones(labels.shape, np.float32))
    with pytest.raises(LfsamError, match="labels for every view"):
        evaluate_labels(labels, no_labels)
    with pytest.raises(LfsamError, match="shape"):
        evaluate_labels(labels[:, :2], make_gt(labels))
    with pytest.raises(LfsamError, match=">= 0"):
        evaluate_labels(-labels, make_gt(labels))
    with pytest.raises(LfsamError, match="integers"):
        evaluate_labels(labels.astype(np.float32), make_gt(labels))


@pytest.mark.cuda
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_matches_cpu():
    rng = np.random.default_rng(3)
    labels = rng.integers(0, 6, (3, 3, 32, 48)).astype(np.int32)
    truth = rng.integers(0, 4, (3, 3, 32, 48)).astype(np.int32)
    disparity = rng.uniform(-2, 2, (3, 3, 32, 48)).astype(np.float32)
    gt = make_gt(truth, disparity)
    cpu = evaluate_labels(labels, gt, device="cpu")
    gpu = evaluate_labels(labels, gt, device="cuda")
    assert gpu == pytest.approx(cpu, nan_ok=True)

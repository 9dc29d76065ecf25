"""Per-view IoU against ground truth (lfsam.metrics.accuracy; docs/design.md section 5)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.metrics.accuracy import per_view_iou
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(3, 3), size=(40, 56), seed=2, num_objects=3,
                          label_background=False)


def test_ground_truth_scores_one_in_every_view_whatever_the_ids(scene):
    renumbered = np.where(scene.labels > 0, scene.labels + 10, 0)
    acc = per_view_iou(renumbered, scene.labels)
    assert acc.mean == 1.0 and acc.worst == 1.0
    assert acc.matched == {int(i) + 10: int(i) for i in np.unique(scene.labels) if i}


def test_a_wrong_view_lowers_the_worst_view_by_its_iou(scene):
    pred = scene.labels.copy()
    obj = int(np.unique(scene.labels[1, 1])[1])
    pred[0, 0][pred[0, 0] == obj] = 0  # the object missed entirely in one view
    acc = per_view_iou(pred, scene.labels)
    assert acc.per_object[obj][0, 0] == 0.0  # counted (the object is in the ground truth)
    others = [v[0, 0] for i, v in acc.per_object.items() if i != obj and np.isfinite(v[0, 0])]
    assert acc.per_view[0, 0] == pytest.approx(np.mean([0.0, *others]))
    assert acc.worst == acc.per_view[0, 0] < 1.0
    assert acc.per_view[1, 1] == 1.0


def test_objects_match_in_their_reference_view_and_absent_views_are_left_out(scene):
    gt = np.zeros_like(scene.labels)
    gt[0, 0, 5:10, 5:10] = 4  # an object only the corner view shows
    gt[1, 1, 20:30, 20:30] = 9
    pred = np.zeros_like(gt)
    pred[0, 0, 5:10, 5:12] = 1  # 25 of 35 pixels right
    pred[1, 1, 20:30, 20:30] = 1  # ... and the same id on another object in the center
    present = np.ones((3, 3), bool)
    present[2, 2] = False
    acc = per_view_iou(pred, gt, reference_views={1: (0, 0)}, present=present)
    assert acc.matched == {1: 4}
    assert acc.per_object[1][0, 0] == pytest.approx(25 / 35)
    assert acc.per_object[1][1, 1] == 0.0  # not its object there
    assert np.isnan(acc.per_view[2, 2]) and np.isnan(acc.per_view[0, 1])  # absent; nothing
    assert acc.matched == per_view_iou(pred, gt, {1: (0, 0)}).matched
    assert per_view_iou(pred, gt).matched == {1: 9}  # from the center, the other object


def test_mismatched_shapes_are_the_callers_error(scene):
    with pytest.raises(ValueError, match="must both be"):
        per_view_iou(scene.labels[:, :, :10], scene.labels)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_matches_a_per_object_brute_force(seed):
    rng = np.random.default_rng(seed)
    gt = rng.integers(0, 4, size=(2, 3, 6, 7))
    pred = rng.integers(0, 4, size=(2, 3, 6, 7))
    refs = {int(i): (int(rng.integers(2)), int(rng.integers(3))) for i in range(1, 4)}
    acc = per_view_iou(pred, gt, refs)
    for obj, iou in acc.per_object.items():
        s, t = refs[obj]
        under = gt[s, t][pred[s, t] == obj]
        counts = np.bincount(under, minlength=4)[1:]

        def ious(label, obj=obj):
            out = np.full((2, 3), np.nan)
            for v in np.ndindex(2, 3):
                p = pred[v] == obj
                g = (gt[v] == label) if label else np.zeros_like(p)
                union = (p | g).sum()
                out[v] = np.nan if union == 0 else (p & g).sum() / union
            return out

        def rank(label, ious=ious):  # ties: best mean IoU, then the IoUs view by view
            values = ious(label)
            finite = values[np.isfinite(values)]
            mean = finite.mean() if finite.size else -1.0
            return (mean, tuple(np.nan_to_num(values.ravel(), nan=-1.0)))

        tied = [int(g) + 1 for g in np.flatnonzero(counts == counts.max())]
        expect = 0 if counts.max() == 0 else max(tied, key=rank)
        assert acc.matched[obj] == expect
        assert np.allclose(iou, ious(expect), equal_nan=True)
        assert np.all(np.isnan(iou) | ((iou >= 0.0) & (iou <= 1.0)))

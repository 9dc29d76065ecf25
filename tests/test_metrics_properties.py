"""Property tests of the paper's metrics (hypothesis): what must hold for every label field."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from lfsam.lightfield import LightField
from lfsam.metrics import evaluate_labels

SETTINGS = settings(max_examples=25, deadline=None)

grids = st.sampled_from([(1, 3), (3, 1), (3, 3), (2, 3)])


def make_gt(labels: np.ndarray, disparity: np.ndarray) -> LightField:
    views = np.zeros((*labels.shape, 3), np.uint8)
    return LightField(views, disparity=disparity.astype(np.float32), labels=labels)


@st.composite
def label_fields(draw, max_label: int = 5):
    """Random labels and disparity on a small grid: (labels, disparity)."""
    s, t = draw(grids)
    u = draw(st.integers(2, 6))
    v = draw(st.integers(2, 7))
    labels = draw(arrays(np.int32, (s, t, u, v), elements=st.integers(0, max_label)))
    disparity = draw(
        arrays(np.float32, (s, t, u, v), elements=st.floats(-2.0, 2.0, width=32))
    )
    return labels, disparity


@st.composite
def plane_scenes(draw):
    """A fronto-parallel plane at integer disparity d, drawn in every view by the convention.

    View (s, t) shows at (u, v) the center pixel (u + d ds, v + d dt) (inverse of the mapping
    of docs/design.md section 1), or 0 where that falls outside the center frame.
    """
    s_count, t_count = draw(grids)
    u = draw(st.integers(3, 7))
    v = draw(st.integers(3, 7))
    d = draw(st.integers(-1, 1))
    center = draw(arrays(np.int32, (u, v), elements=st.integers(1, 4)))
    labels = np.zeros((s_count, t_count, u, v), np.int32)
    s_c, t_c = s_count // 2, t_count // 2
    rows, cols = np.arange(u)[:, None], np.arange(v)[None, :]
    for s in range(s_count):
        for t in range(t_count):
            src_r = rows + d * (s - s_c) + 0 * cols
            src_c = cols + d * (t - t_c) + 0 * rows
            ok = (src_r >= 0) & (src_r < u) & (src_c >= 0) & (src_c < v)
            labels[s, t][ok] = center[src_r[ok], src_c[ok]]
    disparity = np.full(labels.shape, float(d), np.float32)
    return labels, disparity


def same(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is b
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


@SETTINGS
@given(label_fields())
def test_ground_truth_has_perfect_aa_and_no_undersegmentation(field):
    labels, disparity = field
    m = evaluate_labels(labels, make_gt(labels, disparity), device="cpu")
    if labels.any():
        assert m["aa"] == pytest.approx(1.0)
        assert m["ue"] == pytest.approx(0.0, abs=1e-12)
    else:
        assert math.isnan(m["aa"]) and math.isnan(m["ue"])


@SETTINGS
@given(plane_scenes(), st.data())
def test_inconsistent_relabelling_lowers_siou_and_raises_lpp(scene, data):
    labels, disparity = scene
    gt = make_gt(labels, disparity)
    s_count, t_count = labels.shape[:2]
    center = (s_count // 2, t_count // 2)
    others = [(s, t) for s in range(s_count) for t in range(t_count) if (s, t) != center]
    view = data.draw(st.sampled_from(others))
    present = sorted(set(np.unique(labels[view]).tolist()) - {0})
    assume(len(present) >= 2)
    a, b = data.draw(st.permutations(present))[:2]
    before = evaluate_labels(labels, gt, device="cpu")
    assert before["lpp"] == pytest.approx(1.0)  # a consistent labelling: one label per point
    swapped = labels.copy()
    swapped[view][labels[view] == a] = b
    swapped[view][labels[view] == b] = a
    after = evaluate_labels(swapped, gt, device="cpu")
    assert after["siou"] < before["siou"]
    assert after["lpp"] > before["lpp"]


@SETTINGS
@given(label_fields(), st.data())
def test_metrics_are_invariant_to_renumbering_labels(gt_field, data):
    truth, disparity = gt_field
    pred = data.draw(arrays(np.int32, truth.shape, elements=st.integers(0, 6)))
    count = int(pred.max()) + 1
    ids = data.draw(st.lists(st.integers(1, 2**40), min_size=count, max_size=count, unique=True))
    lut = np.array([0, *ids[1:]], dtype=np.int64)  # any injective renumbering keeping 0
    gt_ids = data.draw(st.permutations(range(1, int(truth.max()) + 2)))
    gt_lut = np.array([0, *gt_ids], dtype=np.int32)
    timings = {"total": 2.0}
    base = evaluate_labels(pred, make_gt(truth, disparity), timings, device="cpu")
    renamed = evaluate_labels(
        lut[pred], make_gt(gt_lut[truth], disparity), timings, device="cpu"
    )
    for key, value in base.items():
        assert same(value, renamed[key]), key

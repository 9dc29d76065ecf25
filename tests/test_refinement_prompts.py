"""Refinement prompts: box of surviving pixels and the nearest pixel to the weighted centroid."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.pipeline.occlusion import OcclusionWeights, uniform_weights
from lfsam.pipeline.refinement import mask_iou, refinement_prompts


def test_box_and_point_of_a_ring_lie_on_the_ring():
    # A ring's centroid is its hole; the point must be a ring pixel nearest to it.
    mask = torch.zeros((1, 11, 11), dtype=torch.bool)
    mask[0, 2:9, 2:9] = True
    mask[0, 4:7, 4:7] = False
    prompts, prompted = refinement_prompts(uniform_weights(mask))
    assert prompted.tolist() == [True]
    np.testing.assert_array_equal(prompts.boxes[0], [2, 2, 8, 8])  # x0, y0, x1, y1
    x, y = prompts.points[0, 0]
    assert mask[0, int(y), int(x)]
    assert (x - 5) ** 2 + (y - 5) ** 2 == 4.0  # nearest ring pixels are 2 px from (5, 5)
    assert prompts.point_labels.tolist() == [[1]]


def test_weights_pull_the_point_and_dropped_pixels_leave_the_box():
    # Two blobs; the right one has weight 0.9, the left 0.75, a far pixel is dropped (0).
    pixel = torch.tensor([0 * 20 + 2, 0 * 20 + 3, 0 * 20 + 15, 0 * 20 + 16, 0 * 20 + 19])
    weight = torch.tensor([0.75, 0.75, 0.9, 0.9, 0.0])
    w = OcclusionWeights(
        mask_index=torch.zeros(5, dtype=torch.long), pixel_index=pixel, weight=weight,
        num_masks=2, view_size=(1, 20),
    )
    prompts, prompted = refinement_prompts(w)
    assert prompted.tolist() == [True, False]  # mask 1 has no pixels: no prompt
    assert prompts.boxes[0].tolist() == [2, 0, 16, 0]
    # Weighted centroid column = (0.75*5 + 0.9*31) / 3.3 = 9.59; nearest pixel is column 15.
    assert prompts.points[0, 0].tolist() == [15.0, 0.0]


def test_mask_iou():
    a = torch.zeros((1, 2, 4, 4), dtype=torch.bool)
    a[0, 0, :2] = True  # 8 px
    ref = torch.zeros((1, 4, 4), dtype=torch.bool)
    ref[0, 1:3] = True  # 8 px, 4 shared
    iou = mask_iou(a, ref)
    assert abs(iou[0, 0].item() - 4 / 12) < 1e-6
    assert iou[0, 1].item() == 0.0


def test_box_reaching_an_unseen_frame_strip_extends_to_the_frame_edge():
    from lfsam.pipeline.propagation import forward_warp

    # Constant disparity 2, view one step right (dt = 1): everything moves 2 px left, so the
    # two rightmost columns show content the center view never saw.
    disp = torch.full((10, 20), 2.0)
    warp = forward_warp(disp, 0, 1)
    runs = warp.frame_runs((10, 20))
    assert runs.right.tolist() == [2] * 10 and runs.left.tolist() == [0] * 10
    assert runs.top.tolist() == [0] * 18 + [10, 10]
    seen = warp.seen((10, 20))
    assert not bool(seen[:, 18:].any()) and bool(seen[:, :18].all())
    mask = torch.zeros((2, 10, 20), dtype=torch.bool)
    mask[0, 2:6, 10:18] = True  # reaches the unseen strip: extended to column 19
    mask[1, 2:6, 3:9] = True  # far from it: unchanged
    prompts, _ = refinement_prompts(uniform_weights(mask), runs)
    assert prompts.boxes.tolist() == [[10, 2, 19, 5], [3, 2, 8, 5]]
    # IoU is measured where the propagation reaches: the strip does not count.
    candidate = torch.zeros((1, 1, 10, 20), dtype=torch.bool)
    candidate[0, 0, 2:6, 10:20] = True
    assert mask_iou(candidate, mask[:1], seen)[0, 0].item() == 1.0
    assert mask_iou(candidate, mask[:1])[0, 0].item() < 1.0


def test_mask_iou_matches_a_dense_reference_computation():
    rng = np.random.default_rng(7)
    cand = torch.as_tensor(rng.random((5, 3, 9, 11)) > 0.5)
    ref = torch.as_tensor(rng.random((5, 9, 11)) > 0.6)
    region = torch.as_tensor(rng.random((9, 11)) > 0.2)
    for reg in (None, region):
        c = cand if reg is None else cand & reg
        r = ref if reg is None else ref & reg
        inter = (c & r[:, None]).sum((-1, -2)).float()
        union = (c | r[:, None]).sum((-1, -2)).float()
        expected = inter / union.clamp(min=1)
        assert torch.allclose(mask_iou(cand, ref, reg), expected)


def test_chunked_refinement_equals_one_batch():
    from lfsam.pipeline.refinement import refine_masks
    from lfsam.segmenters import load_segmenter
    from lfsam.synth import generate_scene

    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=1, num_objects=4)
    segmenter = load_segmenter("oracle", lightfield=lf)
    embedding = segmenter.encode(lf.views[0, 0][None], keys=[(0, 0)])[0]
    ids = np.unique(lf.labels[1, 1])[1:]
    coarse = torch.as_tensor(np.stack([lf.labels[1, 1] == k for k in ids]))  # center masks
    weights = uniform_weights(coarse)
    one = refine_masks(segmenter, embedding, coarse, weights, chunk_size=64)
    many = refine_masks(segmenter, embedding, coarse, weights, chunk_size=1)
    assert torch.equal(one.masks, many.masks) and torch.equal(one.fallback, many.fallback)
    assert torch.allclose(one.iou, many.iou, equal_nan=True)


@pytest.mark.parametrize("skips_absent", [False, True])
def test_groups_of_carried_clicks_are_chosen_among_once_per_view(monkeypatch, skips_absent):
    """Prompts with different numbers of carried clicks are decoded apart (one call per group),
    or, by a segmenter that skips absent points, padded with them in one call; either way
    chosen among together (docs/design.md section 3.5): one choice per view, with the outcome
    of refining each mask alone."""
    from lfsam.pipeline import refinement
    from lfsam.segmenters import load_segmenter
    from lfsam.synth import generate_scene

    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=1, num_objects=4)
    segmenter = load_segmenter("oracle", lightfield=lf)
    embedding = segmenter.encode(lf.views[0, 0][None], keys=[(0, 0)])[0]
    ids = np.unique(lf.labels[1, 1])[1:]
    coarse = torch.as_tensor(np.stack([lf.labels[1, 1] == k for k in ids]))
    weights = uniform_weights(coarse)
    n = len(ids)
    # Mask k carries k % 3 clicks of its own (0, 1 or 2), padded with label -1.
    points = np.zeros((n, 2, 2), np.float32)
    labels = np.full((n, 2), -1, np.int64)
    for k in range(n):
        rows, cols = np.nonzero(coarse[k].numpy())
        for j in range(k % 3):
            points[k, j] = (cols[j], rows[j])
            labels[k, j] = 1
    assert len(set((labels != -1).sum(1).tolist())) == 3  # three groups

    calls = {"decode": 0, "choose": 0}
    predict, choose = segmenter.predict, refinement._choose

    def counted_predict(*args, **kwargs):
        calls["decode"] += 1
        return predict(*args, **kwargs)

    def counted_choose(*args, **kwargs):
        calls["choose"] += 1
        return choose(*args, **kwargs)

    monkeypatch.setattr(segmenter, "predict", counted_predict)
    monkeypatch.setattr(segmenter, "skips_absent_points", skips_absent)
    monkeypatch.setattr(refinement, "_choose", counted_choose)
    together = refinement.refine_masks(segmenter, embedding, coarse, weights,
                                       extra_points=(points, labels))
    assert calls == {"decode": 1 if skips_absent else 3, "choose": 1}
    for k in range(n):  # each mask refined alone
        alone = refinement.refine_masks(segmenter, embedding, coarse[k : k + 1],
                                        uniform_weights(coarse[k : k + 1]),
                                        extra_points=(points[k : k + 1], labels[k : k + 1]))
        assert torch.equal(together.masks[k], alone.masks[0])
        assert together.fallback[k] == alone.fallback[0]
        assert torch.allclose(together.iou[k : k + 1], alone.iou, equal_nan=True)

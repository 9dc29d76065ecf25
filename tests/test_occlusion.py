"""Semantic occluding (pipeline.occlusion): source features, similarities and the threshold."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from lfsam.lightfield import LightField
from lfsam.pipeline.occlusion import semantic_occlusion, source_features, uniform_weights
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.base import Segmenter

U, V = 12, 16


def _oracle_setup():
    labels = np.zeros((1, 2, U, V), np.int32)
    labels[0, 0, 2:8, 2:8] = 1
    labels[0, 0, 2:8, 9:14] = 2
    labels[0, 1] = labels[0, 0]
    labels[0, 1, 4:8, 5:11] = 2  # in the second view object 2 moved over part of object 1
    lf = LightField(views=np.zeros((1, 2, U, V, 3), np.uint8), labels=labels)
    oracle = load_segmenter("oracle", lightfield=lf, device="cpu")
    center, other = oracle.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    return lf, oracle, center, other


def test_oracle_similarity_keeps_exactly_the_source_label():
    lf, oracle, center, other = _oracle_setup()
    masks = torch.from_numpy(np.stack([lf.labels[0, 0] == 1, lf.labels[0, 0] == 2]))
    sources = source_features(oracle, center, masks)
    assert torch.allclose(sources.norm(dim=1), torch.ones(2))
    weights = semantic_occlusion(oracle, other, masks, sources, t_sim=0.7)
    kept = weights.surviving_masks().numpy()
    np.testing.assert_array_equal(kept[0], masks[0].numpy() & (lf.labels[0, 1] == 1))
    np.testing.assert_array_equal(kept[1], masks[1].numpy() & (lf.labels[0, 1] == 2))
    assert set(np.unique(weights.weight.numpy())) <= {0.0, 1.0}


def test_threshold_and_weights_follow_the_similarity():
    lf, oracle, center, other = _oracle_setup()
    masks = torch.from_numpy((lf.labels[0, 0] == 1)[None])
    sources = source_features(oracle, center, masks)
    # a mixed source (half label 1, half label 2) has similarity 1/sqrt(2) to either label
    mixed = F.normalize(sources + source_features(
        oracle, center, torch.from_numpy((lf.labels[0, 0] == 2)[None])), dim=1)
    for t_sim, survives in ((0.7, True), (0.71, False)):
        weights = semantic_occlusion(oracle, other, masks, mixed, t_sim=t_sim)
        assert bool((weights.weight > 0).any()) == survives
    weights = semantic_occlusion(oracle, other, masks, mixed, t_sim=0.5)
    kept = weights.weight[weights.weight > 0]
    assert torch.allclose(kept, torch.full_like(kept, 2**-0.5), atol=1e-6)


def test_uniform_weights_keep_every_pixel():
    masks = torch.zeros(2, U, V, dtype=torch.bool)
    masks[0, 1:3, 1:4] = True
    masks[1, 5, 5] = True
    weights = uniform_weights(masks)
    assert torch.equal(weights.surviving_masks(), masks)
    assert torch.equal(weights.weight, torch.ones(7))


@pytest.fixture(scope="module")
def tiny_sam2():
    seg = load_segmenter("sam2-tiny-test", device="cpu")
    rng = np.random.default_rng(3)
    views = rng.integers(0, 256, size=(2, 37, 53, 3), dtype=np.uint8)
    return seg, seg.encode(views, keys=[(0, 0), (0, 1)])


def test_sam2_feature_shortcuts_equal_the_sampled_features(tiny_sam2):
    """The SAM 2 backend's exact grid shortcuts agree with per-pixel sampled features."""
    seg, (center, other) = tiny_sam2
    rng = np.random.default_rng(4)
    masks = torch.from_numpy(rng.random((3, 37, 53)) < 0.3)
    mask_index, pixel_index = torch.nonzero(masks.reshape(3, -1), as_tuple=True)
    fast = seg.feature_sums(center, mask_index, pixel_index, 3)
    slow = Segmenter.feature_sums(seg, center, mask_index, pixel_index, 3)
    assert torch.allclose(fast, slow, rtol=1e-4, atol=1e-3)
    sources = F.normalize(fast, dim=1)
    fast_sim = seg.feature_similarity(other, mask_index, pixel_index, sources)
    slow_sim = Segmenter.feature_similarity(seg, other, mask_index, pixel_index, sources)
    assert torch.allclose(fast_sim, slow_sim, atol=1e-5)
    assert float(slow_sim.std()) > 0.01  # the comparison is not between constants

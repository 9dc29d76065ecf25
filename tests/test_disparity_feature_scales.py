"""Issue 45, third round: two scales of matching features, the wider one's disparity away from
intensity edges and depth jumps (lfsam.disparity.feature_scales; docs/design.md section 3.2)."""

from __future__ import annotations

import numpy as np
import torch

from lfsam.disparity import estimate_disparity
from lfsam.disparity.cost_volume import view_set
from lfsam.disparity.feature_scales import fine_scale_mask
from lfsam.synth import generate_scene


def test_mask_marks_intensity_edges_and_depth_jumps_only():
    gray = torch.full((40, 60), 0.3)
    gray[:, 30:] = 0.7  # an intensity edge between columns 29 and 30
    flat = torch.zeros((40, 60))
    mask = fine_scale_mask(gray, flat, colour_edge=0.06, edge_radius=4)
    # the central differences see the edge at columns 29 and 30; dilated by 4
    assert bool(mask[:, 25:35].all())
    assert not bool(mask[:, :25].any()) and not bool(mask[:, 35:].any())
    # a depth jump of 1.5 px per view step on uniform gray, rows 20 and below nearer
    uniform = torch.full((40, 60), 0.5)
    jump = torch.zeros((40, 60))
    jump[20:] = 1.5
    mask = fine_scale_mask(uniform, jump, depth_jump=1.0, edge_radius=4)
    assert bool(mask[16:24].all())
    assert not bool(mask[:16].any()) and not bool(mask[24:].any())
    # a slanted surface (0.05 px per row: 0.45 over a 9-pixel window) is no jump
    slant = 0.05 * torch.arange(40, dtype=torch.float32)[:, None].expand(40, 60)
    assert not bool(fine_scale_mask(uniform, slant).any())
    # weak texture below the threshold is no edge either
    noise = 0.5 + 0.01 * torch.from_numpy(np.random.default_rng(0).random((40, 60))).float()
    assert not bool(fine_scale_mask(noise, flat).any())


def test_estimate_takes_the_fine_scale_near_edges_and_the_wide_one_elsewhere():
    lf = generate_scene(grid=(5, 5), size=(48, 64), seed=3, disparity_range=(-1.0, 1.0))
    options = {"disparity_range": (-1.5, 1.5), "fusion": False, "device": "cpu",
               "learned_refinement": False, "surface_fit": False}
    fine = estimate_disparity(lf, wide_feature_radius=None, **options)
    wide = estimate_disparity(lf, feature_radius=2, wide_feature_radius=None, **options)
    both = estimate_disparity(lf, **options)
    assert both.meta["wide_feature_radius"] == 2
    mask = fine_scale_mask(view_set(lf, device="cpu").gray, torch.from_numpy(fine.disparity))
    mask = mask.numpy()
    # the scene has objects: both parts are present, and they differ somewhere
    assert 0 < mask.mean() < 1
    assert not np.allclose(fine.disparity, wide.disparity)
    np.testing.assert_array_equal(both.disparity, np.where(mask, fine.disparity, wide.disparity))
    np.testing.assert_array_equal(
        both.confidence, np.where(mask, fine.confidence, wide.confidence)
    )
    # one scale when the wide radius is the fine one
    same = estimate_disparity(lf, wide_feature_radius=1, **options)
    np.testing.assert_array_equal(same.disparity, fine.disparity)

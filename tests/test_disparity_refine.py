"""Edge-aware disparity refinement (lfsam.disparity.refine)."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.disparity.refine import joint_bilateral_filter, refine_disparity


def _two_region_image(rows: int = 40, cols: int = 48, edge: int = 20) -> torch.Tensor:
    """A colour image with a vertical colour edge at column ``edge`` and mild texture."""
    rng = np.random.default_rng(0)
    image = np.empty((3, rows, cols), np.float32)
    image[:, :, :edge] = np.array([0.2, 0.3, 0.25], np.float32)[:, None, None]
    image[:, :, edge:] = np.array([0.7, 0.6, 0.5], np.float32)[:, None, None]
    image += rng.normal(0, 0.01, image.shape).astype(np.float32)
    return torch.from_numpy(image)


@settings(max_examples=15, deadline=None)
@given(value=st.floats(-5, 5), seed=st.integers(0, 2**16))
def test_constant_disparity_is_a_fixed_point(value: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    image = torch.from_numpy(rng.random((3, 16, 20), dtype=np.float32))
    confidence = torch.from_numpy(rng.random((16, 20), dtype=np.float32))
    disparity = torch.full((16, 20), value)
    out = refine_disparity(disparity, confidence, image, radius=3)
    assert torch.allclose(out, disparity, atol=1e-5)


def test_noise_is_averaged_and_a_colour_aligned_depth_edge_is_kept() -> None:
    rows, cols, edge = 40, 48, 20
    image = _two_region_image(rows, cols, edge)
    truth = torch.where(torch.arange(cols) < edge, 1.0, -2.0).expand(rows, cols)
    noise = torch.from_numpy(np.random.default_rng(1).normal(0, 0.1, (rows, cols))).float()
    confidence = torch.full((rows, cols), 0.8)
    out = refine_disparity(truth + noise, confidence, image)
    inner = (slice(8, -8), slice(8, -8))
    before = (noise[inner]).pow(2).mean().sqrt()
    after = (out - truth)[inner].pow(2).mean().sqrt()
    assert after < before / 3
    # the columns on both sides of the edge keep their own surface's value
    assert (out[8:-8, edge - 1] - 1.0).abs().max() < 0.05
    assert (out[8:-8, edge] + 2.0).abs().max() < 0.05


def test_isolated_low_confidence_outliers_are_voted_away() -> None:
    rows, cols = 32, 32
    rng = np.random.default_rng(2)
    image = torch.from_numpy(rng.normal(0.5, 0.01, (3, rows, cols)).astype(np.float32))
    disparity = torch.zeros(rows, cols)
    confidence = torch.ones(rows, cols)
    spots = (rng.integers(4, 28, 12), rng.integers(4, 28, 12))
    disparity[spots] = 3.0
    confidence[spots] = 0.1
    out = refine_disparity(disparity, confidence, image)
    assert out.abs().max() < 0.05


def test_disparity_kernel_excludes_other_surfaces() -> None:
    """With a disparity kernel centred on a reference, neighbours far from it carry no weight."""
    image = torch.full((1, 9, 9), 0.5)
    disparity = torch.zeros(9, 9)
    disparity[:, 5:] = 2.0
    weight = torch.ones(9, 9)
    plain = joint_bilateral_filter(disparity, weight, image, radius=4, spatial_sigma=3.0,
                                   color_sigma=0.1)
    kept = joint_bilateral_filter(disparity, weight, image, radius=4, spatial_sigma=3.0,
                                  color_sigma=0.1, disparity_sigma=0.1)
    assert plain[4, 4] > 0.3  # the plain filter mixes the two surfaces
    assert torch.allclose(kept, disparity, atol=1e-6)

"""Exact mask sums and cosine similarities on a bilinear feature grid (segmenters.feature_grid)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lfsam.segmenters.feature_grid as feature_grid
from lfsam.segmenters.feature_grid import (
    bilinear_corners,
    grid_cosine_similarity,
    grid_feature_sums,
)


def _sampled(grid: torch.Tensor, rows: torch.Tensor, cols: torch.Tensor, size) -> torch.Tensor:
    """Reference: the features at pixels by ``grid_sample`` (the SAM 2 backend's convention)."""
    u_size, v_size = size
    coords = torch.stack(
        [(cols + 0.5) * (2.0 / v_size) - 1.0, (rows + 0.5) * (2.0 / u_size) - 1.0], dim=-1
    )
    out = F.grid_sample(grid[None].double(), coords.view(1, 1, -1, 2).double(), mode="bilinear",
                        padding_mode="border", align_corners=False)
    return out[0, :, 0].T  # (P, C)


sizes = st.tuples(st.integers(1, 7), st.integers(1, 7), st.integers(1, 30), st.integers(1, 30))


@settings(max_examples=40, deadline=None)
@given(shape=sizes, seed=st.integers(0, 2**16))
def test_corner_weights_reproduce_grid_sample(shape, seed):
    h, w, u_size, v_size = shape
    rng = np.random.default_rng(seed)
    grid = torch.from_numpy(rng.normal(size=(3, h, w)))
    rows, cols = torch.meshgrid(torch.arange(u_size), torch.arange(v_size), indexing="ij")
    rows, cols = rows.reshape(-1), cols.reshape(-1)
    corners = bilinear_corners(rows, cols, (u_size, v_size), (h, w))
    assert torch.allclose(corners.weight.sum(1), torch.ones(len(rows)), atol=1e-6)
    assert bool((corners.weight >= -1e-7).all())
    ours = (grid.reshape(3, -1)[:, corners.index] * corners.weight.double()).sum(-1).T
    assert torch.allclose(ours, _sampled(grid, rows, cols, (u_size, v_size)), atol=1e-5)


@settings(max_examples=25, deadline=None)
@given(shape=sizes, masks=st.integers(1, 4), seed=st.integers(0, 2**16))
@example(shape=(4, 1, 25, 23), masks=1, seed=498)  # a float32 sum off by 2e-4 out of ~230
def test_sums_and_similarities_match_per_pixel_features(shape, masks, seed):
    h, w, u_size, v_size = shape
    rng = np.random.default_rng(seed)
    grid = torch.from_numpy(rng.normal(size=(5, h, w)).astype(np.float32))
    dense = torch.from_numpy(rng.random((masks, u_size, v_size)) < 0.4)
    mask_index, pixel_index = torch.nonzero(dense.reshape(masks, -1), as_tuple=True)
    rows, cols = pixel_index // v_size, pixel_index % v_size
    feats = _sampled(grid, rows, cols, (u_size, v_size))  # (P, C), float64
    expected_sums = torch.zeros(masks, 5, dtype=torch.float64).index_add_(0, mask_index, feats)
    sums = grid_feature_sums(grid, mask_index, pixel_index, masks, (u_size, v_size))
    # float32 sums of up to 900 terms: rounding grows with the summed magnitudes, so the bound
    # is relative to the sum of absolute values (a wrong weight is off by a whole feature)
    magnitude = torch.zeros(masks, 5, dtype=torch.float64).index_add_(0, mask_index, feats.abs())
    assert bool(((sums.double() - expected_sums).abs() <= 1e-5 * magnitude + 1e-5).all())
    sources = F.normalize(torch.from_numpy(rng.normal(size=(masks, 5)).astype(np.float32)), dim=1)
    expected = F.cosine_similarity(feats, sources.double()[mask_index], dim=1, eps=1e-12)
    sims = grid_cosine_similarity(grid, mask_index, pixel_index, sources, (u_size, v_size))
    assert torch.allclose(sims.double(), expected, atol=1e-5)


def test_similarity_is_exactly_one_for_a_constant_feature_direction():
    grid = torch.ones(4, 6, 6) * torch.tensor([1.0, -2.0, 0.5, 3.0])[:, None, None]
    grid = grid * torch.linspace(0.5, 2.0, 36).view(1, 6, 6)  # same direction, varying length
    source = F.normalize(torch.tensor([[1.0, -2.0, 0.5, 3.0]]), dim=1)
    pixels = torch.arange(20 * 24)
    sims = grid_cosine_similarity(grid, torch.zeros_like(pixels), pixels, source, (20, 24))
    assert torch.allclose(sims, torch.ones_like(sims), atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(shape=sizes, masks=st.integers(1, 3), density=st.floats(0.01, 1.0), seed=st.integers(0, 99))
def test_interpolated_and_gathered_similarities_agree_with_per_pixel_features(
    shape, masks, density, seed
):
    """Both ways of computing the numerator (whole-view interpolation, four-corner gather)."""
    h, w, u_size, v_size = shape
    rng = np.random.default_rng(seed)
    grid = torch.from_numpy(rng.normal(size=(5, h, w)).astype(np.float32))
    dense = torch.from_numpy(rng.random((masks, u_size, v_size)) < density)
    mask_index, pixel_index = torch.nonzero(dense.reshape(masks, -1), as_tuple=True)
    feats = _sampled(grid, pixel_index // v_size, pixel_index % v_size, (u_size, v_size))
    sources = F.normalize(torch.from_numpy(rng.normal(size=(masks, 5)).astype(np.float32)), dim=1)
    expected = F.cosine_similarity(feats, sources.double()[mask_index], dim=1, eps=1e-12)
    results = []
    for threshold in (0, 10**9):  # never / always interpolate
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(feature_grid, "INTERPOLATE_BELOW", threshold)
            results.append(
                grid_cosine_similarity(grid, mask_index, pixel_index, sources, (u_size, v_size))
            )
    for sims in results:
        assert torch.allclose(sims.double(), expected, atol=1e-5)


def test_a_masks_similarities_do_not_depend_on_the_other_masks_in_the_call():
    """Per-mask choice of interpolation or gather: a dense and a sparse mask give the same
    values alone as together (an incremental edit equals a full run)."""
    rng = np.random.default_rng(0)
    grid = torch.from_numpy(rng.normal(size=(6, 8, 8)).astype(np.float32))
    size = (24, 32)
    dense = torch.ones(size, dtype=torch.bool).reshape(-1)
    sparse = torch.zeros(size, dtype=torch.bool).reshape(-1)
    sparse[::37] = True
    sources = F.normalize(torch.from_numpy(rng.normal(size=(2, 6)).astype(np.float32)), dim=1)
    together = grid_cosine_similarity(
        grid,
        torch.cat([torch.zeros(int(dense.sum()), dtype=torch.long),
                   torch.ones(int(sparse.sum()), dtype=torch.long)]),
        torch.cat([torch.nonzero(dense)[:, 0], torch.nonzero(sparse)[:, 0]]),
        sources, size,
    )
    alone = [
        grid_cosine_similarity(grid, torch.zeros(int(m.sum()), dtype=torch.long),
                               torch.nonzero(m)[:, 0], sources[k : k + 1], size)
        for k, m in enumerate((dense, sparse))
    ]
    assert torch.equal(together, torch.cat(alone))

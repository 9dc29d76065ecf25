"""Disparity propagation (paper section 3.2) checked against exact geometry."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.pipeline.propagation import (
    forward_warp,
    mask_disparities,
    propagate_masks,
    shift_masks,
)


def _square(height=24, width=32, top=8, left=10, size=6):
    mask = torch.zeros((1, height, width), dtype=torch.bool)
    mask[0, top : top + size, left : left + size] = True
    return mask


@settings(max_examples=40, deadline=None)
@given(
    d=st.integers(-3, 3),
    ds=st.integers(-2, 2),
    dt=st.integers(-2, 2),
    mode=st.sampled_from(["pixel", "mean", "median"]),
)
def test_constant_integer_disparity_is_an_exact_translation(d, ds, dt, mode):
    # Convention (lfsam.geometry): (u, v) -> (u - d ds, v - d dt).
    mask = _square()
    disp = torch.full((24, 32), float(d))
    out = propagate_masks(mask, disp, ds, dt, mode)
    expected = torch.zeros_like(mask)
    expected[0, 8 - d * ds : 14 - d * ds, 10 - d * dt : 16 - d * dt] = True
    assert torch.equal(out, expected)


@settings(max_examples=30, deadline=None)
@given(d=st.floats(-2.5, 2.5), ds=st.integers(-3, 3), dt=st.integers(-3, 3))
def test_pixel_propagation_moves_each_pixel_to_its_rounded_target(d, ds, dt):
    rng = np.random.default_rng(0)
    mask = torch.as_tensor(rng.random((2, 20, 20)) > 0.7)
    disp = torch.full((20, 20), float(d))
    out = propagate_masks(mask, disp, ds, dt, "pixel", fill_holes=False)
    n, u, v = np.nonzero(mask.numpy())
    # Same float32 arithmetic as the tensors, so ties at .5 round alike.
    d32 = np.float32(d)
    tu = np.round(u.astype(np.float32) - d32 * np.float32(ds)).astype(int)
    tv = np.round(v.astype(np.float32) - d32 * np.float32(dt)).astype(int)
    inside = (tu >= 0) & (tu < 20) & (tv >= 0) & (tv < 20)
    expected = np.zeros((2, 20, 20), dtype=bool)
    expected[n[inside], tu[inside], tv[inside]] = True
    # torch.round and np.round both round half to even.
    assert np.array_equal(out.numpy(), expected)


def test_stretched_surface_has_no_holes_after_filling():
    # A slanted plane whose disparity grows along columns stretches in views to the left.
    height, width = 20, 40
    disp = torch.linspace(0.0, 3.0, width)[None].repeat(height, 1)
    mask = torch.zeros((1, height, width), dtype=torch.bool)
    mask[0, 5:15, 5:35] = True
    raw = propagate_masks(mask, disp, 0, -3, "pixel", fill_holes=False)
    filled = propagate_masks(mask, disp, 0, -3, "pixel", fill_holes=True)
    row = filled[0, 10]
    cols = torch.nonzero(row).flatten()
    assert bool(row[cols.min() : cols.max() + 1].all())  # contiguous after filling
    assert int((~raw[0, 10, cols.min() : cols.max() + 1]).sum()) > 0  # gaps before filling


def test_zbuffer_hides_farther_pixels():
    # Background (d=0) and a closer square (d=2); in view dt=+1 the square moves 2 px left and
    # covers background pixels, which the z-buffer must report as hidden.
    disp = torch.zeros((10, 20))
    disp[3:7, 8:12] = 2.0
    warp = forward_warp(disp, 0, 1)
    visible = warp.visible(disp, tolerance=0.2).reshape(10, 20)
    assert not bool(visible[4, 6:8].any())  # background landing under the square's new place
    assert bool(visible[4, 8:12].all())  # the square itself is visible
    assert bool(visible[0].all())


def test_mask_disparity_statistics():
    mask = torch.zeros((1, 4, 4), dtype=torch.bool)
    mask[0, 0, :3] = True
    disp = torch.zeros((4, 4))
    disp[0, :3] = torch.tensor([1.0, 2.0, 6.0])
    assert mask_disparities(mask, disp, "mean").item() == 3.0
    assert mask_disparities(mask, disp, "median").item() == 2.0


def test_subpixel_shift_rounds_half_pixel_consistently():
    mask = _square()
    out = shift_masks(mask, torch.tensor([[0.25, -1.75]]))
    expected = torch.zeros_like(mask)
    expected[0, 8:14, 8:14] = True  # 0.25 rounds to 0 rows, -1.75 to -2 columns
    assert torch.equal(out, expected)


def test_hole_filling_does_not_claim_pixels_a_closer_surface_lands_on():
    # Background (d=0) with a one-pixel-wide closer bar (d=1) in column 10. In the center view
    # the background mask has a 1-px gap there; closing would fill it, but the bar lands there.
    disp = torch.zeros((12, 20))
    disp[:, 10] = 1.0
    background = torch.ones((1, 12, 20), dtype=torch.bool)
    background[0, :, 10] = False
    same_view = propagate_masks(background, disp, 0, 0, "pixel")
    assert torch.equal(same_view, background)

"""Shift-and-add and refocusing (lfsam.render; docs/design.md section 13): exact properties."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.render import refocus
from lfsam.render.shift import shift_and_add, translate
from lfsam.render.views import select_views


@settings(max_examples=25, deadline=None)
@given(du=st.integers(-5, 5), dv=st.integers(-5, 5), seed=st.integers(0, 1000))
def test_whole_pixel_shifts_reproduce_the_pixels_exactly(du, dv, seed):
    image = torch.from_numpy(np.random.default_rng(seed).random((2, 9, 11)).astype(np.float32))
    moved = translate(image[None], torch.tensor([float(du)]), torch.tensor([float(dv)]))[0]
    expected = torch.zeros_like(image)
    rows, cols = image.shape[-2:]
    for u in range(rows):
        for v in range(cols):
            if 0 <= u + du < rows and 0 <= v + dv < cols:
                expected[:, u, v] = image[:, u + du, v + dv]
    assert torch.equal(moved, expected)


@settings(max_examples=20, deadline=None)
@given(focus=st.floats(-2.0, 2.0), phase=st.floats(0.0, 6.0))
def test_a_plane_at_the_focus_is_reproduced(focus, phase):
    """Views of a smooth fronto-parallel plane at disparity ``focus`` refocus onto the center
    view (away from the border) whatever the sub-pixel shift; bilinear sampling of a smooth
    texture is nearly exact."""

    def texture(rows, cols):
        value = np.sin(0.35 * rows + phase) * np.cos(0.3 * cols) + 0.5 * np.sin(0.2 * cols)
        return np.repeat((127 + 80 * value)[..., None], 3, axis=-1)

    s_count, t_count, height, width = 3, 3, 24, 28
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    views = np.zeros((s_count, t_count, height, width, 3), dtype=np.uint8)
    for s in range(s_count):
        for t in range(t_count):
            # view (s, t) sees center pixel (u, v) at (u - f ds, v - f dt)
            views[s, t] = texture(rows + focus * (s - 1), cols + focus * (t - 1)).round()
    image = refocus(views, focus)
    inner = (slice(3, -3), slice(3, -3))
    center = views[1, 1].astype(np.float32)
    assert np.abs(image[inner] - center[inner]).max() < 4.0


def test_integer_focus_on_an_exact_plane_is_exact():
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 256, (30, 30, 3), dtype=np.uint8)
    views = np.stack([np.stack([texture[5 + s:25 + s, 5 + t:25 + t] for t in (-1, 0, 1)])
                      for s in (-1, 0, 1)])  # view (s, t) sees center (u, v) at (u - s, v - t)
    image = refocus(views, 1.0)
    assert np.array_equal(image[1:-1, 1:-1], views[1, 1, 1:-1, 1:-1].astype(np.float32))


def test_borders_are_normalised_by_the_rays_that_land():
    views = np.full((5, 5, 12, 14, 3), 200, dtype=np.uint8)
    image = refocus(views, 1.7)  # rays leave the view at every border
    assert np.allclose(image, 200.0, atol=1e-3)  # no dark rim, no wrap


def test_keep_weights_leave_rays_out():
    images = torch.stack([torch.full((1, 4, 4), 10.0), torch.full((1, 4, 4), 90.0)])
    offsets = torch.zeros(2, 2, dtype=torch.float64)
    keep = torch.stack([torch.ones(4, 4), torch.zeros(4, 4)])
    total, weight = shift_and_add(images, offsets, 0.0, keep)
    assert torch.allclose(total / weight, torch.full((1, 4, 4), 10.0))
    assert torch.equal(weight, torch.ones(4, 4))


def test_aperture_selects_views_within_the_radius():
    chosen, _ = select_views((5, 5), aperture=1.0)
    assert sorted(chosen) == [(1, 2), (2, 1), (2, 2), (2, 3), (3, 2)]
    present = np.ones((5, 5), dtype=bool)
    present[2, 3] = False
    chosen, _ = select_views((5, 5), present, aperture=1.0)
    assert (2, 3) not in chosen and len(chosen) == 4
    with pytest.warns(UserWarning, match="outside the scene's disparity range"):
        refocus(np.zeros((3, 3, 4, 4, 3), np.uint8), 9.0, disparity_range=(-1.0, 1.0))


@settings(max_examples=10, deadline=None)
@given(focus=st.floats(0.1, 0.9), phase=st.floats(0.0, 6.0))
def test_lanczos_keeps_a_fine_texture_on_the_focal_plane_sharp(focus, phase):
    """A fine texture (periods of 2.5-4 pixels) on the focal plane: bilinear sampling blurs
    each view by its own sub-pixel phase, Lanczos-3 reproduces the center view far closer."""

    def texture(rows, cols):
        value = np.sin(2.2 * rows + phase) + np.cos(1.7 * cols - phase)
        value = value + np.sin(1.6 * (rows + cols))
        return np.repeat((127 + 35 * value)[..., None], 3, axis=-1)

    height, width = 30, 34
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    views = np.zeros((3, 3, height, width, 3), dtype=np.float64)
    for s in range(3):
        for t in range(3):
            views[s, t] = texture(rows + focus * (s - 1), cols + focus * (t - 1))
    views = views.round().astype(np.uint8)
    inner = (slice(5, -5), slice(5, -5))
    center = views[1, 1].astype(np.float32)[inner]
    sharp = np.abs(refocus(views, focus)[inner] - center).mean()
    soft = np.abs(refocus(views, focus, kernel="linear")[inner] - center).mean()
    assert sharp < 0.5 * soft
    assert sharp < 6.0


def test_separable_bilinear_equals_per_view_translation():
    rng = np.random.default_rng(3)
    images = torch.from_numpy(rng.random((9, 2, 13, 15)).astype(np.float32))
    keep = torch.from_numpy((rng.random((9, 13, 15)) > 0.3).astype(np.float32))
    _, offsets = select_views((3, 3))
    focus = 0.73
    du, dv = -focus * offsets[:, 0], -focus * offsets[:, 1]
    expected = translate(torch.cat([images * keep[:, None], keep[:, None]], 1), du, dv).sum(0)
    total, weight = shift_and_add(images, offsets, focus, keep)
    assert torch.allclose(total, expected[:2], atol=1e-5)
    assert torch.allclose(weight, expected[2], atol=1e-5)

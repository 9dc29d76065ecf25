"""Issue 45's estimator parts: the colour guided filter, the strip windows, the all-views choice
of the cost volume (docs/design.md section 3.2)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.disparity import estimate_disparity
from lfsam.disparity.aggregation import aggregate_costs
from lfsam.disparity.cost_volume import build_cost_volume, view_set
from lfsam.disparity.filters import (
    box_blur,
    box_blur_rect,
    colour_guided_filter,
    guided_filter,
)
from lfsam.errors import LfsamError


def _random(shape, seed=0):
    return torch.from_numpy(np.random.default_rng(seed).random(shape).astype(np.float32))


def test_rectangular_box_is_the_square_box_when_square():
    image = _random((2, 30, 40))
    for radius in (1, 2, 4):
        assert torch.allclose(box_blur_rect(image, radius, radius), box_blur(image, radius),
                              atol=1e-5)
    # a (0, r) window averages along rows only
    line = box_blur_rect(image, 0, 3)
    assert torch.allclose(line[:, 10, 10], image[:, 10, 7:14].mean(-1), atol=1e-6)


def test_shrinking_box_averages_only_inside_the_frame():
    image = _random((2, 30, 40), 7)
    shrink = box_blur_rect(image, 2, 3, "shrink")
    assert torch.allclose(shrink[:, 0, 0], image[:, :3, :4].mean((-2, -1)), atol=1e-6)
    assert torch.allclose(shrink[:, 29, 20], image[:, 27:, 17:24].mean((-2, -1)), atol=1e-6)
    replicate = box_blur_rect(image, 2, 3)
    assert torch.allclose(shrink[:, 2:-2, 3:-3], replicate[:, 2:-2, 3:-3], atol=1e-6)
    assert not torch.allclose(shrink[:, 0, 0], replicate[:, 0, 0], atol=1e-3)
    with pytest.raises(ValueError, match="unknown border"):
        box_blur_rect(image, 1, 1, "wrap")


def test_border_windows_do_not_overweight_the_outermost_column():
    # hypothesis 0 is right everywhere but costs 1 in the outermost column (fewer views see it);
    # hypothesis 1 costs 0.3 everywhere. Replicated, that column fills a third of the window of
    # the pixel two columns in and hypothesis 1 wins there; shrunk, hypothesis 0 wins
    cost = torch.zeros((2, 24, 24))
    cost[0, :, 0] = 1.0
    cost[1] = 0.3
    guide = torch.full((3, 24, 24), 0.5)
    for border, winner in (("shrink", 0), ("replicate", 1)):
        out = aggregate_costs(cost, guide, line_radius=0, border=border)
        assert int(out[:, 12, 2].argmin()) == winner
    assert bool((aggregate_costs(cost, guide)[:, :, 1:].argmin(0) == 0).all())


def test_colour_guide_with_equal_channels_is_the_gray_guided_filter():
    # with the three channels equal, Sigma = var * 1 1^T + eps I, so the colour filter is the
    # gray one with eps / 3 (He et al.'s formulas, solved by hand)
    gray = _random((40, 48), 1)
    cost = _random((3, 40, 48), 2)
    colour = colour_guided_filter(gray[None].expand(3, -1, -1), cost, (3, 3), 3e-3)
    assert torch.allclose(colour, guided_filter(gray, cost, 3, 1e-3), atol=1e-4)


def test_colour_guided_filter_keeps_constants_and_edges():
    guide = torch.zeros((3, 32, 32))
    guide[0, :, 16:] = 1.0  # a red / black edge
    constant = torch.full((2, 32, 32), 0.3)
    assert torch.allclose(colour_guided_filter(guide, constant, (4, 4), 1e-4), constant,
                          atol=1e-5)
    step = guide[:1].clone()
    smoothed = colour_guided_filter(guide, step, (4, 4), 1e-4)[0]
    assert float((smoothed - step[0]).abs().max()) < 0.01


def test_aggregation_picks_a_window_per_pixel():
    cost = _random((5, 36, 36), 3)
    guide = _random((3, 36, 36), 4)
    out = aggregate_costs(cost, guide)
    square = colour_guided_filter(guide, cost, (4, 4), 1e-4, "shrink")
    horizontal = colour_guided_filter(guide, cost, (1, 8), 1e-4, "shrink")
    vertical = colour_guided_filter(guide, cost, (8, 1), 1e-4, "shrink")
    one_of = [(out - v).abs().amax(0) < 1e-6 for v in (square, horizontal, vertical)]
    assert bool((one_of[0] | one_of[1] | one_of[2]).all())
    assert torch.equal(aggregate_costs(cost, guide, line_radius=0), square)


def test_all_views_cost_is_the_plain_mean_without_a_clear_half():
    lf = np.random.default_rng(5).integers(0, 256, size=(5, 5, 24, 32, 3), dtype=np.uint8)
    views = view_set(lf, device="cpu")
    hypotheses = np.array([-0.5, 0.0, 0.5])
    plain = build_cost_volume(views, hypotheses, occlusion_aware=False)
    never = build_cost_volume(views, hypotheses, full_set_ratio=1.0)  # no half is ever clear
    assert torch.equal(never, plain)
    halves = build_cost_volume(views, hypotheses)  # always the best half (before issue 45)
    mixed = build_cost_volume(views, hypotheses, full_set_ratio=0.08)
    chose_all = (mixed == plain).float().mean()
    chose_half = (mixed == halves).float().mean()
    assert chose_all > 0.3 and chose_half > 0.01
    assert bool(((mixed == plain) | (mixed == halves)).all())


def test_the_aggregation_option_is_checked():
    lf = np.random.default_rng(6).integers(0, 256, size=(3, 3, 20, 24, 3), dtype=np.uint8)
    with pytest.raises(LfsamError, match="aggregation"):
        estimate_disparity(lf, (-1.0, 1.0), device="cpu", aggregation="median")
    old = estimate_disparity(lf, (-1.0, 1.0), device="cpu", aggregation="guided",
                             aggregation_radius=3, full_set_ratio=None, fusion=False)
    assert old.meta["aggregation"] == "guided" and old.meta["full_set_ratio"] is None


def test_shrinking_box_on_frames_narrower_than_its_window():
    image = _random((1, 5, 3), 8)
    shrink = box_blur_rect(image, 4, 4, "shrink")
    assert torch.allclose(shrink, image.mean((-2, -1), keepdim=True).expand_as(image), atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(1, 40), cols=st.integers(1, 40), radius_rows=st.integers(0, 12),
       radius_cols=st.integers(0, 12), border=st.sampled_from(["replicate", "shrink"]),
       seed=st.integers(0, 2**16))
def test_opencv_box_sums_are_the_torch_sums(rows, cols, radius_rows, radius_cols, border, seed):
    """On a CPU the box filter's window sums are OpenCV's (cv2.boxFilter); the separable torch
    sums by doubling, the path on a GPU and without OpenCV, give the same means to float32
    rounding, windows wider than the image included."""
    from lfsam.disparity import filters

    image = _random((3, rows, cols), seed) * 4 - 1
    box = filters.BoxFilter((rows, cols), radius_rows, radius_cols, border)
    assert filters._opencv_can_sum(image)
    ours = box._means(image.clone())
    assert filters._opencv_can_sum(image) and not filters._opencv_can_sum(image.double())
    installed = filters._HAS_CV2
    try:
        filters._HAS_CV2 = False
        theirs = box._means(image.clone())
    finally:
        filters._HAS_CV2 = installed
    torch.testing.assert_close(ours, theirs, atol=1e-5, rtol=0)

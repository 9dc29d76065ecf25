"""Tests of side-by-side comparisons (lfsam.viz.compare)."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.errors import LfsamError
from lfsam.viz.animation import animation_frames
from lfsam.viz.colors import label_colors
from lfsam.viz.compare import (
    compare_epi,
    compare_frames,
    compare_grid,
    match_labels,
    side_by_side,
)
from lfsam.viz.epi import epi_figure
from lfsam.viz.grid import view_grid
from lfsam.viz.layout import CAPTION_HEIGHT
from lfsam.viz.overlay import label_boundaries
from test_viz_scene import make_scene


def test_side_by_side_sizes():
    a = np.zeros((10, 20, 3), dtype=np.uint8)
    b = np.zeros((14, 8, 3), dtype=np.uint8)
    assert side_by_side([a, b], gap=3).shape == (14, 31, 3)
    assert side_by_side([a, b], ["a", "b"], gap=3).shape == (14 + CAPTION_HEIGHT, 31, 3)
    assert side_by_side([a, b], gap=2, direction="vertical").shape == (26, 20, 3)
    with pytest.raises(LfsamError, match="direction"):
        side_by_side([a, b], direction="diagonal")


def test_compare_grid_holds_both_grids_with_shared_colours():
    lf = make_scene(grid=(3, 3))
    other = lf.labels.copy()
    other[other == 1] = 2  # the second result merged objects 1 and 2
    fig = compare_grid(lf.views, lf.labels, other, names=("ours", "merged"), which="corners", gap=6)
    left = view_grid(lf.views, lf.labels, which="corners")
    right = view_grid(lf.views, other, which="corners")
    c = CAPTION_HEIGHT
    assert fig.shape == (left.shape[0] + c, 2 * left.shape[1] + 6, 3)
    np.testing.assert_array_equal(fig[c:, : left.shape[1]], left)
    np.testing.assert_array_equal(fig[c:, left.shape[1] + 6 :], right)
    # Label 2 has one colour in both panels: read it back at an interior pixel of each.
    inner = (lf.labels[0, 0] == 2) & ~label_boundaries(lf.labels[0, 0])
    u, v = np.argwhere(inner)[0]
    grey = lf.views[0, 0, u, v].astype(float)
    expected = np.rint(0.5 * grey + 0.5 * label_colors(2))
    x0 = left.shape[1] + 6
    np.testing.assert_array_equal(fig[c + 2 + u, 2 + v], expected)
    np.testing.assert_array_equal(fig[c + 2 + u, x0 + 2 + v], expected)


def test_compare_epi_and_frames():
    lf = make_scene(grid=(3, 5))
    other = np.where(lf.labels == 3, 0, lf.labels)
    fig = compare_epi(lf.views, lf.labels, other, names=None, upsample=4, gap=5)
    single = epi_figure(lf.views, lf.labels, upsample=4)
    assert fig.shape == (single.shape[0], 2 * single.shape[1] + 5, 3)
    np.testing.assert_array_equal(fig[:, : single.shape[1]], single)
    frames = list(compare_frames(lf.views, lf.labels, other, names=("a", "b"), gap=4))
    assert len(frames) == 15
    lone = list(animation_frames(lf.views, other))
    h, w = lone[0].shape[:2]
    for frame, expected in zip(frames, lone, strict=True):
        assert frame.shape == (h + CAPTION_HEIGHT, 2 * w + 4, 3)
        np.testing.assert_array_equal(frame[CAPTION_HEIGHT:, w + 4 :], expected)


def test_compare_rejects_results_of_another_light_field():
    lf = make_scene(grid=(3, 3))
    with pytest.raises(LfsamError, match="second labels"):
        compare_grid(lf.views, lf.labels, lf.labels[:, :, :20])


def test_match_labels_recovers_a_renumbering():
    lf = make_scene(grid=(3, 3))
    renumber = np.array([0, 7, 5, 9])  # 1 -> 7, 2 -> 5, 3 -> 9
    shuffled = renumber[lf.labels]
    np.testing.assert_array_equal(match_labels(lf.labels, shuffled), lf.labels)


def test_match_labels_is_one_to_one_and_keeps_unmatched_regions_apart():
    reference = np.array([[1, 1, 1, 2, 2, 0, 0]])
    labels = np.array([[4, 4, 6, 6, 6, 8, 8]])
    matched = match_labels(reference, labels)
    # 4 overlaps 1 (2 px); 6 overlaps 2 (2 px) and 1 (1 px) -> 2; 8 overlaps only 0 -> fresh id.
    np.testing.assert_array_equal(matched, [[1, 1, 2, 2, 2, 3, 3]])
    two_to_one = match_labels(np.array([[1, 1, 1, 1]]), np.array([[5, 5, 5, 6]]))
    np.testing.assert_array_equal(two_to_one, [[1, 1, 1, 2]])
    np.testing.assert_array_equal(match_labels(reference, np.zeros_like(labels)), 0)

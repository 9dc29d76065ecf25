"""Tests of the view-grid figure (lfsam.viz.grid) and its layout helpers."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.errors import LfsamError
from lfsam.result import PackedMasks
from lfsam.viz.colors import label_colors
from lfsam.viz.grid import grid_layout, select_views, view_grid
from lfsam.viz.layout import CAPTION_HEIGHT, rescale, tile
from lfsam.viz.overlay import label_boundaries, overlay_labels
from test_viz_scene import make_scene


def test_select_views():
    assert select_views((3, 4), "all") == [(s, t) for s in range(3) for t in range(4)]
    assert select_views((5, 7), "corners") == [(0, 0), (0, 6), (2, 3), (4, 0), (4, 6)]
    assert select_views((5, 7), "diagonal") == [(0, 0), (2, 3), (4, 6)]
    assert select_views((1, 3), "corners") == [(0, 0), (0, 2), (0, 1)]  # duplicates dropped
    assert select_views((1, 1), "corners") == [(0, 0)]
    assert select_views((3, 3), [(1, 2), (0, 0)]) == [(1, 2), (0, 0)]
    with pytest.raises(LfsamError, match="unknown view selection"):
        select_views((3, 3), "edges")
    with pytest.raises(LfsamError, match="outside"):
        select_views((3, 3), [(3, 0)])


@pytest.mark.parametrize(
    ("grid", "which", "captions", "pad"),
    [((3, 4), "all", False, 2), ((5, 5), "corners", True, 3), ((5, 3), "diagonal", True, 0)],
)
def test_grid_size_and_tiles(grid, which, captions, pad):
    lf = make_scene(grid=grid)
    fig = view_grid(lf.views, lf.labels, which=which, captions=captions, pad=pad)
    rows, cols, cells = grid_layout(grid, which)
    if which == "all":
        assert (rows, cols) == grid
    else:
        assert rows == 1 and cols == len(select_views(grid, which))
    c = CAPTION_HEIGHT if captions else 0
    assert fig.shape == (rows * (48 + c) + (rows + 1) * pad, cols * 64 + (cols + 1) * pad, 3)
    for index, (s, t) in enumerate(cells):
        r, q = divmod(index, cols)
        y = pad + r * (48 + c + pad) + c
        x = pad + q * (64 + pad)
        expected = overlay_labels(lf.views[s, t], lf.labels[s, t])
        np.testing.assert_array_equal(fig[y : y + 48, x : x + 64], expected)


def test_label_colour_is_the_same_in_every_view_of_the_figure():
    # Flat grey views: the colour of a label's interior pixel read back from the figure must be
    # the blend of grey with that label's palette colour, in every view.
    lf = make_scene(grid=(3, 3))
    grey = np.full_like(lf.views, 120)
    alpha = 0.5
    fig = view_grid(grey, lf.labels, alpha=alpha, pad=2)
    for k in (1, 2, 3):
        expected = np.rint((1 - alpha) * 120 + alpha * label_colors(k).astype(float))
        seen = []
        for s in range(3):
            for t in range(3):
                inner = (lf.labels[s, t] == k) & ~label_boundaries(lf.labels[s, t])
                y, x = 2 + s * 50, 2 + t * 66
                pixels = fig[y : y + 48, x : x + 64][inner]
                assert len(pixels) > 0
                seen.append(np.unique(pixels, axis=0))
        for colours in seen:
            np.testing.assert_array_equal(colours, expected[None].astype(np.uint8))


def test_grid_draws_mask_outlines_from_packed_masks():
    lf = make_scene(grid=(3, 3))
    masks = PackedMasks((3, 3, 3, 48, 64))
    for s in range(3):
        for t in range(3):
            masks.set_view(s, t, np.stack([lf.labels[s, t] == k for k in (1, 2, 3)]))
    with_masks = view_grid(lf.views, lf.labels, masks=masks, pad=0)
    plain = view_grid(lf.views, lf.labels, pad=0)
    assert with_masks.shape == plain.shape
    # Masks equal to the label regions give the same picture.
    np.testing.assert_array_equal(with_masks, plain)


def test_grid_without_labels_shows_the_views():
    lf = make_scene(grid=(2, 2))
    fig = view_grid(lf.views, None, pad=1, background=0)
    np.testing.assert_array_equal(fig[1:49, 66:130], lf.views[0, 1])
    assert (fig[0] == 0).all()


def test_grid_rejects_mismatched_labels():
    lf = make_scene(grid=(3, 3))
    with pytest.raises(LfsamError, match="same light field"):
        view_grid(lf.views, lf.labels[:2])


def test_tile_and_rescale_sizes():
    a = np.zeros((4, 6, 3), dtype=np.uint8)
    assert tile([a, None, a], 2, 2, pad=1).shape == (2 * 4 + 3, 2 * 6 + 3, 3)
    with pytest.raises(ValueError):
        tile([a] * 5, 2, 2)
    big = np.zeros((10, 30, 3), dtype=np.uint8)
    assert rescale(big, 0.5).shape == (5, 15, 3)
    assert rescale(big, 2).shape == (20, 60, 3)
    labels_img = np.kron(np.eye(2, dtype=np.uint8) * 200, np.ones((2, 2), dtype=np.uint8))
    up = rescale(np.repeat(labels_img[..., None], 3, -1), 3)  # nearest: colours stay exact
    assert set(np.unique(up)) == {0, 200}

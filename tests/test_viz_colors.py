"""Tests of the label palette (lfsam.viz.colors)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from lfsam.viz.colors import NO_LABEL_COLOR, colorize_labels, label_colors, palette


def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a.astype(float) - b.astype(float), axis=-1)


def test_label_zero_has_no_colour():
    assert tuple(label_colors(0)) == NO_LABEL_COLOR
    assert tuple(palette(5)[0]) == NO_LABEL_COLOR


@given(st.integers(1, 10_000), st.integers(0, 200))
def test_colour_depends_on_the_id_only(label, extra):
    # The same id gets the same colour whatever palette length or array it is looked up in.
    table = palette(label + extra)
    np.testing.assert_array_equal(table[label], label_colors(label))
    np.testing.assert_array_equal(label_colors([[label, 0], [label, label]])[1, 1], table[label])


def test_neighbouring_ids_are_far_apart():
    colors = label_colors(np.arange(1, 5001))
    assert _distance(colors[1:], colors[:-1]).min() > 150  # of at most 441 in RGB


def test_first_twenty_ids_are_all_distinguishable():
    colors = label_colors(np.arange(1, 21))
    dist = _distance(colors[:, None], colors[None, :])
    dist[np.eye(20, dtype=bool)] = np.inf
    assert dist.min() > 35


def test_labelled_colours_are_never_black():
    # Value >= 0.82: a labeled pixel always differs from "no label".
    colors = label_colors(np.arange(1, 2000))
    assert colors.max(axis=1).min() >= 200


def test_colorize_uses_the_palette():
    labels = np.array([[0, 1, 7], [7, 7, 2]])
    image = colorize_labels(labels)
    assert image.shape == (2, 3, 3) and image.dtype == np.uint8
    for (i, j), k in np.ndenumerate(labels):
        np.testing.assert_array_equal(image[i, j], label_colors(k))


def test_negative_ids_are_rejected():
    with pytest.raises(ValueError):
        label_colors([-1])
    with pytest.raises(ValueError):
        colorize_labels(np.array([[0, -2]]))

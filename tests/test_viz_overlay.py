"""Tests of label overlays and boundaries (lfsam.viz.overlay)."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.viz.colors import label_colors
from lfsam.viz.overlay import label_boundaries, mask_boundaries, overlay_labels


def _square(labels: np.ndarray, label: int, top: int, left: int, size: int) -> None:
    labels[top : top + size, left : left + size] = label


def _ring(shape, top, left, size, width=1) -> np.ndarray:
    """The pixels of a square that lie within ``width`` of its outside (built independently)."""
    ring = np.zeros(shape, dtype=bool)
    ring[top : top + size, left : left + size] = True
    ring[top + width : top + size - width, left + width : left + size - width] = False
    return ring


def test_boundaries_of_a_square_are_its_inner_ring():
    labels = np.zeros((20, 30), dtype=np.int32)
    _square(labels, 4, 3, 5, 8)
    np.testing.assert_array_equal(label_boundaries(labels), _ring(labels.shape, 3, 5, 8))
    np.testing.assert_array_equal(label_boundaries(labels, 2), _ring(labels.shape, 3, 5, 8, 2))
    assert not label_boundaries(labels, 0).any()


def test_image_border_is_not_a_boundary():
    labels = np.full((6, 7), 3, dtype=np.int32)
    assert not label_boundaries(labels).any()


def test_touching_regions_both_get_an_edge():
    labels = np.zeros((10, 10), dtype=np.int32)
    labels[:, :5] = 1
    labels[:, 5:] = 2
    edge = label_boundaries(labels)
    expected = np.zeros_like(edge)
    expected[:, 4:6] = True
    np.testing.assert_array_equal(edge, expected)


def test_overlay_blends_interior_and_paints_edges_opaque():
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, size=(24, 32, 3), dtype=np.uint8)
    labels = np.zeros((24, 32), dtype=np.int32)
    _square(labels, 3, 2, 2, 10)
    _square(labels, 9, 12, 18, 9)
    alpha = 0.4
    out = overlay_labels(image, labels, alpha=alpha)
    assert out.shape == image.shape and out.dtype == np.uint8
    edge = label_boundaries(labels)
    for k in (3, 9):
        color = label_colors(k).astype(float)
        inner = (labels == k) & ~edge
        expected = np.rint((1 - alpha) * image[inner].astype(float) + alpha * color)
        np.testing.assert_allclose(out[inner], expected, atol=1)
        on_edge = (labels == k) & edge
        np.testing.assert_array_equal(out[on_edge], np.tile(label_colors(k), (on_edge.sum(), 1)))
    np.testing.assert_array_equal(out[labels == 0], image[labels == 0])


def test_overlay_without_boundaries_and_with_fixed_edge_colour():
    image = np.full((16, 16, 3), 100, dtype=np.uint8)
    labels = np.zeros((16, 16), dtype=np.int32)
    _square(labels, 2, 4, 4, 6)
    plain = overlay_labels(image, labels, alpha=1.0, boundaries=False)
    np.testing.assert_array_equal(plain[labels == 2], np.tile(label_colors(2), (36, 1)))
    white = overlay_labels(image, labels, boundary_color=(255, 255, 255))
    ring = _ring(labels.shape, 4, 4, 6)
    assert (white[ring] == 255).all()


def test_overlay_of_no_labels_is_the_image():
    image = np.arange(5 * 6 * 3, dtype=np.uint8).reshape(5, 6, 3)
    np.testing.assert_array_equal(overlay_labels(image, None), image)
    grey = overlay_labels(image[..., 0], None)
    assert grey.shape == (5, 6, 3)


def test_mask_boundaries_show_overlaps_with_the_highest_id_on_top():
    masks = np.zeros((2, 20, 20), dtype=bool)
    masks[0, 2:14, 2:14] = True
    masks[1, 8:18, 8:18] = True
    ids = mask_boundaries(masks)
    ring0 = _ring((20, 20), 2, 2, 12)
    ring1 = _ring((20, 20), 8, 8, 10)
    np.testing.assert_array_equal(ids != 0, ring0 | ring1)
    assert (ids[ring1] == 2).all()
    assert (ids[ring0 & ~ring1] == 1).all()
    # Mask 1's edge inside mask 2 is drawn even though the label field would hide it.
    image = np.zeros((20, 20, 3), dtype=np.uint8)
    labels = np.where(masks[1], 2, np.where(masks[0], 1, 0))
    out = overlay_labels(image, labels, masks=masks)
    hidden = ring0 & masks[1] & ~ring1
    assert hidden.any()
    np.testing.assert_array_equal(out[hidden], np.tile(label_colors(1), (hidden.sum(), 1)))


def test_bad_inputs_are_rejected():
    image = np.zeros((4, 4, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match="do not match"):
        overlay_labels(image, np.zeros((4, 5), dtype=int))
    with pytest.raises(ValueError, match="alpha"):
        overlay_labels(image, np.zeros((4, 4), dtype=int), alpha=1.5)
    with pytest.raises(ValueError, match=">= 0"):
        overlay_labels(image, -np.ones((4, 4), dtype=int))

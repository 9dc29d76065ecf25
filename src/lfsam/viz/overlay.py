"""Label overlays and mask boundaries on one view (or any 2-D image such as an EPI).

A labeled pixel is alpha-blended with its label's colour (:mod:`lfsam.viz.colors`):

    out = round((1 - alpha) * image + alpha * color[label])

and, when boundaries are drawn, the pixels on the inner edge of each region are painted in the
region's colour at full opacity. Unlabeled pixels (label 0) keep the image's colour. Inputs are
plain arrays; the output is a new ``(U, V, 3)`` uint8 image of the input's size.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from lfsam.viz.colors import label_colors, palette
from lfsam.viz.layout import _to_numpy, as_rgb_uint8

__all__ = ["blend", "label_boundaries", "mask_boundaries", "overlay_labels"]


def label_boundaries(labels: ArrayLike, width: int = 1) -> np.ndarray:
    """Inner boundary pixels of every labeled region.

    A pixel with label ``k != 0`` is on a boundary if some pixel within Chebyshev distance
    ``width`` has a different label (0 included). The image border is not a boundary (edge
    pixels are compared with themselves, ``mode="nearest"``).

    Parameters
    ----------
    labels : (U, V) array_like of int
    width : int
        Boundary thickness in pixels (>= 1); 0 gives no boundary.

    Returns
    -------
    boundary : (U, V) bool ndarray
    """
    labels = _to_numpy(labels)
    if width <= 0:
        return np.zeros(labels.shape, dtype=bool)
    size = 2 * int(width) + 1
    hi = ndimage.maximum_filter(labels, size=size, mode="nearest")
    lo = ndimage.minimum_filter(labels, size=size, mode="nearest")
    return (labels != 0) & ((hi != labels) | (lo != labels))


def mask_boundaries(masks: ArrayLike, width: int = 1) -> np.ndarray:
    """Inner boundaries of N possibly overlapping masks, as the label id drawn at each pixel.

    Mask ``n`` has label ``n + 1`` (:class:`lfsam.result.SegmentationResult`). Where boundaries of
    several masks meet, the highest id wins (smaller masks are written on top,
    docs/design.md section 3.6).

    Parameters
    ----------
    masks : (N, U, V) array_like of bool
    width : int
        Boundary thickness in pixels (>= 1).

    Returns
    -------
    ids : (U, V) int32 ndarray
        ``n + 1`` on the boundary of mask ``n``, 0 elsewhere.

    Raises
    ------
    ValueError
        If ``masks`` is not three-dimensional (a fault of the calling code).
    """
    masks = _to_numpy(masks).astype(bool)
    if masks.ndim != 3:
        raise ValueError(f"masks must have shape (N, U, V), got {masks.shape}")
    if masks.shape[0] == 0 or width <= 0:
        return np.zeros(masks.shape[1:], dtype=np.int32)
    size = 2 * int(width) + 1
    footprint = np.ones((1, size, size), dtype=bool)
    inner = ndimage.binary_erosion(masks, structure=footprint, border_value=1)
    edges = masks & ~inner
    last = masks.shape[0] - 1 - np.argmax(edges[::-1], axis=0)  # highest n with an edge
    return np.where(edges.any(axis=0), last + 1, 0).astype(np.int32)


def blend(image: np.ndarray, colors: np.ndarray, where: np.ndarray, alpha: float) -> np.ndarray:
    """``round((1 - alpha) * image + alpha * colors)`` where ``where`` is true, else ``image``.

    All of ``image``, ``colors`` are ``(U, V, 3)`` uint8 and ``where`` is ``(U, V)`` bool.
    """
    out = image.copy()
    mixed = (1.0 - alpha) * image[where].astype(np.float32) + alpha * colors[where]
    out[where] = np.clip(np.rint(mixed), 0, 255).astype(np.uint8)
    return out


def overlay_labels(
    image: ArrayLike,
    labels: ArrayLike | None,
    *,
    alpha: float = 0.5,
    boundaries: bool = True,
    boundary_width: int = 1,
    boundary_color: tuple[int, int, int] | None = None,
    masks: ArrayLike | None = None,
) -> np.ndarray:
    """Draw a label field (and region boundaries) over an image.

    Parameters
    ----------
    image : (U, V, 3) or (U, V) array_like
        The view (uint8, or float in ``[0, 1]``).
    labels : (U, V) array_like of int, or None
        Label ids, 0 = no label. None returns the image unchanged (as uint8 RGB).
    alpha : float
        Opacity of the label colour inside regions, in ``[0, 1]``.
    boundaries : bool
        Paint region edges (:func:`label_boundaries`, or of ``masks`` when given) opaque.
    boundary_width : int
        Edge thickness in pixels.
    boundary_color : (r, g, b), optional
        One colour for all edges; default: each region's own colour.
    masks : (N, U, V) array_like of bool, optional
        The masks before label fusion; when given, the edges drawn are those of every mask
        (overlaps visible, :func:`mask_boundaries`) instead of those of the label field.

    Returns
    -------
    out : (U, V, 3) uint8 ndarray
        Same size as ``image``.

    Raises
    ------
    ValueError
        ``alpha`` outside ``[0, 1]``, labels or masks of another size than the image, or a
        negative label id: faults of the calling code (``lfsam show`` checks its options and
        inputs with one-line :class:`~lfsam.errors.LfsamError` messages first).
    """
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must lie in [0, 1], got {alpha}")
    image = as_rgb_uint8(image)
    if labels is None:
        return image.copy()
    labels = _to_numpy(labels)
    if labels.shape != image.shape[:2]:
        raise ValueError(f"labels {labels.shape} do not match the image {image.shape[:2]}")
    if labels.size and labels.min() < 0:
        raise ValueError("label ids must be >= 0 (0 = no label)")
    table = palette(int(labels.max()) if labels.size else 0)
    out = blend(image, table[labels], labels != 0, alpha)
    if boundaries:
        if masks is not None:
            edge_ids = mask_boundaries(masks, boundary_width)
            if edge_ids.shape != labels.shape:
                raise ValueError(f"masks {edge_ids.shape} do not match the image {labels.shape}")
            edge = edge_ids != 0
            edge_colors = label_colors(edge_ids[edge])
        else:
            edge = label_boundaries(labels, boundary_width)
            edge_colors = table[labels[edge]]
        out[edge] = edge_colors if boundary_color is None else np.asarray(boundary_color)
    return out


def overlay_view(
    views: np.ndarray,
    labels: np.ndarray | None,
    masks,
    s: int,
    t: int,
    *,
    alpha: float = 0.5,
    boundaries: bool = True,
) -> np.ndarray:
    """:func:`overlay_labels` of view ``(s, t)`` of a light field, with its labels and masks.

    Parameters
    ----------
    views : (S, T, U, V, 3) ndarray
    labels : (S, T, U, V) ndarray, optional
    masks : PackedMasks, optional
        Per-mask outlines are drawn from ``masks.view(s, t)`` when given.
    s, t : int
        The view.
    alpha, boundaries
        As for :func:`overlay_labels`.

    Returns
    -------
    (U, V, 3) uint8 ndarray
    """
    return overlay_labels(
        as_rgb_uint8(views[s, t]),
        None if labels is None else labels[s, t],
        alpha=alpha,
        boundaries=boundaries,
        masks=None if masks is None else masks.view(s, t),
    )

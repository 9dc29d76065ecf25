"""Composing figures from images: tiles, padding, caption strips, stacking, rescaling.

Every function takes and returns ``(H, W, 3)`` uint8 arrays and documents the size of its output,
so figure sizes are predictable from their inputs. Text is drawn with Pillow's default font into
fixed-height strips (headless, no matplotlib), so text never changes a figure's size.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from lfsam.errors import LfsamError

__all__ = [
    "CAPTION_HEIGHT",
    "as_rgb_uint8",
    "blank",
    "caption",
    "hstack",
    "rescale",
    "tile",
    "vstack",
]

#: Height in pixels of a caption strip added by :func:`caption`.
CAPTION_HEIGHT = 14

Color = int | tuple[int, int, int]


def _to_numpy(array) -> np.ndarray:
    """NumPy view of an array or a (possibly CUDA) torch tensor."""
    if hasattr(array, "detach") and hasattr(array, "cpu"):
        array = array.detach().cpu().numpy()
    return np.asarray(array)


def _matching_labels(views: np.ndarray, labels) -> np.ndarray | None:
    """``labels`` as NumPy, checked to be ``[S, T, U, V]`` like ``views`` (None passes)."""
    if labels is None:
        return None
    labels = _to_numpy(labels)
    if labels.shape != views.shape[:4]:
        raise LfsamError(
            f"labels have shape {labels.shape} but the views are {views.shape[:4]}; "
            "give the labels of the same light field"
        )
    return labels


def as_rgb_uint8(image) -> np.ndarray:
    """Return ``image`` as ``(H, W, 3)`` uint8.

    Grey ``(H, W)`` images are repeated over three channels; float images in ``[0, 1]`` are scaled
    by 255 (otherwise clipped to ``[0, 255]``); torch tensors are moved to the CPU.

    Raises
    ------
    ValueError
        If ``image`` is neither ``(H, W, 3)`` nor ``(H, W)`` (a fault of the calling code).
    """
    image = _to_numpy(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=-1)
    if image.ndim != 3 or image.shape[-1] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB or (H, W) grey image, got {image.shape}")
    if image.dtype == np.uint8:
        return image
    if np.issubdtype(image.dtype, np.floating):
        scale = 255.0 if image.size and np.nanmax(image) <= 1.0 + 1e-6 else 1.0
        image = np.nan_to_num(image) * scale
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def blank(height: int, width: int, color: Color = 255) -> np.ndarray:
    """A ``(height, width, 3)`` uint8 image filled with ``color``."""
    out = np.empty((height, width, 3), dtype=np.uint8)
    out[...] = np.asarray(color, dtype=np.uint8)
    return out


def caption(
    image: np.ndarray,
    text: str,
    *,
    height: int = CAPTION_HEIGHT,
    background: Color = 255,
    color: Color = 0,
) -> np.ndarray:
    """Add a strip of ``height`` pixels holding ``text`` above ``image``.

    Returns
    -------
    out : ndarray, shape (H + height, W, 3), uint8
        Text longer than the width is cut off; the size never depends on the text.
    """
    image = as_rgb_uint8(image)
    strip = Image.fromarray(blank(height, image.shape[1], background))
    draw = ImageDraw.Draw(strip)
    font = ImageFont.load_default()
    fill = (color,) * 3 if isinstance(color, int) else tuple(color)
    draw.text((2, max(0, (height - 11) // 2)), text, fill=fill, font=font)
    return np.concatenate([np.asarray(strip), image], axis=0)


def tile(
    images: Sequence[np.ndarray | None],
    rows: int,
    cols: int,
    *,
    pad: int = 2,
    background: Color = 255,
) -> np.ndarray:
    """Place equally sized images on a ``rows x cols`` grid, row-major, with ``pad`` around each.

    Parameters
    ----------
    images : sequence of (h, w, 3) uint8 arrays or None
        At most ``rows * cols`` images of one size; ``None`` leaves a cell blank.
    rows, cols : int
        Grid size.
    pad : int
        Pixels of ``background`` between cells and around the grid.

    Returns
    -------
    figure : ndarray, shape (rows * h + (rows + 1) * pad, cols * w + (cols + 1) * pad, 3), uint8

    Raises
    ------
    ValueError
        No image, more images than cells, or images of different sizes (faults of the calling
        code).
    """
    present = [as_rgb_uint8(im) for im in images if im is not None]
    if not present:
        raise ValueError("tile() needs at least one image")
    if len(images) > rows * cols:
        raise ValueError(f"{len(images)} images do not fit a {rows}x{cols} grid")
    h, w = present[0].shape[:2]
    if any(im.shape[:2] != (h, w) for im in present):
        raise ValueError("tile() needs images of one size")
    out = blank(rows * h + (rows + 1) * pad, cols * w + (cols + 1) * pad, background)
    for index, image in enumerate(images):
        if image is None:
            continue
        r, c = divmod(index, cols)
        y, x = pad + r * (h + pad), pad + c * (w + pad)
        out[y : y + h, x : x + w] = as_rgb_uint8(image)
    return out


def hstack(images: Sequence[np.ndarray], *, gap: int = 8, background: Color = 255) -> np.ndarray:
    """Images left to right, top-aligned, ``gap`` pixels apart.

    Returns
    -------
    figure : ndarray, shape (max h_i, sum w_i + gap * (n - 1), 3), uint8
    """
    images = [as_rgb_uint8(im) for im in images]
    height = max(im.shape[0] for im in images)
    width = sum(im.shape[1] for im in images) + gap * (len(images) - 1)
    out = blank(height, width, background)
    x = 0
    for image in images:
        out[: image.shape[0], x : x + image.shape[1]] = image
        x += image.shape[1] + gap
    return out


def vstack(images: Sequence[np.ndarray], *, gap: int = 8, background: Color = 255) -> np.ndarray:
    """Images top to bottom, left-aligned, ``gap`` pixels apart.

    Returns
    -------
    figure : ndarray, shape (sum h_i + gap * (n - 1), max w_i, 3), uint8
    """
    images = [as_rgb_uint8(im) for im in images]
    width = max(im.shape[1] for im in images)
    height = sum(im.shape[0] for im in images) + gap * (len(images) - 1)
    out = blank(height, width, background)
    y = 0
    for image in images:
        out[y : y + image.shape[0], : image.shape[1]] = image
        y += image.shape[0] + gap
    return out


def rescale(image: np.ndarray, scale: float) -> np.ndarray:
    """Resize by ``scale`` (Lanczos when shrinking, nearest when enlarging to keep label edges).

    Returns
    -------
    out : ndarray, shape (max(1, round(H * scale)), max(1, round(W * scale)), 3), uint8

    Raises
    ------
    ValueError
        If ``scale`` is not positive (a fault of the calling code; ``lfsam show --scale`` is
        checked with a one-line :class:`~lfsam.errors.LfsamError` first).
    """
    image = as_rgb_uint8(image)
    if scale <= 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    if scale == 1:
        return image
    h, w = image.shape[:2]
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    method = Image.Resampling.LANCZOS if scale < 1 else Image.Resampling.NEAREST
    return np.asarray(Image.fromarray(image).resize(size, method))

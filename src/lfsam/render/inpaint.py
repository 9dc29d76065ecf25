"""OpenCV's inpainting (``cv2.inpaint``, Telea 2004), loaded on first use (``render`` extra).

:mod:`lfsam.render` fills what no view sees, and the disparity behind an object, with the
maintained implementation rather than one of its own (docs/design.md section 13).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfsam.errors import LfsamError

__all__ = ["inpaint", "require_cv2"]

#: Inpainting radius of ``cv2.inpaint``, pixels.
RADIUS = 3


def require_cv2() -> Any:
    """The ``cv2`` module, or a one-line error saying how to install it."""
    try:
        import cv2
    except ImportError as exc:
        raise LfsamError(
            "object removal needs OpenCV (cv2.inpaint): pip install 'lfsam[render]' "
            "(or opencv-python-headless)"
        ) from exc
    return cv2


def inpaint(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``image`` with the pixels of ``mask`` filled by ``cv2.inpaint`` (Telea's method).

    Parameters
    ----------
    image : (U, V, 3) uint8 or (U, V) float array
    mask : (U, V) bool array
        The pixels to fill.

    Returns
    -------
    array of ``image``'s shape (float32 for a float image, else its dtype; a copy; the known
    pixels unchanged)
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return np.array(image, copy=True)
    cv2 = require_cv2()
    if mask.all():  # nothing to fill from: a flat guess
        fill = np.nanmedian(image) if image.dtype.kind == "f" else 128
        return np.full_like(image, fill)
    hole = mask.astype(np.uint8)
    if image.dtype.kind == "f":
        # cv2.inpaint's float32 path returns garbage on flat or negative input (OpenCV 4.x and
        # 5.0): fill a 16-bit quantisation of the known range instead.
        image = np.asarray(image, dtype=np.float64)
        low, high = float(image[~mask].min()), float(image[~mask].max())
        scale = (high - low) / 60000.0 if high > low else 1.0
        levels = np.where(mask, 0, np.round((image - low) / scale) + 2000).astype(np.uint16)
        filled = cv2.inpaint(levels, hole, RADIUS, cv2.INPAINT_TELEA).astype(np.float64)
        out = np.where(mask, (filled - 2000) * scale + low, image)
        return out.astype(np.float32)
    return cv2.inpaint(np.ascontiguousarray(image), hole, RADIUS, cv2.INPAINT_TELEA)

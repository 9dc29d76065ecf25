"""Moving center-view prompts into another view by disparity, for the video baseline.

The baseline of the paper (section 4) starts tracking on the first view of the snake. When the
user prompts the center view, the prompts are carried to the start view with the package's
disparity convention (:mod:`lfsam.geometry`; docs/design.md section 1): a center pixel ``(u, v)``
with disparity ``d`` is seen in view ``(s, t)`` at ``(u - d (s - s_c), v - d (t - t_c))``.

- A point moves by the disparity of the center pixel under it (nearest pixel).
- A box moves rigidly by the median disparity of the center pixels inside it (a box holds its
  object and some background; the median follows whichever covers more of it).

Prompts that leave the view are clamped to its border, so every object still gets a prompt (the
object may simply not be visible in the start view; tracking then starts from a poor mask, as it
would for a user prompting that view).
"""

from __future__ import annotations

import numpy as np

from lfsam.geometry import project_pixels
from lfsam.segmenters.base import Prompts

__all__ = ["transfer_prompts"]


def transfer_prompts(
    prompts: Prompts,
    disparity: np.ndarray,
    offset: tuple[float, float],
) -> Prompts:
    """Carry prompts of the center view into a view at angular ``offset`` from it.

    Parameters
    ----------
    prompts : Prompts
        Points ``(x, y)`` = (column, row) and/or boxes ``(x0, y0, x1, y1)`` in center-view pixels.
    disparity : (U, V) float ndarray
        Center-view disparity in the package convention.
    offset : (ds, dt)
        View-row and view-column steps from the center to the target view.

    Returns
    -------
    Prompts
        The same prompts (same labels) in target-view pixels, clamped to the view.
    """
    disparity = np.asarray(disparity, dtype=np.float32)
    height, width = disparity.shape
    ds, dt = float(offset[0]), float(offset[1])
    points = boxes = None
    if prompts.points is not None:
        xy = prompts.points.astype(np.float64)
        rows = np.clip(np.rint(xy[..., 1]), 0, height - 1).astype(np.int64)
        cols = np.clip(np.rint(xy[..., 0]), 0, width - 1).astype(np.int64)
        u, v = project_pixels(xy[..., 1], xy[..., 0], disparity[rows, cols], ds, dt)
        points = np.stack([np.clip(v, 0, width - 1), np.clip(u, 0, height - 1)], axis=-1)
    if prompts.boxes is not None:
        boxes = np.stack([_move_box(box, disparity, ds, dt) for box in prompts.boxes])
    return Prompts(points=points, point_labels=prompts.point_labels, boxes=boxes)


def _move_box(box: np.ndarray, disparity: np.ndarray, ds: float, dt: float) -> np.ndarray:
    """Shift one box by the median disparity inside it, clamped to the view (never empty)."""
    height, width = disparity.shape
    x0, y0, x1, y1 = (float(c) for c in box)
    r0, r1 = int(np.clip(np.floor(y0), 0, height - 1)), int(np.clip(np.ceil(y1), 0, height - 1))
    c0, c1 = int(np.clip(np.floor(x0), 0, width - 1)), int(np.clip(np.ceil(x1), 0, width - 1))
    d = float(np.median(disparity[r0 : r1 + 1, c0 : c1 + 1]))
    (ya, yb), (xa, xb) = project_pixels(np.array([y0, y1]), np.array([x0, x1]), d, ds, dt)
    xa, xb = np.clip([xa, xb], 0, width - 1)
    ya, yb = np.clip([ya, yb], 0, height - 1)
    # A box pushed past the border keeps a width of at least one pixel on the border.
    if xb <= xa:
        xa, xb = (xa - 1.0, xa) if xa >= 1.0 else (xa, xa + 1.0)
    if yb <= ya:
        ya, yb = (ya - 1.0, ya) if ya >= 1.0 else (ya, ya + 1.0)
    return np.array([xa, ya, xb, yb], dtype=np.float32)

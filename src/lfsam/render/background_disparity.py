"""The disparity of what lies behind objects (docs/design.md section 13).

Never the object's own disparity: behind an object, the surface its rim shows continues. In the
center view, the disparity estimated from the views is kept wherever the objects are not (their
masks grown by a few pixels, where estimates bleed across the edge) and filled inside from
around: a plane fitted robustly to the rim behind the object, plus OpenCV's inpainting of what
departs from it (:mod:`lfsam.render.inpaint`): a plane behind the object is filled exactly.
Any other view gets the center's disparity forward-warped into it (its own rim, even where
nearer objects hide the background from the center view), filled in its own object pixels
the same way.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.disparity import warp_center_disparity
from lfsam.render.inpaint import inpaint

__all__ = ["background_center", "dilate", "rim_disparity", "view_backgrounds"]

#: Pixels by which the object masks grow before their disparity is replaced.
GAP = 2
#: Disparity above the object's (95th percentile) that marks a nearer surface, pixels.
NEARER = 0.1
#: Width of the ring around an object from which the surface behind it is fitted, pixels.
RING = 6


def dilate(masks: torch.Tensor, radius: int) -> torch.Tensor:
    """Bool masks ``(..., U, V)`` grown by ``radius`` pixels (a square neighbourhood)."""
    if radius <= 0:
        return masks.bool()
    shape = masks.shape
    flat = masks.reshape(-1, 1, *shape[-2:]).float()
    grown = F.max_pool2d(flat, 2 * radius + 1, stride=1, padding=radius)
    return grown.reshape(shape) > 0.5


def rim_disparity(mask: np.ndarray, disparity: np.ndarray, width: int = 3) -> float | None:
    """The disparity of the surface an object's rim shows (median of a ring around it).

    Ring pixels nearer than the object (larger disparity than its median) are left out: they
    are in front of it, not behind. None for an empty mask or ring.
    """
    mask_t = torch.from_numpy(np.asarray(mask, dtype=bool))
    if not mask_t.any():
        return None
    ring = dilate(mask_t, GAP + width) & ~dilate(mask_t, GAP)
    disparity = np.asarray(disparity, dtype=np.float32)
    values = disparity[ring.numpy()]
    inside = disparity[np.asarray(mask, dtype=bool)]
    inside = inside[np.isfinite(inside)]
    values = values[np.isfinite(values)]
    if inside.size:
        behind = values[values < np.median(inside)]
        values = behind if behind.size else values
    return float(np.median(values)) if values.size else None


def background_center(disparity: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The center view's disparity with the objects of ``mask`` taken out (filled from around).

    Parameters
    ----------
    disparity : (U, V) float array
        The center view's disparity (estimated from the views, or ground truth).
    mask : (U, V) bool array
        The objects in the center view.

    Returns
    -------
    (U, V) float32 array
    """
    disparity = np.asarray(disparity, dtype=np.float32)
    mask = np.asarray(mask, dtype=bool)
    hole_t = dilate(torch.from_numpy(mask), GAP)
    hole = hole_t.numpy() | ~np.isfinite(disparity)
    if not hole.any():
        return disparity.copy()
    plane = _rim_plane(disparity, mask, hole)
    # What lies in front of the object around it (nearer objects) is not what lies behind it:
    # left out of the fill as well.
    inside = disparity[mask & np.isfinite(disparity)]
    unknown = hole.copy()
    if inside.size:
        near = dilate(torch.from_numpy(hole), RING).numpy() & (disparity >= np.median(inside))
        unknown |= near
    residual = np.where(unknown, 0.0, disparity - plane).astype(np.float32)
    filled = plane + inpaint(residual, unknown)
    if inside.size:  # the grown mask's pixels of nearer objects keep their own disparity
        hole &= ~(disparity > np.percentile(inside, 95) + NEARER)
    return np.where(hole, filled, disparity).astype(np.float32)


def _rim_plane(disparity: np.ndarray, mask: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """A plane ``a + b u + c v`` fitted robustly to the ring around ``hole`` that lies behind
    the object (disparity below the object's median), evaluated everywhere.

    Inpainting the residual from it (:func:`background_center`) fills a planar surface behind
    the object exactly, and follows the rim's own values where the rim shows several surfaces.
    """
    height, width = disparity.shape
    ring = (dilate(torch.from_numpy(hole), RING).numpy() & ~hole) & np.isfinite(disparity)
    inside = disparity[mask & np.isfinite(disparity)]
    if inside.size:
        behind = ring & (disparity < np.median(inside))
        ring = behind if behind.sum() >= 3 else ring
    rows, cols = np.nonzero(ring)
    if rows.size < 3:
        value = float(np.median(disparity[ring])) if rows.size else 0.0
        return np.full((height, width), value, dtype=np.float32)
    design = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(np.float64)
    values = disparity[rows, cols].astype(np.float64)
    use = np.ones(rows.size, dtype=bool)
    for _ in range(4):  # least squares, dropping the rim of other surfaces
        coef = np.linalg.lstsq(design[use], values[use], rcond=None)[0]
        error = np.abs(design @ coef - values)
        spread = max(float(np.median(error[use])) * 3.0, 0.02)
        use = error <= spread
        if use.sum() < 3:
            break
    uu, vv = np.mgrid[0:height, 0:width]
    return (coef[0] + coef[1] * uu + coef[2] * vv).astype(np.float32)


def view_backgrounds(
    center: np.ndarray, masks: np.ndarray, offsets: torch.Tensor,
    device: str | torch.device | None = None,
) -> torch.Tensor:
    """The background disparity of every view: the center's disparity carried into the view
    (:func:`lfsam.disparity.warp_center_disparity`: z-buffer, disocclusions filled from the
    farther side), the view's own object pixels then filled from its own rim
    (:func:`background_center`). Each view's rim shows what lies behind the object there, even
    where nearer objects hide it from the center view.

    Parameters
    ----------
    center : (U, V) float array
        The center view's disparity (estimated from the views, or ground truth).
    masks : (N, U, V) bool array
        The objects in each view.
    offsets : (N, 2) tensor
        ``(ds, dt)`` of each view from the center view.
    device : str or torch.device, optional
        Where the warps run.

    Returns
    -------
    (N, U, V) float32 tensor
    """
    center = np.asarray(center, dtype=np.float32)
    finite = np.where(np.isfinite(center), center, np.nanmin(center[np.isfinite(center)]))
    out = []
    for k, (ds, dt) in enumerate(torch.as_tensor(offsets).tolist()):
        view = finite if ds == 0 and dt == 0 else warp_center_disparity(
            finite, (ds, dt), device=device)[0]
        out.append(background_center(view, masks[k]))
    return torch.from_numpy(np.stack(out))

"""The disparity of what lies behind objects (docs/design.md section 13).

Never the object's own disparity: behind an object, the surface its rim shows continues. In the
center view, the disparity estimated from the views is kept wherever the objects are not (their
masks grown by a few pixels, where estimates bleed across the edge) and filled inside from
around: a plane fitted robustly to the rim behind the object, plus OpenCV's inpainting of what
departs from it (:mod:`lfsam.render.inpaint`): a plane behind the object is filled exactly.
Any other view looks the background up in the center: a background point seen in view
``(s, t)`` at ``(u, v)`` with disparity ``d`` is seen by the center view at
``(u + d ds, v + d dt)`` (docs/design.md section 1); ``d`` is found by a few fixed-point steps.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.render.inpaint import inpaint

__all__ = ["background_center", "dilate", "rim_disparity", "view_backgrounds"]

#: Pixels by which the object masks grow before their disparity is replaced.
GAP = 2
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
    residual = np.where(hole, 0.0, disparity - plane).astype(np.float32)
    return (plane + inpaint(residual, hole)).astype(np.float32)


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
    center: np.ndarray, offsets: torch.Tensor, steps: int = 4
) -> torch.Tensor:
    """The background disparity of every view, looked up in the center's.

    Parameters
    ----------
    center : (U, V) float array
        :func:`background_center`.
    offsets : (N, 2) tensor
        ``(ds, dt)`` of each view from the center view.
    steps : int
        Fixed-point steps ``d <- center(u + d ds, v + d dt)``.

    Returns
    -------
    (N, U, V) float32 tensor
    """
    height, width = center.shape
    base = torch.from_numpy(np.asarray(center, dtype=np.float32))[None, None]
    offsets = torch.as_tensor(offsets, dtype=torch.float32)
    n = offsets.shape[0]
    rows = torch.arange(height, dtype=torch.float32)[:, None].expand(height, width)
    cols = torch.arange(width, dtype=torch.float32)[None, :].expand(height, width)
    d = base[0].expand(n, height, width).clone()
    ds = offsets[:, 0, None, None]
    dt = offsets[:, 1, None, None]
    source = base.expand(n, 1, height, width)
    for _ in range(steps):
        u = rows + d * ds
        v = cols + d * dt
        grid = torch.stack([2 * v / max(width - 1, 1) - 1, 2 * u / max(height - 1, 1) - 1], -1)
        d = F.grid_sample(source, grid, mode="bilinear", padding_mode="border",
                          align_corners=True)[:, 0]
    return d

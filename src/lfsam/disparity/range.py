"""Automatic disparity range: a coarse photo-consistency search on downsampled EPI stacks.

The sheared structure tensor needs to know which disparities to shear to. This module finds them
from the data with a cheap plane sweep (Collins, "A space-sweep approach to true multi-image
matching", CVPR 1996): for candidate disparities ``d`` on a coarse grid, every view of the center
row and column is shifted back onto the center view (center pixel ``x`` is seen in view ``n`` at
``x - d (n - n_c)``, DESIGN.md section 1), the mean absolute difference to the center view is
box-filtered, and each pixel takes the winner. The range is the 1st to 99th percentile of the
winners over pixels with a clear minimum, widened by one search step on both sides.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.disparity.epi import epi_stacks
from lfsam.disparity.filters import box_blur
from lfsam.lightfield import LightField

__all__ = ["DEFAULT_MAX_DISPARITY", "estimate_disparity_range"]

#: Largest |disparity| searched by default, pixels per view step.
DEFAULT_MAX_DISPARITY = 12.0

# Low-resolution target for the search (pixels along the shorter side).
_TARGET_SIZE = 128
# A winner counts when its cost is below this fraction of the pixel's median cost.
_DISTINCT = 0.6
# Fallback when no pixel has texture: the structure tensor's own working range.
_FALLBACK = (-1.0, 1.0)


def _shift_last_axis(images: torch.Tensor, shifts: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Sample ``images[n, ..., x - shifts[n]]`` by linear interpolation.

    Returns the sampled values and a mask of samples that fall inside the image.
    """
    cols = images.shape[-1]
    x = torch.arange(cols, device=images.device, dtype=torch.float32)
    src = x - shifts.view(-1, *([1] * (images.ndim - 1)))
    valid = (src >= 0) & (src <= cols - 1)
    src = src.clamp(0, cols - 1)
    left = src.floor().long().clamp(max=cols - 2) if cols > 1 else src.floor().long()
    frac = src - left
    index = left.expand_as(images)
    a = torch.gather(images, -1, index)
    b = torch.gather(images, -1, (index + 1).clamp(max=cols - 1))
    return a + frac * (b - a), valid.expand_as(images)


def estimate_disparity_range(
    views: LightField | np.ndarray,
    *,
    device: str | torch.device | None = None,
    max_disparity: float = DEFAULT_MAX_DISPARITY,
    percentiles: tuple[float, float] = (1.0, 99.0),
) -> tuple[float, float]:
    """Estimate the range of disparities present in the center view.

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field (at least three views in a row or column).
    device : str or torch.device, optional
        Where to compute; default CUDA when present, else the CPU.
    max_disparity : float
        Largest |disparity| searched, pixels per view step (also capped so that the outermost
        view's shift stays below a quarter of the image).
    percentiles : (low, high)
        Percentiles of the per-pixel winners taken as the range ends.

    Returns
    -------
    (lo, hi) : tuple of float
        Pixels per view step, ``lo < hi``, widened by one search step on each side.
    """
    stacks = epi_stacks(views, device=device)
    winners = []
    step_used = 0.5
    with torch.no_grad():
        for stack in stacks:
            images = stack.images[:, 0]  # (N, rows, cols)
            max_offset = float(stack.offsets.abs().max())
            rows, cols = images.shape[-2:]
            factor = max(1, min(math.ceil(min(rows, cols) / _TARGET_SIZE), int(2 * max_offset)))
            if factor > 1:
                images = F.avg_pool2d(images[:, None], factor, ceil_mode=True)[:, 0]
            # one low-resolution pixel of shift at the outermost view, at most 1 px per view step
            step = factor / (2.0 * max_offset)
            step_used = max(step_used, step)
            limit = min(max_disparity, 0.25 * min(cols, rows) / max_offset)
            count = max(1, int(limit / step))
            grid = step * torch.arange(-count, count + 1, device=images.device, dtype=torch.float32)
            others = torch.ones(images.shape[0], dtype=torch.bool, device=images.device)
            others[stack.center] = False
            center = images[stack.center]
            moving = images[others]
            offsets = stack.offsets[others] / factor
            costs = []
            for d in grid:
                aligned, valid = _shift_last_axis(moving, d * offsets)
                diff = (aligned - center).abs() * valid
                cost = diff.sum(0) / valid.sum(0).clamp(min=1)
                # pixels no view covers get an uninformative cost
                cost = torch.where(valid.any(0), cost, torch.full_like(cost, math.inf))
                costs.append(cost)
            volume = box_blur(torch.nan_to_num(torch.stack(costs), posinf=1.0), 2)
            best, arg = volume.min(0)
            median = volume.median(0).values
            gy, gx = torch.gradient(center)
            texture = (gx.abs() + gy.abs()) > 2.0 / 255.0
            reliable = (best < _DISTINCT * median) & texture
            winners.append(grid[arg][reliable])
    values = torch.cat(winners)
    if values.numel() < 16:
        return _FALLBACK
    lo, hi = np.percentile(values.cpu().numpy(), percentiles)
    lo = math.floor((lo - step_used) * 4.0) / 4.0
    hi = math.ceil((hi + step_used) * 4.0) / 4.0
    return float(lo), float(hi)

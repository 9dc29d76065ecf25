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
# Finest search step (pixels per view step): the range is widened by one step anyway.
_MIN_STEP = 0.5
# Candidates swept per batched resampling call (bounds the memory of the sweep).
_CHUNK = 8
# Fallback when no pixel has texture: the structure tensor's own working range.
_FALLBACK = (-1.0, 1.0)


def _sweep_costs(
    moving: torch.Tensor, center: torch.Tensor, offsets: torch.Tensor, grid: torch.Tensor
) -> torch.Tensor:
    """Mean absolute difference to ``center`` of the views ``moving`` shifted back by each
    disparity of ``grid``: view ``n`` sampled at ``x - d * offsets[n]`` (linear interpolation).

    Returns ``(K, rows, cols)``; pixels that no view covers get cost 1 (uninformative).
    """
    count, rows, cols = moving.shape
    x = torch.arange(cols, device=moving.device, dtype=torch.float32)
    # sample positions for every (candidate, view): (K, N, cols)
    src = x - grid[:, None, None] * offsets[None, :, None]
    valid = (src >= 0) & (src <= cols - 1)
    norm_x = 2.0 * src / max(cols - 1, 1) - 1.0
    norm_y = 2.0 * torch.arange(rows, device=moving.device, dtype=torch.float32) / max(
        rows - 1, 1
    ) - 1.0
    k = grid.numel()
    sample = torch.stack(
        torch.broadcast_tensors(
            norm_x[:, :, None, :].expand(k, count, rows, cols),
            norm_y[None, None, :, None].expand(k, count, rows, cols),
        ),
        dim=-1,
    ).reshape(k * count, rows, cols, 2)
    source = moving[None].expand(k, count, rows, cols).reshape(k * count, 1, rows, cols)
    aligned = F.grid_sample(source, sample, align_corners=True).view(k, count, rows, cols)
    weight = valid[:, :, None, :].float()
    diff = (aligned - center).abs() * weight
    total = weight.sum(1)
    return torch.where(total > 0, diff.sum(1) / total.clamp(min=1), torch.ones_like(total))


def estimate_disparity_range(
    views: LightField | np.ndarray,
    *,
    device: str | torch.device | None = None,
    max_disparity: float = DEFAULT_MAX_DISPARITY,
    percentiles: tuple[float, float] = (1.0, 99.0),
    view: tuple[int, int] | None = None,
) -> tuple[float, float]:
    """Estimate the range of disparities present in a view (default: the center view).

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
    view : (s, t), optional
        The reference view (0-based view row and column); default the center. Only present
        views of its row and column are swept.

    Returns
    -------
    (lo, hi) : tuple of float
        Pixels per view step, ``lo < hi``, widened by one search step on each side.
    """
    stacks = epi_stacks(views, device=device, view=view)
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
            step = max(_MIN_STEP, factor / (2.0 * max_offset))
            step_used = max(step_used, step)
            limit = min(max_disparity, 0.25 * cols / max_offset)
            count = max(1, int(limit / step))
            grid = step * torch.arange(-count, count + 1, device=images.device, dtype=torch.float32)
            others = stack.present.clone()
            others[stack.center] = False
            center = images[stack.center]
            moving = images[others]
            offsets = stack.offsets[others] / factor
            costs = torch.cat(
                [
                    _sweep_costs(moving, center, offsets, chunk)
                    for chunk in grid.split(_CHUNK)
                ]
            )
            volume = box_blur(costs, 2)
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

"""Cross-view consistency of a light-field segmentation: SIoU and LPP (paper section 4.1).

Both work on the masks of every view projected into the center view with ground-truth disparity
(:mod:`lfsam.metrics.projection`).

SIoU (self IoU; paper section 4.1, after the self-similarity of Zhu et al., CVPR 2017, with IoU in
place of centroid distance). For each mask ``n`` (every label present in any view) and each view
``(s, t)`` other than the center whose projected mask ``P_n(s, t)`` is non-empty, take
``IoU(P_n(s, t), P_n(center))``; the mask's score is the mean over those views and SIoU is the
mean over masks. Choices made here:

- The center view is left out of each mask's mean: its projection is itself, so it would add a
  constant 1 and inflate small grids (the authors' self-similarity also divided by the number of
  views minus one).
- A mask absent from the center view has IoU 0 in every view where it appears, so it scores 0
  (docs/design.md section 5).
- A mask with no non-empty projected mask outside the center view (seen only in the center, or
  only in pixels that project out of the center frame) has nothing to be compared with and is
  left out of the mean. With no such comparable mask at all, SIoU is NaN.

LPP (labels per pixel; Khan et al., "View-consistent 4D light field superpixel segmentation",
ICCV 2019): the number of distinct labels that one scene point, i.e. one center pixel, receives
from all views (the center included) after projection, averaged over the center pixels that
receive at least one label. 1 is ideal; NaN when no pixel receives a label. Occluded surfaces land
on their occluders, so even the ground-truth label field scores a little above 1. (The authors'
code averaged the number of overlapping projected masks per pixel instead; we follow the paper's
text and Khan et al.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from lfsam.metrics.projection import (
    BATCH_PIXELS,
    distinct,
    iter_projected_views,
    project_view_to_center,
)
from lfsam.precision import wide_float

__all__ = ["ConsistencyScores", "consistency_metrics"]

# Largest (center pixels x labels) boolean table kept dense for LPP (bytes); beyond it the
# distinct (pixel, label) pairs are merged by sorting instead.
DENSE_LIMIT = 1 << 28


@dataclass
class ConsistencyScores:
    """SIoU and LPP of one label field, with the per-mask detail.

    Attributes
    ----------
    siou : float
        Mean self IoU over comparable masks (NaN if none).
    lpp : float
        Mean number of distinct labels per labeled center pixel (NaN if none).
    mask_siou : (K,) float64 ndarray
        Score of each compact label (index 0, "unlabeled", and masks left out are NaN).
    mask_views : (K,) int64 ndarray
        Number of non-center views in which each mask's projection is non-empty.
    """

    siou: float
    lpp: float
    mask_siou: np.ndarray
    mask_views: np.ndarray


def consistency_metrics(
    labels: torch.Tensor,
    disparity: torch.Tensor,
    num_labels: int,
    dense_limit: int = DENSE_LIMIT,
    batch_pixels: int = BATCH_PIXELS,
) -> ConsistencyScores:
    """SIoU and LPP of a label field (paper section 4.1; definitions in the module docstring).

    Parameters
    ----------
    labels : (S, T, U, V) integer tensor
        Compact labels ``0 .. num_labels - 1`` (see :func:`lfsam.metrics.labelmap.compact_labels`),
        0 = unlabeled.
    disparity : (S, T, U, V) float tensor
        Ground-truth disparity of every view, same device.
    num_labels : int
        ``K``, one more than the largest compact label.
    dense_limit : int
        Size in bytes up to which LPP uses a dense ``(U V) x K`` hit table; above, sorted merging.
    batch_pixels : int
        About how many pixels are projected at once (see
        :func:`lfsam.metrics.projection.iter_projected_views`).

    Returns
    -------
    ConsistencyScores
    """
    s_count, t_count, height, width = labels.shape
    s_c, t_c = s_count // 2, t_count // 2
    device = labels.device
    k = int(num_labels)
    npix = height * width

    center_pixels, center_labels = project_view_to_center(
        labels[s_c, t_c], disparity[s_c, t_c], 0, 0, k
    )
    center_map = torch.zeros(npix, dtype=torch.long, device=device)
    center_map[center_pixels] = center_labels
    wide = wide_float(device)
    center_area = torch.bincount(center_labels, minlength=k).to(wide)

    iou_sum = torch.zeros(k, dtype=wide, device=device)
    view_count = torch.zeros(k, dtype=torch.long, device=device)
    dense = npix * k <= dense_limit
    hits = torch.zeros(npix * k, dtype=torch.bool, device=device) if dense else None
    merged = torch.zeros(0, dtype=torch.long, device=device)

    for batch in iter_projected_views(labels, disparity, k, batch_pixels):
        keys = batch.pixels * k + batch.labels
        if dense:
            hits[keys] = True
        else:
            merged = distinct(torch.cat([merged, keys]))
        count = len(batch.views)
        compared = torch.tensor([view != (s_c, t_c) for view in batch.views], device=device)
        cell = batch.view * k + batch.labels  # (view in batch, label)
        area = torch.bincount(cell, minlength=count * k).view(count, k).to(wide)
        agree = center_map[batch.pixels] == batch.labels
        inter = torch.bincount(cell[agree], minlength=count * k).view(count, k).to(wide)
        union = area + center_area - inter
        seen = (area > 0) & compared[:, None]
        iou_sum += torch.where(seen, inter / union.clamp(min=1), torch.zeros_like(inter)).sum(0)
        view_count += seen.sum(0)

    mask_siou = (iou_sum / view_count.clamp(min=1)).cpu().numpy()
    mask_views = view_count.cpu().numpy()
    mask_siou[mask_views == 0] = np.nan
    mask_siou[0] = np.nan
    scored = mask_siou[1:][~np.isnan(mask_siou[1:])]
    siou = float(scored.mean()) if scored.size else math.nan

    if dense:
        # Column 0 is never hit (label 0 is not projected). Summing a bool table widens it to
        # int64, so sum a block of pixels at a time.
        rows = max(1, (1 << 22) // k)
        per_pixel = torch.cat([block.sum(dim=1) for block in torch.split(hits.view(npix, k), rows)])
    else:
        per_pixel = torch.bincount(torch.div(merged, k, rounding_mode="floor"), minlength=npix)
    labeled = per_pixel > 0
    lpp = float(per_pixel[labeled].to(wide).mean()) if bool(labeled.any()) else math.nan
    return ConsistencyScores(siou=siou, lpp=lpp, mask_siou=mask_siou, mask_views=mask_views)

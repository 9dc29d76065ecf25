"""Object-level scores for objects the center view may not see (docs/design.md section 8).

The paper's SIoU (section 4.1, :mod:`lfsam.metrics.consistency`) compares each mask's projection
from every other view with its center-view mask. A mask absent from the center view (an object
hidden there behind a nearer one, found in an outer view) has an empty center mask, so its IoU is
0 in every view where it appears and it scores 0: the paper's definition, kept unchanged. SIoU
therefore penalises recovering hidden objects. Two scores are reported beside it:

- **Object recall**: a ground-truth object (label >= 1) counts when some view shows at least
  ``min_area`` of its pixels; it is recalled when some predicted label (>= 1) overlaps it with
  IoU >= 0.5 in the view where the object is largest (the first such view in row-major order on
  ties). Recall is the fraction of counted objects recalled (NaN when none counts). An object
  seen only in outer views is judged in an outer view, so it counts like any other.
- **SIoU over center-present masks**: the mean of the per-mask SIoU over the predicted masks that
  have at least one pixel in the center view (the masks SIoU leaves out are left out here too).
  It equals SIoU when every mask is in the center view.

Both take compact labels (:func:`lfsam.metrics.labelmap.compact_labels`); recall needs no
disparity. Counted per view with one ``bincount`` per block of views, on any torch device.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from lfsam.metrics.consistency import ConsistencyScores
from lfsam.precision import wide_float

__all__ = ["ObjectRecall", "center_present_siou", "default_min_area", "object_recall"]

#: IoU at which a predicted label recalls a ground-truth object.
MATCH_IOU = 0.5

_CHUNK = 1 << 22


def default_min_area(view_shape: tuple[int, int]) -> int:
    """Default ``min_area``: 0.1 % of a view's pixels, at least 4 (77 pixels at 240x320)."""
    return max(4, math.ceil(1e-3 * view_shape[0] * view_shape[1]))


@dataclass
class ObjectRecall:
    """Object recall with the per-object detail (indices are compact ground-truth labels).

    Attributes
    ----------
    recall : float
        Fraction of counted objects recalled; NaN when no object counts.
    counted : (G,) bool ndarray
        Objects shown with at least ``min_area`` pixels in some view (index 0 is False).
    recalled : (G,) bool ndarray
        Counted objects matched with IoU >= 0.5 in their largest view.
    best_view : (G, 2) int ndarray
        ``(s, t)`` of the view where each object is largest.
    best_iou : (G,) float ndarray
        The largest IoU of a predicted label with the object in that view.
    """

    recall: float
    counted: np.ndarray
    recalled: np.ndarray
    best_view: np.ndarray
    best_iou: np.ndarray


def _per_view_counts(labels: torch.Tensor, k: int) -> torch.Tensor:
    """``(views, k)`` pixel count of each label in each view, labels ``(views, pixels)``."""
    views, pixels = labels.shape
    block = max(1, _CHUNK // max(pixels, 1))
    counts = []
    for start in range(0, views, block):
        part = labels[start : start + block].long()
        offset = torch.arange(part.shape[0], device=part.device)[:, None] * k
        flat = (part + offset).reshape(-1)
        counts.append(torch.bincount(flat, minlength=part.shape[0] * k).view(-1, k))
    return torch.cat(counts)


def object_recall(
    predicted: torch.Tensor,
    truth: torch.Tensor,
    num_predicted: int,
    num_truth: int,
    min_area: int | None = None,
) -> ObjectRecall:
    """Object recall of a label field (definition in the module docstring).

    Parameters
    ----------
    predicted, truth : (S, T, U, V) integer tensors
        Compact predicted labels ``0 .. num_predicted - 1`` and ground-truth labels
        ``0 .. num_truth - 1``; 0 = unlabeled / no ground truth.
    num_predicted, num_truth : int
        Number of compact labels of each.
    min_area : int, optional
        Pixels an object must show in some view to count (default :func:`default_min_area`).

    Returns
    -------
    ObjectRecall
    """
    s_count, t_count, height, width = truth.shape
    if min_area is None:
        min_area = default_min_area((height, width))
    views = s_count * t_count
    p_count, g_count = int(num_predicted), int(num_truth)
    pred = predicted.reshape(views, -1)
    gt = truth.reshape(views, -1)
    gt_area = _per_view_counts(gt, g_count)  # (views, G)
    pred_area = _per_view_counts(pred, p_count)  # (views, P)
    largest, best = gt_area.max(dim=0)  # first maximal view on ties
    counted = largest >= int(min_area)
    counted[0] = False

    # |p ∩ g| in g's largest view, for every (g, p).
    inter = torch.zeros(g_count * p_count, dtype=torch.long, device=truth.device)
    block = max(1, _CHUNK // max(gt.shape[1], 1))
    for start in range(0, views, block):
        g_part, p_part = gt[start : start + block].long(), pred[start : start + block].long()
        view = torch.arange(start, start + g_part.shape[0], device=truth.device)[:, None]
        keep = (best[g_part] == view) & (g_part > 0)
        pairs = g_part[keep] * p_count + p_part[keep]
        inter += torch.bincount(pairs, minlength=g_count * p_count)
    wide = wide_float(truth.device)
    inter_f = inter.view(g_count, p_count).to(wide)
    union = largest.to(wide)[:, None] + pred_area[best].to(wide) - inter_f
    iou = inter_f / union.clamp(min=1)
    iou[:, 0] = 0.0  # "unlabeled" recalls nothing
    best_iou = iou.max(dim=1).values
    recalled = counted & (best_iou >= MATCH_IOU)
    n_counted = int(counted.sum())
    recall = float(recalled.sum()) / n_counted if n_counted else math.nan
    best_st = torch.stack([best // t_count, best % t_count], dim=1)
    return ObjectRecall(
        recall=recall,
        counted=counted.cpu().numpy(),
        recalled=recalled.cpu().numpy(),
        best_view=best_st.cpu().numpy(),
        best_iou=best_iou.cpu().numpy(),
    )


def center_present_siou(scores: ConsistencyScores, predicted: torch.Tensor) -> float:
    """SIoU over the predicted masks present in the center view (module docstring).

    Parameters
    ----------
    scores : ConsistencyScores
        From :func:`lfsam.metrics.consistency.consistency_metrics` on the same labels.
    predicted : (S, T, U, V) integer tensor
        The compact predicted labels scored there.

    Returns
    -------
    float
        Mean per-mask SIoU over the scored masks with a center-view pixel; NaN when none.
    """
    s_count, t_count = predicted.shape[:2]
    center = predicted[s_count // 2, t_count // 2].reshape(-1).long()
    k = len(scores.mask_siou)
    present = (torch.bincount(center, minlength=k) > 0).cpu().numpy()
    chosen = scores.mask_siou[present & ~np.isnan(scores.mask_siou)]
    return float(chosen.mean()) if chosen.size else math.nan

"""Per-view accuracy against ground truth: how right each view's masks are, not only how well
the views agree (docs/design.md section 5).

SIoU (paper section 4.1) measures agreement between views: masks carried between views without
refinement agree perfectly with each other even where they are wrong. :func:`per_view_iou` asks
instead how well each predicted object matches its ground-truth object in every view. Each
predicted object is matched to the ground-truth object it covers most in its reference view
(where it was segmented; the center view when not given; a tie goes to the candidate with the
best IoUs, so that the scores never depend on how labels are numbered), and its IoU with that
object is taken in every view present. A view's score is the mean over the objects present
there (in the prediction or the matched ground truth); the light field's scores are the mean and
the worst view. This is the metric by which refining only some views is judged (issue 24).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["ViewAccuracy", "per_view_iou"]

View = tuple[int, int]


def _nanmean(values: np.ndarray) -> float:
    """Mean of the finite values (-1 when there is none)."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else -1.0


@dataclass(frozen=True)
class ViewAccuracy:
    """Per-view IoU against ground truth.

    Attributes
    ----------
    per_view : (S, T) float ndarray
        Mean IoU of the objects in each view; NaN where no object is present, or the view is
        absent.
    per_object : dict obj_id -> (S, T) float ndarray
        Each predicted object's IoU with its matched ground-truth object (NaN where both are
        empty or the view is absent).
    matched : dict obj_id -> int
        The ground-truth label each predicted object is matched to (0: it covers no labelled
        pixel in its reference view).
    """

    per_view: np.ndarray
    per_object: dict[int, np.ndarray]
    matched: dict[int, int]

    @property
    def mean(self) -> float:
        """Mean over the views (NaN without any object)."""
        values = self.per_view[np.isfinite(self.per_view)]
        return float(values.mean()) if values.size else float("nan")

    @property
    def worst(self) -> float:
        """The worst view's score (NaN without any object)."""
        values = self.per_view[np.isfinite(self.per_view)]
        return float(values.min()) if values.size else float("nan")


def per_view_iou(
    labels: np.ndarray,
    gt_labels: np.ndarray,
    reference_views: Mapping[int, View] | None = None,
    present: np.ndarray | None = None,
) -> ViewAccuracy:
    """Per-view IoU of each predicted object with its ground-truth object (module docstring).

    Parameters
    ----------
    labels : (S, T, U, V) integer ndarray
        Predicted labels, 0 = unlabeled (a result's ``labels``).
    gt_labels : (S, T, U, V) integer ndarray
        Ground-truth labels, 0 = unlabeled.
    reference_views : mapping obj_id -> (s, t), optional
        Where each object was segmented (a result's ``meta["objects"]``); default the center.
    present : (S, T) bool ndarray, optional
        Views present (absent views score NaN); default all.

    Returns
    -------
    ViewAccuracy

    Raises
    ------
    ValueError
        If the two label fields differ in shape (the caller's data are mismatched).

    Examples
    --------
    >>> gt = np.zeros((1, 3, 4, 4), dtype=int); gt[:, :, :2, :2] = 7
    >>> pred = gt.copy(); pred[pred == 7] = 1; pred[0, 2, 0, 0] = 0   # one pixel missed
    >>> acc = per_view_iou(pred, gt)
    >>> acc.matched, round(acc.worst, 2), acc.per_view.shape
    ({1: 7}, 0.75, (1, 3))
    """
    labels = np.asarray(labels)
    gt_labels = np.asarray(gt_labels)
    if labels.shape != gt_labels.shape or labels.ndim != 4:
        raise ValueError(
            f"labels {labels.shape} and ground truth {gt_labels.shape} must both be (S, T, U, V)"
        )
    s_count, t_count = labels.shape[:2]
    center = (s_count // 2, t_count // 2)
    present = np.ones((s_count, t_count), bool) if present is None else np.asarray(present, bool)
    ids = [int(i) for i in np.unique(labels) if i != 0]
    gt_ids = np.unique(gt_labels)
    num_views = s_count * t_count
    # one contingency table per view: (views, predicted index, ground-truth index)
    pred_index = np.searchsorted(np.asarray([0, *ids]), labels.reshape(num_views, -1))
    gt_index = np.searchsorted(gt_ids, gt_labels.reshape(num_views, -1))
    n_pred, n_gt = len(ids) + 1, len(gt_ids)
    flat = (np.arange(num_views)[:, None] * n_pred + pred_index) * n_gt + gt_index
    table = np.bincount(flat.ravel(), minlength=num_views * n_pred * n_gt)
    table = table.reshape(num_views, n_pred, n_gt)
    pred_area = table.sum(axis=2)  # (views, n_pred)
    gt_area = table.sum(axis=1)  # (views, n_gt)
    refs = dict(reference_views or {})
    labelled = gt_ids != 0
    per_object: dict[int, np.ndarray] = {}
    matched: dict[int, int] = {}
    def iou_with(k: int, g: int | None) -> np.ndarray:
        inter = table[:, k, g] if g is not None else np.zeros(num_views, np.int64)
        other = gt_area[:, g] if g is not None else np.zeros(num_views, np.int64)
        union = pred_area[:, k] + other - inter
        with np.errstate(invalid="ignore", divide="ignore"):
            iou = np.where(union > 0, inter / np.maximum(union, 1), np.nan)
        iou = iou.reshape(s_count, t_count)
        iou[~present] = np.nan
        return iou

    for k, obj_id in enumerate(ids, start=1):  # objects, not pixels
        s, t = refs.get(obj_id, center)
        overlap = table[s * t_count + t, k] * labelled
        g, iou = None, iou_with(k, None)
        if overlap.any():
            # ties go to the best match (mean IoU, then the IoUs view by view), never to the
            # smaller label: the scores do not depend on how either field numbers its labels
            tied = np.flatnonzero(overlap == overlap.max())
            candidates = [(iou_with(k, int(c)), int(c)) for c in tied]
            g, iou = max(
                ((c, v) for v, c in candidates),
                key=lambda cv: (_nanmean(cv[1]), tuple(np.nan_to_num(cv[1].ravel(), nan=-1.0))),
            )
        matched[obj_id] = 0 if g is None else int(gt_ids[g])
        per_object[obj_id] = iou
    if per_object:
        stacked = np.stack(list(per_object.values()))
        with np.errstate(invalid="ignore"):
            finite = np.isfinite(stacked)
            count = finite.sum(axis=0)
            per_view = np.where(count > 0, np.nansum(stacked, axis=0) / np.maximum(count, 1),
                                np.nan)
    else:
        per_view = np.full((s_count, t_count), np.nan)
    return ViewAccuracy(per_view=per_view, per_object=per_object, matched=matched)

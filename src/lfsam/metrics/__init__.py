"""The paper's evaluation metrics (section 4.1): SIoU, LPP, AA, UE, coverage C and time T,
with object recall and SIoU over center-present masks beside them (docs/design.md section 8).

:func:`evaluate_labels` scores a predicted label field ``[S, T, U, V]`` (0 = unlabeled) against a
ground-truth :class:`~lfsam.lightfield.LightField` with per-view disparity and labels;
:func:`evaluate_result` does the same for a :class:`~lfsam.result.SegmentationResult`, taking T
from its timings. The definitions, and the choices the paper leaves open, are documented in
:mod:`lfsam.metrics.consistency` (SIoU, LPP), :mod:`lfsam.metrics.segmentation` (AA, UE) and
:mod:`lfsam.metrics.performance` (C, T) and :mod:`lfsam.metrics.recall` (object recall, SIoU
over center-present masks, and how SIoU scores masks absent from the center view). The work runs
on torch tensors, on CUDA when present.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.metrics.accuracy import per_view_iou
from lfsam.metrics.consistency import ConsistencyScores, consistency_metrics
from lfsam.metrics.labelmap import compact_labels, to_tensor
from lfsam.metrics.performance import coverage, ms_per_mask_view
from lfsam.metrics.recall import center_present_siou, object_recall
from lfsam.metrics.segmentation import (
    achievable_accuracy,
    contingency_table,
    undersegmentation_error,
)
from lfsam.result import SegmentationResult

__all__ = [
    "METRICS",
    "OBJECT_METRICS",
    "REPORT_METRICS",
    "VIDEO_METRICS",
    "ConsistencyScores",
    "Metric",
    "achievable_accuracy",
    "check_ground_truth",
    "consistency_metrics",
    "contingency_table",
    "coverage",
    "evaluate_labels",
    "evaluate_result",
    "ms_per_mask_view",
    "result_reference_views",
    "undersegmentation_error",
]


@dataclass(frozen=True)
class Metric:
    """One column of the paper's Tables 1 and 2.

    Attributes
    ----------
    key : str
        Key in the dictionaries returned by :func:`evaluate_labels`.
    title : str
        Column title with its direction arrow, as in the paper.
    higher_is_better : bool
        Direction used to mark the best value.
    digits : int
        Decimals shown in tables.
    """

    key: str
    title: str
    higher_is_better: bool
    digits: int = 3


#: The columns of paper Table 1, in order.
METRICS: tuple[Metric, ...] = (
    Metric("siou", "SIoU↑", True),
    Metric("lpp", "LPP↓", False),
    Metric("aa", "AA↑", True),
    Metric("ue", "UE↓", False),
    Metric("coverage", "C↑", True),
    Metric("ms_per_mask_view", "T↓", False, digits=1),
)

#: Beside the paper's columns: object recall and SIoU over center-present masks
#: (:mod:`lfsam.metrics.recall`, docs/design.md section 8).
OBJECT_METRICS: tuple[Metric, ...] = (
    Metric("recall", "Recall↑", True),
    Metric("siou_center", "SIoU(c)↑", True),
    Metric("view_iou", "vIoU↑", True),
    Metric("view_iou_worst", "vIoU(min)↑", True),
)

#: Every reported column: paper Table 1's, then :data:`OBJECT_METRICS`.
REPORT_METRICS: tuple[Metric, ...] = METRICS + OBJECT_METRICS

#: Columns of a light-field video's row in ``lfsam evaluate`` (docs/design.md section 10): its
#: frames and its identity switches (:mod:`lfsam.metrics.temporal`); the other columns are then
#: means over the frames.
VIDEO_METRICS: tuple[Metric, ...] = (
    Metric("frames", "F", True, digits=0),
    Metric("identity_switches", "IDsw↓", False, digits=0),
)


def check_ground_truth(shape: tuple[int, ...], gt: LightField) -> None:
    """Check that ``gt`` can score a label field of ``shape``.

    Raises
    ------
    LfsamError
        If ``gt`` lacks per-view disparity or labels, or its grid differs from ``shape``.
    """
    source = gt.meta.get("source", "the ground truth")
    if tuple(shape) != tuple(gt.views.shape[:4]):
        raise LfsamError(
            f"labels have shape {tuple(shape)} but {source} has {tuple(gt.views.shape[:4])} "
            "(S, T, U, V); score a result against the light field it was computed on"
        )
    if not gt.has_full_disparity:
        have = "center-view disparity only" if gt.disparity is not None else "no disparity"
        raise LfsamError(
            f"{source} has {have}; the metrics need ground-truth disparity for every view "
            "(e.g. UrbanLF-Syn or a scene from `lfsam synth`)"
        )
    if not gt.has_full_labels:
        have = "center-view labels only" if gt.labels is not None else "no labels"
        raise LfsamError(
            f"{source} has {have}; the metrics need ground-truth labels for every view "
            "(e.g. UrbanLF-Syn or a scene from `lfsam synth`)"
        )


def evaluate_labels(
    labels: np.ndarray | torch.Tensor,
    gt: LightField,
    timings: Mapping[str, float] | None = None,
    *,
    num_masks: int | None = None,
    device: str | torch.device | None = None,
    min_area: int | None = None,
    present: np.ndarray | None = None,
    reference_views: Mapping[int, tuple[int, int]] | None = None,
) -> dict[str, float | int | None]:
    """All metrics of paper Table 1 for one predicted label field, and the object metrics.

    Views absent from a partial grid (``present`` and ``gt.present``; docs/design.md section 8)
    are skipped: their pixels are left out of every metric (they are treated as unlabeled in both
    the prediction and the ground truth, which SIoU, LPP, AA and UE ignore; coverage and T count
    the views present only).

    Parameters
    ----------
    labels : (S, T, U, V) integer array or tensor
        Predicted labels, 0 = unlabeled; ids are arbitrary (any renumbering scores the same).
    gt : LightField
        Ground truth with per-view ``disparity`` and ``labels`` of the same shape.
    timings : mapping, optional
        Seconds per stage with ``"total"``, for T; without it T is None.
    num_masks : int, optional
        N for T; defaults to the number of distinct non-zero labels.
    device : str or torch.device, optional
        Where to compute; default ``auto`` (:func:`lfsam.devices.resolve_device`).
    min_area : int, optional
        Pixels a ground-truth object must show in some view to count for recall (default
        :func:`lfsam.metrics.recall.default_min_area`).
    present : (S, T) bool array, optional
        The views the prediction holds (a result's ``present``); default all.
    reference_views : mapping obj_id -> (s, t), optional
        Where each predicted object was segmented, for the per-view IoU's matching (default
        the center view).

    Returns
    -------
    dict
        ``siou``, ``siou_center`` (SIoU over the masks present in the center view), ``lpp``,
        ``aa``, ``ue``, ``coverage``, ``recall`` (object recall; :mod:`lfsam.metrics.recall`),
        ``view_iou`` and ``view_iou_worst`` (per-view IoU against the ground truth, mean and
        worst view; :func:`lfsam.metrics.accuracy.per_view_iou`)
        (floats; NaN where undefined, e.g. SIoU, LPP and AA of an empty prediction),
        ``ms_per_mask_view`` (float or None), and ``num_masks``, the N used for T.

    Raises
    ------
    LfsamError
        If the ground truth is incomplete or the shapes differ (:func:`check_ground_truth`).

    Examples
    --------
    A 1 x 3 grid of 2 x 5 views at disparity 0: an object (label 1, 4 pixels per view) on a
    background (label 2). The ground truth scores perfectly; one label over everything maps to
    the background (AA = 18 / 30) and crosses both regions (UE = (12/12 + 12/18) / 2):

    >>> import numpy as np
    >>> from lfsam.lightfield import LightField
    >>> gt = np.full((1, 3, 2, 5), 2, dtype=np.int32)
    >>> gt[..., 1:3] = 1
    >>> lf = LightField(
    ...     np.zeros((1, 3, 2, 5, 3), np.uint8), disparity=np.zeros(gt.shape, np.float32), labels=gt
    ... )
    >>> scores = evaluate_labels(gt, lf, device="cpu")
    >>> [scores[k] for k in ("siou", "lpp", "aa", "ue", "coverage")]
    [1.0, 1.0, 1.0, 0.0, 1.0]
    >>> scores = evaluate_labels(np.ones_like(gt), lf, device="cpu")
    >>> round(scores["aa"], 4), round(scores["ue"], 4), scores["num_masks"]
    (0.6, 0.8333, 1)
    """
    shape = tuple(labels.shape)
    if len(shape) != 4:
        raise LfsamError(f"labels must have shape (S, T, U, V), got {shape}")
    check_ground_truth(shape, gt)
    dev = resolve_device(device)
    views = np.asarray(gt.present, dtype=bool)
    if present is not None:
        views = views & np.asarray(present, dtype=bool)
    absent = torch.as_tensor(~views, device=dev)
    raw_predicted, raw_truth = to_tensor(labels, dev), to_tensor(gt.labels, dev)
    if bool(absent.any()):
        raw_predicted = raw_predicted.masked_fill(absent[:, :, None, None], 0)
        raw_truth = raw_truth.masked_fill(absent[:, :, None, None], 0)
    predicted, predicted_ids = compact_labels(raw_predicted, "predicted labels")
    truth, truth_ids = compact_labels(raw_truth, "ground-truth labels")
    disparity = to_tensor(gt.disparity, dev)

    consistency = consistency_metrics(predicted, disparity, len(predicted_ids))
    table = contingency_table(predicted, truth, len(predicted_ids), len(truth_ids))
    recall = object_recall(predicted, truth, len(predicted_ids), len(truth_ids), min_area)
    if num_masks is None:
        num_masks = len(predicted_ids) - 1
    host_labels = labels.cpu().numpy() if isinstance(labels, torch.Tensor) else labels
    accuracy = per_view_iou(
        np.asarray(host_labels), np.asarray(gt.labels), reference_views, present=views
    )
    return {
        "siou": consistency.siou,
        "siou_center": center_present_siou(consistency, predicted),
        "lpp": consistency.lpp,
        "aa": achievable_accuracy(table),
        "ue": undersegmentation_error(table),
        "coverage": coverage(predicted[~absent]),
        "recall": recall.recall,
        "view_iou": accuracy.mean,
        "view_iou_worst": accuracy.worst,
        "ms_per_mask_view": ms_per_mask_view(timings, num_masks, (int(views.sum()), 1)),
        "num_masks": num_masks,
    }


def evaluate_result(
    result: SegmentationResult,
    gt: LightField,
    *,
    device: str | torch.device | None = None,
    min_area: int | None = None,
) -> dict[str, float | int | None]:
    """:func:`evaluate_labels` for a result, with T from its own timings and mask count.

    Parameters
    ----------
    result : SegmentationResult
        Labels ``[S, T, U, V]`` and timings (``total`` seconds).
    gt : LightField
        Ground truth with per-view disparity and labels.
    device : str or torch.device, optional
        Where to compute.
    min_area : int, optional
        Pixels a ground-truth object must show in some view to count for recall.

    Returns
    -------
    dict
        As :func:`evaluate_labels`. For T, N is the number of stored masks
        (:attr:`SegmentationResult.ms_per_mask_view`), or, for a file holding only ``labels``, the
        number of distinct non-zero labels (ids need not be ``1 .. N``).
    """
    num_masks = result.masks.num_masks if result.masks is not None else None
    return evaluate_labels(
        result.labels,
        gt,
        result.timings,
        num_masks=num_masks,
        device=device,
        min_area=min_area,
        present=result.present_mask,
        reference_views=result_reference_views(result),
    )


def result_reference_views(result: SegmentationResult) -> dict[int, tuple[int, int]]:
    """Each object's reference view recorded in a result's ``meta["objects"]`` (by id)."""
    views = {}
    for entry in result.meta.get("objects", []) or []:
        if isinstance(entry, dict) and "id" in entry and "reference_view" in entry:
            s, t = entry["reference_view"]
            views[int(entry["id"])] = (int(s), int(t))
    return views

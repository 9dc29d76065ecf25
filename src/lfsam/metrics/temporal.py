"""Metrics of a light-field video over time (docs/design.md section 10).

Per frame, the single light field's metrics (:func:`lfsam.metrics.evaluate_result`: the paper's
metrics and the per-view IoU against the ground truth). Over time:

- **best match** of a ground-truth object in a frame (:func:`frame_matches`): the predicted id
  with the largest IoU with it over all views of that frame (pixels of every view together);
  none when no predicted pixel overlaps it. Only objects visible in the frame (at least one
  pixel in some view) are matched;
- **identity switches** (:func:`identity_switches`): per ground-truth object, how often its
  best match changes between consecutive frames where it is visible and matched (frames where
  it is hidden or missed are skipped: a different id after a gap is a switch);
- **mean IoU over frames and views** (``mean_view_iou``): the mean over frames of each frame's
  ``view_iou`` (itself the mean over views); ``view_iou_worst`` is the worst view of any frame;
- **tracks** (:mod:`lfsam.metrics.tracks`, issue 47): each object's one predicted id over the
  whole video, and the share of the (object, frame, view) triples where it shows that this id
  misses (``lost``, IoU below 0.5).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from lfsam.lightfield import LightField
from lfsam.metrics.tracks import (
    FrameOverlaps,
    default_track_pixels,
    frame_overlaps,
    track_scores,
)
from lfsam.result import SegmentationResult

__all__ = ["best_matches", "evaluate_frames", "frame_matches", "identity_switches"]


def frame_matches(labels: np.ndarray, gt_labels: np.ndarray) -> dict[int, int | None]:
    """Each visible ground-truth object's best-matching predicted id in one frame.

    Parameters
    ----------
    labels, gt_labels : (S, T, U, V) integer arrays
        Predicted and ground-truth labels of the frame (0 = unlabeled).

    Returns
    -------
    dict
        ``{gt_id: pred_id or None}`` for every non-zero ground-truth id present, by IoU over all
        views (ties to the smaller id).

    Examples
    --------
    >>> gt = np.array([[[[1, 1, 2, 2]]]])
    >>> frame_matches(np.array([[[[5, 5, 5, 0]]]]), gt)
    {1: 5, 2: 5}
    >>> frame_matches(np.array([[[[0, 0, 7, 7]]]]), gt)
    {1: None, 2: 7}
    """
    return best_matches(frame_overlaps(labels, gt_labels))


def best_matches(overlaps: FrameOverlaps) -> dict[int, int | None]:
    """:func:`frame_matches` from a frame's pixel counts (:func:`lfsam.metrics.tracks.
    frame_overlaps`, read once for both the matches and the tracks): every view's pixels
    together."""
    if overlaps.pred_ids.size == 0:
        return {int(g): None for g in overlaps.gt_ids}
    joint = overlaps.joint.sum(-1)
    union = overlaps.gt_area.sum(-1)[:, None] + overlaps.pred_area.sum(-1)[None, :] - joint
    iou = np.where(joint > 0, joint / np.maximum(union, 1), 0.0)
    best = iou.argmax(1)  # ties: the smaller id
    return {int(g): int(overlaps.pred_ids[best[n]]) if iou[n, best[n]] > 0 else None
            for n, g in enumerate(overlaps.gt_ids)}


def identity_switches(matches: Sequence[dict[int, int | None]]) -> dict[int, int]:
    """Per ground-truth object, the changes of its best match over the frames.

    Parameters
    ----------
    matches : sequence of dict
        :func:`frame_matches` of each frame, in order.

    Returns
    -------
    dict
        ``{gt_id: switches}`` for every ground-truth object visible in some frame.

    Examples
    --------
    >>> identity_switches([{1: 4, 2: 5}, {1: 4}, {1: None, 2: 6}, {1: 5, 2: 6}])
    {1: 1, 2: 1}
    """
    last: dict[int, int] = {}
    switches: dict[int, int] = {}
    for frame in matches:
        for gt_id, pred_id in frame.items():
            switches.setdefault(gt_id, 0)
            if pred_id is None:
                continue
            if gt_id in last and last[gt_id] != pred_id:
                switches[gt_id] += 1
            last[gt_id] = pred_id
    return dict(sorted(switches.items()))


def _mean(values: Iterable[Any]) -> float | None:
    finite = [float(v) for v in values
              if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)]
    return sum(finite) / len(finite) if finite else None


def evaluate_frames(
    frames: Iterable[tuple[SegmentationResult, LightField]],
    *,
    device: Any = None,
    min_area: int | None = None,
    track_pixels: int | None = None,
) -> dict[str, Any]:
    """The metrics of every frame and over time (see the module docstring).

    Parameters
    ----------
    frames : iterable of (SegmentationResult, LightField)
        Each frame's result and its ground truth (per-view disparity and labels), in order;
        read one at a time.
    device, min_area
        As :func:`lfsam.metrics.evaluate_result`.
    track_pixels : int, optional
        Pixels an object must show in a view to count in ``tracks`` (default
        :func:`lfsam.metrics.tracks.default_track_pixels`).

    Returns
    -------
    dict
        ``frames``: per frame the metrics of :func:`lfsam.metrics.evaluate_result` plus
        ``frame`` and ``matches`` (ground-truth id -> best predicted id); ``summary``:
        ``frames``, ``identity_switches`` (total), ``switches`` (per ground-truth id),
        ``mean_view_iou``, ``view_iou_worst``, the mean over frames of every other
        per-frame metric (``siou``, ``aa``, ...; undefined values left out, None if none) and
        ``tracks``: each object's one track over the video and the share of the views where
        it shows that the track misses (:func:`lfsam.metrics.tracks.track_scores`, issue 47).
    """
    from lfsam.metrics import evaluate_result

    rows: list[dict[str, Any]] = []
    matches: list[dict[int, int | None]] = []
    overlaps: list[FrameOverlaps] = []
    for index, (result, gt) in enumerate(frames):
        scores = evaluate_result(result, gt, device=device, min_area=min_area)
        overlaps.append(frame_overlaps(result.labels, gt.labels))
        found = best_matches(overlaps[-1])
        if track_pixels is None:
            track_pixels = default_track_pixels(gt.view_shape)
        matches.append(found)
        rows.append({"frame": index, **scores,
                     "matches": {str(k): v for k, v in found.items()}})
    switches = identity_switches(matches)
    keys = [k for k in (rows[0] if rows else {}) if k not in ("frame", "matches", "num_masks")]
    summary: dict[str, Any] = {
        "frames": len(rows),
        "identity_switches": int(sum(switches.values())),
        "switches": {str(k): v for k, v in switches.items()},
        "mean_view_iou": _mean(r["view_iou"] for r in rows),
        "view_iou_worst": min((r["view_iou_worst"] for r in rows
                               if r["view_iou_worst"] is not None
                               and math.isfinite(r["view_iou_worst"])), default=None),
    }
    summary.update({k: _mean(r[k] for r in rows) for k in keys if k not in summary
                    and k != "view_iou"})
    summary["tracks"] = track_scores(overlaps, track_pixels or 1)
    return {"frames": rows, "summary": summary}

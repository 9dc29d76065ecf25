"""Tracks that never drop an object, measured (issue 47; docs/design.md section 10): the share
of a video's (object, frame, view) triples where a ground-truth object shows and its track
misses it.

- **Track of a ground-truth object**: its predicted id in the one-to-one pairing of
  ground-truth objects and predicted ids that covers the most pixels over the whole video
  (every frame and view; :func:`scipy.optimize.linear_sum_assignment`); an object paired with
  no id it overlaps (never segmented, or a background labelled as an object when every id is
  another object's) has no track and is listed as ``untracked``. One id for the whole video: a
  frame where the object is under another id counts as missed, so identity swaps count here
  too.
- **Visible triple**: an object showing at least ``min_pixels`` pixels in a view of a frame
  (default :func:`default_track_pixels`: issue 47's 100 pixels at 96x128, scaled with the
  view's area);
- **lost**: the share of the visible triples of tracked objects where the track's IoU with
  the object in that view is below 0.5; ``mean_iou`` over the same triples.

:func:`frame_overlaps` reads one frame (so a long video is scored frame by frame) and
:func:`track_scores` scores them all.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

__all__ = ["FrameOverlaps", "default_track_pixels", "frame_overlaps", "track_scores"]

#: A triple is lost where the track's IoU with the object is below this.
LOST_IOU = 0.5


def default_track_pixels(view_shape: tuple[int, int]) -> int:
    """Pixels an object must show in a view to count: 100 at 96x128 (issue 47), scaled with
    the view's area (2500 at 480x640)."""
    return max(1, round(100 * view_shape[0] * view_shape[1] / (96 * 128)))


@dataclass(frozen=True)
class FrameOverlaps:
    """One frame's pixel counts per view: ground-truth ids ``gt_ids`` (G,), predicted ids
    ``pred_ids`` (P,), ``joint`` (G, P, views) pixels of both, ``gt_area`` (G, views) and
    ``pred_area`` (P, views)."""

    gt_ids: np.ndarray
    pred_ids: np.ndarray
    joint: np.ndarray
    gt_area: np.ndarray
    pred_area: np.ndarray


def frame_overlaps(labels: np.ndarray, gt_labels: np.ndarray) -> FrameOverlaps:
    """The pixel counts of one frame (``(S, T, U, V)`` predicted and ground-truth labels, 0 =
    unlabeled: left out of both), one ``bincount`` over every view.

    Examples
    --------
    >>> gt = np.array([[[[1, 1, 2, 2]], [[1, 1, 1, 2]]]])
    >>> counts = frame_overlaps(np.array([[[[4, 4, 4, 0]], [[0, 4, 4, 4]]]]), gt)
    >>> counts.gt_ids.tolist(), counts.pred_ids.tolist(), counts.joint[:, :, 1].tolist()
    ([1, 2], [4], [[2], [1]])
    """
    pred = np.asarray(labels).astype(np.int64)
    truth = np.asarray(gt_labels).astype(np.int64)
    views = int(np.prod(truth.shape[:2]))
    pred, truth = pred.reshape(views, -1), truth.reshape(views, -1)
    gt_ids, gt_index = np.unique(truth, return_inverse=True)
    pred_ids, pred_index = np.unique(pred, return_inverse=True)
    g, p = len(gt_ids), len(pred_ids)
    view = np.repeat(np.arange(views), truth.shape[1])
    code = (gt_index.ravel() * p + pred_index.ravel()) * views + view
    counts = np.bincount(code, minlength=g * p * views).reshape(g, p, views)
    gt_keep, pred_keep = gt_ids != 0, pred_ids != 0
    return FrameOverlaps(gt_ids[gt_keep], pred_ids[pred_keep],
                         counts[gt_keep][:, pred_keep], counts[gt_keep].sum(1),
                         counts[:, pred_keep].sum(0))


def track_scores(frames: Sequence[FrameOverlaps], min_pixels: int) -> dict:
    """The lost share and mean IoU of a video's tracks (see the module docstring).

    Returns
    -------
    dict
        ``min_pixels``, ``visible`` (triples counted), ``lost`` (their share with IoU below
        :data:`LOST_IOU`, None without any), ``mean_iou``, ``tracks`` (``{gt_id: pred_id}``,
        string keys) and ``untracked`` (ground-truth ids without a track).

    Examples
    --------
    Object 1 tracked by id 7 in both frames but the second's view 1; object 2 never
    segmented (a 1 x 2 grid of 1 x 4 views, an object counting from 2 pixels):

    >>> gt = np.array([[[[1, 1, 2, 2]], [[1, 1, 2, 2]]]])
    >>> first = frame_overlaps(np.array([[[[7, 7, 0, 0]], [[7, 7, 0, 0]]]]), gt)
    >>> second = frame_overlaps(np.array([[[[7, 7, 0, 0]], [[0, 0, 0, 0]]]]), gt)
    >>> scores = track_scores([first, second], min_pixels=2)
    >>> scores["visible"], scores["lost"], scores["mean_iou"], scores["tracks"]
    (4, 0.25, 0.75, {'1': 7})
    >>> scores["untracked"]
    [2]
    """
    gt_all = sorted({int(g) for frame in frames for g in frame.gt_ids.tolist()})
    pred_all = sorted({int(p) for frame in frames for p in frame.pred_ids.tolist()})
    totals = np.zeros((len(gt_all), len(pred_all)), np.int64)  # pixels over the video
    for frame in frames:
        rows = np.searchsorted(gt_all, frame.gt_ids)
        cols = np.searchsorted(pred_all, frame.pred_ids)
        totals[np.ix_(rows, cols)] += frame.joint.sum(-1)
    paired_rows, paired_cols = optimize.linear_sum_assignment(totals, maximize=True)
    tracks = {gt_all[r]: pred_all[c] for r, c in zip(paired_rows, paired_cols, strict=True)
              if totals[r, c] > 0}
    ious: list[np.ndarray] = []
    for frame in frames:
        for gi, g in enumerate(frame.gt_ids.tolist()):
            if g not in tracks:
                continue
            shown = frame.gt_area[gi] >= min_pixels
            if not shown.any():
                continue
            hit = np.flatnonzero(frame.pred_ids == tracks[g])
            joint = frame.joint[gi, hit[0]] if hit.size else np.zeros_like(frame.gt_area[gi])
            ours = frame.pred_area[hit[0]] if hit.size else np.zeros_like(joint)
            union = frame.gt_area[gi] + ours - joint
            ious.append((joint / np.maximum(union, 1))[shown])
    values = np.concatenate(ious) if ious else np.zeros(0)
    return {
        "min_pixels": int(min_pixels),
        "visible": int(values.size),
        "lost": float((values < LOST_IOU).mean()) if values.size else None,
        "mean_iou": float(values.mean()) if values.size else None,
        "tracks": {str(g): p for g, p in sorted(tracks.items())},
        "untracked": [g for g in gt_all if g not in tracks],
    }

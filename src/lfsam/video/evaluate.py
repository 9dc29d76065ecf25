"""Light-field videos in the data-set harness (``lfsam evaluate``; docs/design.md section 10).

:class:`VideoTracking` is the :class:`lfsam.evaluate.VideoScenes` of :func:`lfsam.evaluate.
evaluate_dataset`: it recognises the entries of a data set that are light-field videos
(:func:`lfsam.video.is_video`), tracks each with :func:`lfsam.video.track.track_video` into its
result folder, and scores it frame by frame against the video's ground truth
(:func:`lfsam.metrics.temporal.evaluate_frames`, the same scores as ``lfsam metrics`` prints for
that folder). The scene's row holds the means over the frames of the paper's metrics and of the
per-view IoU, the worst view of any frame, the number of frames and the identity switches.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lfsam.evaluate import SceneRow, describe_failure
from lfsam.metrics import check_ground_truth
from lfsam.metrics.temporal import evaluate_frames
from lfsam.video.detect import is_video, read_video
from lfsam.video.result import VideoResult
from lfsam.video.source import LightFieldVideo

__all__ = ["VideoTracking", "video_row_metrics"]

#: ``track(video, result_folder)``: tracks a video's objects into a result folder.
TrackFn = Callable[[LightFieldVideo, Path], VideoResult]


def video_row_metrics(summary: dict[str, Any]) -> dict[str, Any]:
    """A video's row of ``metrics.csv`` from the ``summary`` of
    :func:`lfsam.metrics.temporal.evaluate_frames`: the per-frame means under the single light
    field's column names (``view_iou`` is the mean over frames and views), ``frames`` and
    ``identity_switches``.

    >>> video_row_metrics({"frames": 3, "identity_switches": 0, "mean_view_iou": 0.9,
    ...                    "view_iou_worst": 0.8, "siou": 0.7})["view_iou"]
    0.9
    """
    row = {key: value for key, value in summary.items()
           if key not in ("switches", "mean_view_iou", "num_masks")}
    row["view_iou"] = summary.get("mean_view_iou")
    return row


@dataclass
class VideoTracking:
    """Tracks and scores the light-field videos of a data set (module docstring).

    Attributes
    ----------
    track : callable(LightFieldVideo, Path) -> VideoResult
        The method, called as ``track(video, result_folder)``, e.g. ``lambda video, folder:
        track_video(video, None, folder, model="oracle", disparity="gt")`` (the automatic
        mode's objects of frame 0).
    method_label : str
        The method's name in the tables.
    device : str, optional
        Where the metrics are computed.
    value_range : int, optional
        As ``lfsam segment --value-range`` (reading 16-bit views).
    """

    track: TrackFn
    method_label: str
    device: str | None = None
    value_range: int | None = None

    def is_video(self, path: Path) -> bool:
        """Whether ``path`` is a light-field video (:func:`lfsam.video.is_video`)."""
        return is_video(path)

    def run(self, name: str, path: Path, result_folder: Path) -> SceneRow:
        """Track ``path`` into ``result_folder`` and score it; any failure is the row's error
        and leaves nothing at ``result_folder`` (the track writes it atomically; a scoring
        failure removes it, so that a resumed run tracks the video again)."""
        row = SceneRow(scene=name, method=self.method_label)
        result = None
        try:
            with read_video(path, value_range=self.value_range) as video:
                first = video.frame(0)
                check_ground_truth(first.views.shape[:4], first)
                start = time.perf_counter()
                result = self.track(video, result_folder)
                row.seconds = time.perf_counter() - start
                pairs = ((result.frame(f), video.frame(f)) for f in range(len(result)))
                scores = evaluate_frames(pairs, device=self.device)
        except Exception as exc:  # one broken video must not stop the data set
            if result is not None:
                shutil.rmtree(result_folder, ignore_errors=True)
            row.error = describe_failure(exc)
            return row
        row.metrics = video_row_metrics(scores["summary"])
        row.num_masks = len(result.object_ids)
        return row

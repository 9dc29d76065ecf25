"""Light-field videos in the data-set harness (``lfsam evaluate``; docs/design.md section 10).

:class:`VideoTracking` is the :class:`lfsam.evaluate.VideoScenes` of :func:`lfsam.evaluate.
evaluate_dataset`: it recognises the entries of a data set that are light-field videos
(:func:`lfsam.video.is_video`), tracks each with :func:`lfsam.video.tracking.track.track_video` into
its result folder, and scores it frame by frame against the video's ground truth
(:func:`lfsam.metrics.temporal.evaluate_frames`, the same scores as ``lfsam metrics`` prints for
that folder). The scene's row holds the means over the frames of the paper's metrics and of the
per-view IoU, the worst view of any frame, the number of frames and the identity switches.

On a Ray cluster (``lfsam evaluate --ray``, :mod:`lfsam.distributed`) each video is one task:
:meth:`VideoTracking.run_detached` tracks and scores it into a temporary folder on the worker
and returns the folder's files; the calling process writes them with
:meth:`VideoTracking.store`, under the same checks as the sequential run, so both give the same
result folder and row (docs/design.md section 10).
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lfsam.errors import LfsamError
from lfsam.evaluate import SceneRow, describe_failure
from lfsam.fileutil import atomic_folder_output
from lfsam.metrics import check_ground_truth
from lfsam.metrics.temporal import evaluate_frames
from lfsam.video.io.detect import is_video, read_video
from lfsam.video.io.result import VideoResult, check_result_folder
from lfsam.video.io.source import LightFieldVideo

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
    row = {key: value for key, value in summary.items()  # tracks: nested, in `lfsam metrics`
           if key not in ("switches", "mean_view_iou", "num_masks", "tracks")}
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

    def run_detached(self, name: str, path: Path, result_folder: Path
                     ) -> tuple[SceneRow, dict[str, bytes] | None]:
        """:meth:`run` on a machine that may not see ``result_folder`` (a Ray task).

        The video is tracked and scored into a temporary folder, whose files come back instead
        (docs/design.md section 10); the caller writes them with :meth:`store`.

        Parameters
        ----------
        name : str
            Scene name.
        path : Path
            The video (at the same path as for the caller: a shared file system).
        result_folder : Path
            Where the caller will write the folder (named in error messages instead of the
            temporary folder, so that an error row reads as the sequential run's).

        Returns
        -------
        row : SceneRow
        files : dict of str to bytes, or None
            Each file of the result folder by its path inside it (``/``-separated); None when
            the row is an error.
        """
        with tempfile.TemporaryDirectory(prefix="lfsam-video-") as tmp:
            folder = Path(tmp) / name
            row = self.run(name, path, folder)
            if row.error is not None:
                row.error = row.error.replace(str(folder), str(result_folder))
                return row, None
            files = {item.relative_to(folder).as_posix(): item.read_bytes()
                     for item in sorted(folder.rglob("*")) if item.is_file()}
        return row, files

    def check_target(self, result_folder: Path) -> None:
        """Refuse a ``result_folder`` that may not be replaced (neither new, an earlier video
        result nor empty: :func:`lfsam.video.io.result.check_result_folder`), before any work;
        a Ray run asks before it sends the video's task (issue 46)."""
        check_result_folder(result_folder)

    def store(self, files: dict[str, bytes], result_folder: Path) -> None:
        """Write the files of :meth:`run_detached` as the result folder ``result_folder``.

        As the sequential run writes it: refused where ``result_folder`` is neither new, an
        earlier video result nor an empty folder (:func:`lfsam.video.io.result.
        check_result_folder`), and atomic (:func:`lfsam.fileutil.atomic_folder_output`: a
        failure leaves what was there).

        Raises
        ------
        LfsamError
            If ``result_folder`` may not be replaced, or a file's path leaves the folder.
        """
        check_result_folder(result_folder)
        with atomic_folder_output(result_folder) as tmp:
            for relative, data in files.items():
                parts = Path(relative).parts
                if Path(relative).is_absolute() or ".." in parts or not parts:
                    raise LfsamError(f"{relative!r} is not a path inside a result folder")
                target = tmp.joinpath(*parts)
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(data)

"""One scene of a data-set evaluation (:mod:`lfsam.evaluate`): :class:`SceneJob`, what a scene
needs to be segmented and scored, run here or on a Ray worker (:mod:`lfsam.distributed`), and
its :class:`SceneOutcome`; :class:`VideoScenes`, the light-field videos a data set may hold
(docs/design.md section 10); :func:`describe_failure`, a failed scene's one-line error.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from lfsam.errors import LfsamError
from lfsam.evaluate.table import SceneRow
from lfsam.lightfield import LightField
from lfsam.metrics import (
    check_ground_truth,
    evaluate_result,
)
from lfsam.result import SegmentationResult, save_result

__all__ = ["SceneJob", "SceneOutcome", "VideoScenes", "describe_failure"]


SegmentFn = Callable[[LightField], SegmentationResult]


Reader = Callable[[Path], LightField]


@dataclass
class SceneOutcome:
    """What one scene's job produced, for the process that writes the output folder.

    Attributes
    ----------
    name : str
        Scene name.
    row : SceneRow or None
        Its row; None when the entry is not a light field (then ``skipped`` says why).
    skipped : str or None
        Why the entry was skipped.
    entry : str
        The entry's file or folder name (for the skip note).
    result_bytes : bytes or None
        The result's ``.npz`` file, when the job ran with ``in_memory`` (on another machine);
        otherwise the job wrote it into the output folder itself.
    result_files : dict of str to bytes, or None
        A video's result folder (path inside it -> file contents), when the job ran with
        ``in_memory`` (:meth:`VideoScenes.run_detached`).
    """

    name: str
    row: SceneRow | None
    skipped: str | None = None
    entry: str = ""
    result_bytes: bytes | None = None
    result_files: dict[str, bytes] | None = None


@dataclass
class SceneJob:
    """Detect, read, segment, score and save one scene: the unit of work of
    :func:`evaluate_dataset`, picklable so that it can run in another process (a Ray task)."""

    segment_fn: SegmentFn
    method_label: str
    out: Path
    device: str | None
    reader: Reader
    detect: Callable[[Path], object]
    videos: VideoScenes | None = None

    def __call__(self, name: str, path: Path, in_memory: bool = False) -> SceneOutcome:
        """Run the scene; with ``in_memory`` the result file (a video's result folder) comes
        back as bytes instead of being written to the output folder (for a machine that may not
        see it; docs/design.md section 10)."""
        if self.videos is not None and self.videos.is_video(path):
            if in_memory:
                row, files = self.videos.run_detached(name, path, self.out / name)
                return SceneOutcome(name=name, row=row, entry=path.name, result_files=files)
            row = self.videos.run(name, path, self.out / name)
            return SceneOutcome(name=name, row=row, entry=path.name)
        try:
            self.detect(path)
        except LfsamError as exc:
            return SceneOutcome(name=name, row=None, skipped=str(exc), entry=path.name)
        try:
            lightfield = self.reader(path)
        except Exception as exc:  # an unreadable scene is a failed scene, not the end of the run
            row = SceneRow(scene=name, method=self.method_label, error=describe_failure(exc))
            return SceneOutcome(name=name, row=row, entry=path.name)
        if not in_memory:
            row = _run_scene(
                name, lightfield, self.segment_fn, self.method_label, self.out, self.device
            )
            return SceneOutcome(name=name, row=row, entry=path.name)
        with tempfile.TemporaryDirectory(prefix="lfsam-scene-") as tmp:
            row = _run_scene(
                name, lightfield, self.segment_fn, self.method_label, Path(tmp), self.device
            )
            saved = Path(tmp) / f"{name}.npz"
            data = saved.read_bytes() if saved.is_file() else None
        return SceneOutcome(name=name, row=row, entry=path.name, result_bytes=data)


    def refused(self, name: str, path: Path) -> SceneOutcome | None:
        """The error row of a video whose result folder may not be replaced, found before any
        work (a Ray run asks before sending its task, issue 46), else None."""
        if self.videos is None or not self.videos.is_video(path):
            return None
        try:
            self.videos.check_target(self.out / name)
        except LfsamError as exc:
            row = SceneRow(scene=name, method=self.method_label, error=describe_failure(exc))
            return SceneOutcome(name=name, row=row, entry=path.name)
        return None


class VideoScenes(Protocol):
    """How :func:`evaluate_dataset` runs the light-field videos of a data set (docs/design.md
    section 10); :class:`lfsam.video.evaluate.VideoTracking` is the implementation."""

    def is_video(self, path: Path) -> bool:
        """Whether the data-set entry ``path`` is a light-field video."""

    def run(self, name: str, path: Path, result_folder: Path) -> SceneRow:
        """Track, write the result folder ``result_folder`` and score one video; any failure
        is the row's error."""

    def run_detached(self, name: str, path: Path, result_folder: Path
                     ) -> tuple[SceneRow, dict[str, bytes] | None]:
        """As :meth:`run` on a machine that may not see ``result_folder`` (a Ray task): the
        row, and the result folder's files (path inside it -> contents; None on error)."""

    def store(self, files: dict[str, bytes], result_folder: Path) -> None:
        """Write the files of :meth:`run_detached` as ``result_folder``, as :meth:`run` would
        have written it; raises when it cannot."""

    def check_target(self, result_folder: Path) -> None:
        """Raise :class:`LfsamError` (as :meth:`run` would) if ``result_folder`` may not be
        written, before any work."""


def _run_scene(
    name: str,
    lightfield: LightField,
    segment_fn: SegmentFn,
    method_label: str,
    out: Path,
    device: str | None,
) -> SceneRow:
    """Segment, save and score one scene; any exception becomes the row's error."""
    row = SceneRow(scene=name, method=method_label)
    try:
        check_ground_truth(lightfield.views.shape[:4], lightfield)
        start = time.perf_counter()
        result = segment_fn(lightfield)
        row.seconds = time.perf_counter() - start
        if result.timings.get("total") is None:
            result.timings["total"] = row.seconds
        result.meta.setdefault("evaluation_method", method_label)
        metrics = evaluate_result(result, lightfield, device=device)
        row.num_masks = int(metrics.pop("num_masks"))
        row.metrics = metrics
        save_result(result, out / f"{name}.npz")
    except Exception as exc:  # one broken scene must not stop the data set
        row.metrics = {}
        row.error = describe_failure(exc)
    return row


def describe_failure(exc: BaseException) -> str:
    """One line naming an exception: the message of an LfsamError, else type and message."""
    text = str(exc) if isinstance(exc, LfsamError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())

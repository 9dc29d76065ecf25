"""The viewer's slow work in a worker thread: typed events, the jobs, and the queue that runs them.

The dock widget (:mod:`lfsam.viewer.widget`) never calls a slow method of its
:class:`lfsam.viewer.session.ViewerSession` itself (loading the model, the coarse-to-fine
prediction, automatic segmentation; docs/design.md section 8). It starts a *job*, a generator
function run by napari's ``create_worker`` (:mod:`napari.qt.threading`), which yields one typed
event per step; the events arrive in the main thread, where the widget dispatches on their type.
A job's :class:`lfsam.errors.LfsamError` (a user error: no weights, no ground truth, ...) becomes
a :class:`Failed` event instead of a raise.

One job runs at a time. Actions asked for meanwhile wait in a :class:`WorkQueue` and run in
order once the job has finished; a segmentation asked for meanwhile is remembered once (the
latest prompts are segmented when the worker is free), so the interface never blocks and no
click is lost.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from qtpy.QtCore import QObject
from qtpy.QtWidgets import QProgressBar

from lfsam.errors import LfsamError

__all__ = [
    "AllMasks",
    "CoarseMasks",
    "Failed",
    "FinalMasks",
    "FrameTracked",
    "ModelLoaded",
    "ReferenceMask",
    "TextFound",
    "TrackStopped",
    "Tracked",
    "WorkQueue",
    "WorkerEvent",
    "find_job",
    "generate_job",
    "guarded",
    "load_job",
    "predict_all_job",
    "segment_job",
    "track_job",
    "video_segment_job",
]


# --- events -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModelLoaded:
    """The model and disparity are loaded (:meth:`ViewerSession.load`).

    Attributes
    ----------
    model : str
        The model's name.
    device : str or None
        Where it runs (None for a segmenter without a device, e.g. the oracle).
    """

    model: str
    device: str | None


@dataclass(frozen=True, eq=False)  # eq=False: the mask is an array (events compare by identity)
class ReferenceMask:
    """First stage of a segmentation: the mask in the view the object is prompted in.

    Attributes
    ----------
    obj_id : int
        The object segmented.
    view : (s, t)
        Its reference view.
    mask : (U, V) bool ndarray
        Its mask there.
    score : float
        The segmenter's confidence.
    """

    stage: ClassVar[str] = "reference"
    obj_id: int
    view: tuple[int, int]
    mask: np.ndarray
    score: float


@dataclass(frozen=True, eq=False)
class CoarseMasks:
    """Second stage: the object in every view, propagated and occluded, not refined.

    Attributes
    ----------
    obj_id : int
        The object segmented.
    prediction : LightFieldPrediction
        ``predict_coarse([obj_id])``: ``prediction.masks[obj_id]`` is ``(S, T, U, V)``.
    """

    stage: ClassVar[str] = "coarse"
    obj_id: int
    prediction: Any


@dataclass(frozen=True, eq=False)
class FinalMasks:
    """Last stage: every object, refined (the segmented one among them).

    Attributes
    ----------
    obj_id : int
        The object segmented.
    prediction : LightFieldPrediction
        ``predict()``: every object's masks and labels.
    """

    stage: ClassVar[str] = "final"
    obj_id: int
    prediction: Any


@dataclass(frozen=True, eq=False)
class AllMasks:
    """Every object's masks, after loading, committing, reopening or segmenting everything.

    Attributes
    ----------
    prediction : LightFieldPrediction
    found : int, optional
        Segmenting everything: how many new objects were found (None otherwise).
    """

    prediction: Any
    found: int | None = None


@dataclass(frozen=True)
class TextFound:
    """A text prompt's instances were added; every object's masks.

    Parameters
    ----------
    prediction : LightFieldPrediction
    phrase : str
    finds : list of dict
        :meth:`lfsam.text_search.TextFind.to_dict` of each view searched.
    """

    prediction: Any
    phrase: str
    finds: list[dict[str, Any]]


@dataclass(frozen=True, eq=False)
class FrameTracked:
    """Tracking a video: one frame is finished (docs/design.md section 10).

    Attributes
    ----------
    index : int
        The frame (0-based).
    total : int
        The video's number of frames.
    labels : (S, T, U, V) int ndarray
        Every object's labels in that frame.
    """

    index: int
    total: int
    labels: np.ndarray


@dataclass(frozen=True)
class Tracked:
    """Tracking a video is finished.

    Attributes
    ----------
    result : VideoResult
        The result folder, read lazily.
    """

    result: Any


@dataclass(frozen=True)
class TrackStopped:
    """Tracking a video was stopped by the user after frame ``index`` (docs/design.md
    section 10); nothing was written (the result folder of the stopped track is removed).

    Attributes
    ----------
    index : int
        The last frame tracked (0-based).
    total : int
        The video's number of frames.
    """

    index: int
    total: int


@dataclass(frozen=True)
class Failed:
    """A job stopped on a user error (:class:`LfsamError`); what was queued after it is dropped.

    Attributes
    ----------
    message : str
        lfsam's one-line message.
    """

    message: str


#: Everything a job yields.
WorkerEvent = (
    ModelLoaded | ReferenceMask | CoarseMasks | FinalMasks | AllMasks | TextFound
    | FrameTracked | Tracked | TrackStopped | Failed
)

#: A job: a generator function run in the worker thread.
Job = Callable[[], Iterator[WorkerEvent]]


# --- jobs (run in the worker thread) ------------------------------------------------------------
def load_job(session: Any) -> Iterator[WorkerEvent]:
    """Load the session's model and disparity; then, if there are objects, predict them all."""
    session.load()
    segmenter = getattr(session.predictor, "segmenter", None)
    device = getattr(segmenter, "device", None)
    yield ModelLoaded(session.model, None if device is None else str(device))
    if session.object_ids:
        yield AllMasks(session.predict_all())


def segment_job(session: Any, obj_id: int) -> Iterator[WorkerEvent]:
    """Segment the current object ``obj_id`` coarse to fine: three events, one per stage.

    :meth:`ViewerSession.segment_current` tags its stages with strings; this is the one place
    that reads them.

    Raises
    ------
    ValueError
        For a stage name the session should not give (the session's code is at fault).
    """
    for stage, value in session.segment_current():
        if stage == "reference":
            view, mask, score = value
            yield ReferenceMask(
                obj_id, (int(view[0]), int(view[1])), np.asarray(mask, dtype=bool), float(score)
            )
        elif stage == "coarse":
            yield CoarseMasks(obj_id, value)
        elif stage == "final":
            yield FinalMasks(obj_id, value)
        else:  # the session's code is at fault
            raise ValueError(f"unknown segmentation stage {stage!r}")


def video_segment_job(session: Any, obj_id: int, frame: int) -> Iterator[WorkerEvent]:
    """A video: go to ``frame`` (:meth:`VideoSession.goto_frame`), then :func:`segment_job`."""
    session.goto_frame(frame)
    yield from segment_job(session, obj_id)


class _StopTracking(Exception):
    """Raised from the frame callback to end a track the user stopped."""


def track_job(
    session: Any, out: Any = None, stop: threading.Event | None = None
) -> Iterator[WorkerEvent]:
    """Track a video's objects (:meth:`VideoSession.track`): one :class:`FrameTracked` per
    frame as it finishes, then :class:`Tracked`; :class:`TrackStopped` instead once ``stop``
    is set (checked as each frame finishes: the frame being tracked is finished first, and
    :func:`lfsam.video.track_video` leaves nothing at ``out``).

    ``track_video`` reports frames through a callback, which cannot yield: it runs in a thread
    of its own and hands each frame over a queue to this generator (the worker thread).
    """
    frames: queue.Queue = queue.Queue()
    done = object()
    outcome: dict[str, Any] = {}
    total = session.video.num_frames

    def on_frame(index: int, result: Any) -> None:
        frames.put(FrameTracked(index, total, result.labels))
        if stop is not None and stop.is_set() and index + 1 < total:
            outcome["stopped"] = index
            raise _StopTracking

    def run() -> None:
        try:
            outcome["result"] = session.track(out, on_frame=on_frame)
        except _StopTracking:
            pass
        except BaseException as exc:  # re-raised in the worker thread below
            outcome["error"] = exc
        finally:
            frames.put(done)

    thread = threading.Thread(target=run, name="lfsam-track", daemon=True)
    thread.start()
    while (event := frames.get()) is not done:
        yield event
    thread.join()
    if "error" in outcome:
        raise outcome["error"]
    if "stopped" in outcome:
        yield TrackStopped(outcome["stopped"], total)
    else:
        yield Tracked(outcome["result"])


def predict_all_job(session: Any) -> Iterator[WorkerEvent]:
    """Every object's masks (unchanged objects are reused)."""
    yield AllMasks(session.predict_all())


def generate_job(session: Any, references: str) -> Iterator[WorkerEvent]:
    """Automatic mode from the ``references`` views; then every object's masks."""
    before = set(session.object_ids)
    prediction = session.generate(references)
    yield AllMasks(prediction, found=len(set(session.object_ids) - before))


def find_job(session: Any, phrase: str, view: tuple[int, int] | None) -> Iterator[WorkerEvent]:
    """Text prompt: the instances of ``phrase`` in ``view`` as objects; then every object's
    masks (docs/design.md section 9)."""
    prediction, finds = session.find(phrase, view)
    yield TextFound(prediction, phrase, [find.to_dict() for find in finds])


def guarded(job: Job) -> Job:
    """``job``, with an :class:`LfsamError` turned into a :class:`Failed` event, not a raise."""

    def run() -> Iterator[WorkerEvent]:
        try:
            yield from job()
        except LfsamError as exc:
            yield Failed(str(exc))

    return run


# --- the queue ----------------------------------------------------------------------------------
class WorkQueue(QObject):
    """Runs one job at a time in a napari worker; queues actions and a pending segmentation.

    Parameters
    ----------
    progress : QProgressBar
        Shows the running job's steps (one per event).
    deliver : callable
        Called in the main thread with each event but :class:`Failed`.
    error : callable
        Called with the message of a :class:`Failed` event or an action's :class:`LfsamError`.
    status : callable
        Called with a status line when a job starts, or crashes.
    finished : callable
        Called when a job has finished (before the queue is drained; see :meth:`drain`).
    segment : callable
        Segments the current object; runs once when :attr:`segment_pending` is set and the queue
        is idle.
    parent : QObject, optional
    """

    def __init__(
        self,
        progress: QProgressBar,
        *,
        deliver: Callable[[WorkerEvent], None],
        error: Callable[[str], None],
        status: Callable[[str], None],
        finished: Callable[[], None],
        segment: Callable[[], None],
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)
        self.progress = progress
        self.worker: Any = None
        #: Actions waiting for the running job, in order.
        self.actions: list[Callable[[], None]] = []
        #: Whether a segmentation of the current object was asked for while busy.
        self.segment_pending = False
        self._deliver = deliver
        self._error = error
        self._status = status
        self._finished = finished
        self._segment = segment

    @property
    def busy(self) -> bool:
        """Whether a worker is running."""
        return self.worker is not None

    @property
    def idle(self) -> bool:
        """No worker running, no action queued and no segmentation pending."""
        return not (self.busy or self.actions or self.segment_pending)

    def when_idle(self, action: Callable[[], None]) -> None:
        """Run ``action`` now, or after the running job (in order)."""
        if self.busy:
            self.actions.append(action)
        else:
            self.attempt(action)

    def attempt(self, action: Callable[[], None]) -> None:
        """Run ``action``; an :class:`LfsamError` it raises goes to ``error``."""
        try:
            action()
        except LfsamError as exc:
            self._error(str(exc))

    def request_segment(self) -> None:
        """Segment the current object now, or once the running job has finished (once, however
        often it is asked for meanwhile: the latest prompts are segmented)."""
        if self.busy:
            self.segment_pending = True
        else:
            self.attempt(self._segment)

    def cancel(self) -> None:
        """Drop the queued actions and the pending segmentation."""
        self.actions.clear()
        self.segment_pending = False

    def start(self, job: Job, total: int, desc: str) -> None:
        """Run ``job`` in a napari worker thread; ``total`` events are expected."""
        from napari.qt.threading import create_worker

        self.progress.setRange(0, total)
        self.progress.setValue(0)
        self._status(desc + "…")
        self.worker = create_worker(
            guarded(job),
            _progress={"total": total, "desc": desc},
            _connect={
                "yielded": self._on_yielded,
                "finished": self._on_finished,
                "errored": self._on_errored,
            },
            _start_thread=True,
        )

    def describe(self, text: str) -> None:
        """Rename the running job in napari's activity dock (e.g. the frame being tracked)."""
        pbar = getattr(self.worker, "pbar", None)
        if pbar is not None:
            pbar.set_description(text)

    def drain(self) -> None:
        """Run queued actions in order until one starts a job; then a pending segmentation."""
        while self.actions and not self.busy:
            self.attempt(self.actions.pop(0))
        if self.segment_pending and not self.busy:
            self.segment_pending = False
            self.attempt(self._segment)

    def _on_yielded(self, event: WorkerEvent) -> None:
        self.progress.setValue(min(self.progress.value() + 1, self.progress.maximum()))
        if isinstance(event, Failed):
            self._error(event.message)
            self.cancel()
        else:
            self._deliver(event)

    def _on_errored(self, exc: Exception) -> None:  # a bug, not a user error: keep its traceback
        self.cancel()
        self._status(f"error: {exc}")

    def _on_finished(self) -> None:
        self.worker = None
        self.progress.setValue(self.progress.maximum())
        self._finished()

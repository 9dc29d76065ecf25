"""The dock's "Follow": a light-field camera's growing frames folder segmented live in napari
(docs/design.md section 10, issue 35; ``lfsam view FOLDER --follow``).

:class:`FollowController` (the widget's ``follow``) runs
:func:`lfsam.video.stream.live.segment_stream` with the dock's model, disparity and refine views in
a thread of its own, never in the GUI thread; its events reach the GUI thread through a queued Qt
signal. The latest frame is an RGB image layer ``(S, T, U, V, 3)`` (``s``, ``t`` on sliders), its
masks a labels layer; the status line says ``frame N (name): X.XX s from arrival``, the objects
shown and those searched for (``searching for 2 (hidden since frame 5)``: not found, kept under
their ids, issue 47), or why a frame was skipped. A click on the ``live clicks`` layer (polarity as
elsewhere in the viewer, tagged with its view) is a new object posted with
:meth:`~lfsam.video.tracking.online.OnlineTracker.post_prompts`, segmented from the next frame on
with a stable id (a negative click corrects the object it lands on). Stop calls
``follower.stop()`` (the frame being segmented is kept); a file named ``END`` ends the stream
too. The result folder is valid throughout; at the end the status says how and after how many
frames, which objects were hidden in which frames (and how many clicks came after the last
frame, unused), and a viewer with nothing else open shows the frames segmented as a video with
it. The box "Follow: everything in the first frame" follows in automatic mode; ``texts``
(``lfsam view --follow --text``) are found in the first frame and tracked. A fault of the
setup (not of one frame) ends the stream with its one line (issue 46).
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from qtpy.QtCore import QObject, Signal

from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.io import read_lightfield
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.prompts import ObjectPrompts, TextPrompt
from lfsam.result import SegmentationResult
from lfsam.segmenters.registry import ORACLE
from lfsam.video.io.live_result import check_live_folder
from lfsam.video.io.result import load_video_result
from lfsam.video.io.source import LightFieldVideo, check_frame
from lfsam.video.stream.follow import FrameFollower, check_follow_folder
from lfsam.video.stream.hidden_lines import HiddenSince, hidden_frames_text, hidden_now
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer.prompt_layers import prompts_from_layers
from lfsam.viewer.session import SAM2_ONLY_OPTIONS

if TYPE_CHECKING:  # lfsam.api loads torchvision: only after the native libraries (widget.py)
    from lfsam.video.stream.live import FrameTiming, StreamReport
    from lfsam.video.tracking.online import OnlineTracker

__all__ = ["FollowController", "FrameShown", "StatusLine", "StreamEnded", "default_out"]

#: How each way of ending reads in the status line.
ENDINGS = {"END": "END file", "timeout": "no new frame within the timeout"}
_AXES = ("s", "t", "u", "v")


@dataclass(frozen=True, eq=False)
class FrameShown:
    """A frame is segmented and in the result folder: its timing, views ``(S, T, U, V, 3)``,
    labels ``(S, T, U, V)``, the ids the tracker knows after it, why clicks posted for it
    were left out (``meta["refused_prompts"]``, or None) and the ids not found in it
    (*hidden*: kept and searched for in the next frames, ``meta["tracks"]``)."""

    timing: FrameTiming
    views: np.ndarray
    labels: np.ndarray
    ids: tuple[int, ...]
    refused: str | None
    hidden: tuple[int, ...] = ()


@dataclass(frozen=True)
class StatusLine:
    """A line for the status: a frame skipped (and why; the stream goes on), the model loaded."""

    line: str


@dataclass(frozen=True)
class StreamEnded:
    """The stream is over: its report, or the one-line error that ended it."""

    report: StreamReport | None
    error: str | None = None


@functools.cache
def _showing_tracker() -> type:
    """An :class:`OnlineTracker` that keeps the last light field it was given (its views are
    shown, not read twice); made when first needed (module imports above)."""
    from lfsam.video.tracking.online import OnlineTracker

    class ShowingTracker(OnlineTracker):
        last: LightField | None = None

        def track(self, lightfield: LightField) -> SegmentationResult:
            self.last = lightfield
            return super().track(lightfield)

    return ShowingTracker


class _SegmentedFrames:
    """The frames a stream segmented (skipped ones left out), in order: a video's frame source
    (:class:`lfsam.video.io.source.FrameSource`) whose frame f is the result's frame f."""

    def __init__(self, folder: Path, names: list[str]) -> None:
        self.folder, self.paths = folder, [folder / name for name in names]
        self.num_frames, first = len(names), read_lightfield(self.paths[0])
        self.grid_shape, self.view_shape = first.grid_shape, first.view_shape
        self.has_disparity, self.has_labels = first.disparity is not None, first.labels is not None

    def read(self, index: int) -> LightField:
        lf = check_frame(read_lightfield(self.paths[index]), index, self.grid_shape,
                         self.view_shape, str(self.folder))
        lf.meta["frame_source"] = str(self.paths[index])
        return lf

    def close(self) -> None:
        """Nothing stays open."""


def default_out(folder: str | os.PathLike) -> Path:
    """The result folder of a followed ``folder`` by default: ``<folder>_live`` next to it, or
    ``<folder>_live_2``, ... when that one is taken (not empty)."""
    folder, n = Path(folder).resolve(), 1
    while True:
        out = folder.parent / f"{folder.name}_live{'' if n == 1 else f'_{n}'}"
        if not out.exists() or (out.is_dir() and not any(out.iterdir())):
            return out
        n += 1


class FollowController(QObject):
    """Follow a growing frames folder in the viewer (see the module docstring).

    Parameters
    ----------
    widget : LightFieldWidget
        The dock: its model, weights, disparity and refine views, status line, click polarity
        (``T``) and viewer.

    Attributes
    ----------
    follower : FrameFollower or None
        The stream being followed (None when none is).
    tracker, folder, out, report, names
        The last stream's tracker, frames folder, result folder, report (once over) and the
        names of the frames shown, in order (frame f of the result is ``names[f]``).
    layers : dict
        The live layers (``image``, ``labels``, ``points``), once a frame is shown.
    """

    _delivered = Signal(object)

    def __init__(self, widget: Any) -> None:
        super().__init__(widget)
        self.widget = widget
        self.follower: FrameFollower | None = None
        self.tracker: OnlineTracker | None = None
        self.thread: threading.Thread | None = None
        self.folder: Path | None = None
        self.out: Path | None = None
        self.report: StreamReport | None = None
        self.names: list[str] = []
        self.layers: dict[str, Any] = {}
        self._next_id = 1
        #: Each hidden object's first frame of its current run of hidden frames.
        self._hidden = HiddenSince()
        self._delivered.connect(self._on_event)  # queued: emitted in the stream's thread

    @property
    def running(self) -> bool:
        """Whether a stream is followed (until its end has reached the GUI thread)."""
        return self.follower is not None

    def ask(self) -> None:
        """"Follow…": ask for the frames folder and the result folder, then :meth:`start`."""
        folder = C.ask_open_folder(self.widget, "Follow a frames folder (a camera writes into it)")
        out = folder and C.ask_save_file(self.widget, "Write the results into (a new or empty "
                                         "folder)", str(default_out(folder)))
        auto = self.widget.controls.follow_auto_box.isChecked()
        if out:
            self.widget.work.attempt(lambda: self.start(folder, out, auto=auto))

    def start(self, folder: str | os.PathLike, out: str | os.PathLike | None = None, *,
              timeout: float | None = None, auto: bool = False, poll: float = 0.05,
              latest: bool | None = None, texts: Sequence[TextPrompt] = ()) -> Path:
        """Follow ``folder``, writing the live result into ``out`` (a new or empty folder;
        default :func:`default_out`); returns ``out`` at once (the stream runs in a thread).
        ``timeout``: end after so many seconds without a new frame (default: END or Stop only);
        ``auto``: find the first frame's objects automatically, besides clicked ones (the
        "Follow: everything in the first frame" box); ``poll``: seconds between looks at the
        folder; ``latest``: segment only the newest frame that has landed (default: the dock's
        "Newest frame only" box); ``texts``: phrases found in the first frame, their instances
        tracked.

        Raises
        ------
        LfsamError
            A stream already followed, a missing folder, an output folder that is not new or
            empty, or a disparity file (one line each; nothing is started).
        """
        if self.running:
            raise LfsamError(f"already following {self.follower.folder}; Stop it first")
        folder = check_follow_folder(folder)
        out = default_out(folder) if out is None else Path(out)
        check_writable(out, folder=True, option="the output folder", inside=True)
        check_live_folder(out)
        tracker = self._tracker(auto, texts)
        follower = FrameFollower(folder, timeout=timeout, poll=poll)
        self._remove_layers()
        self.follower, self.tracker, self.folder, self.out = follower, tracker, folder, out
        self.report, self.names, self._next_id, self._hidden = None, [], 1, HiddenSince()
        if latest is None:
            latest = self.widget.controls.latest_box.isChecked()
        self.thread = threading.Thread(target=self._run, args=(follower, tracker, out, latest),
                                       name="lfsam-follow", daemon=True)
        self.thread.start()
        self._buttons(following=True)
        what = "" if tracker.name == ORACLE else f"loading {tracker.name}; "
        self._status(f"following {folder} into {out}: {what}waiting for frames (a file named "
                     "END or Stop ends the stream)")
        return out

    def stop(self, wait: float = 0.0) -> None:
        """"Stop following": the stream ends after the frame being segmented (kept); ``wait``:
        seconds to wait for the stream's thread (when the viewer closes)."""
        if self.follower is not None:
            self.follower.stop()
            self.widget.controls.stop_follow_button.setEnabled(False)
            self._status("stopping the stream after the frame being segmented…")
        if wait and self.thread is not None:
            self.thread.join(wait)

    def _tracker(self, auto: bool, texts: Sequence[TextPrompt] = ()) -> OnlineTracker:
        """A tracker with the dock's model (built as Track builds it), disparity, refine views,
        consensus (docs/design.md section 3.9), "Everything from" views (``auto``) and
        embedding cache; ``texts`` with the dock's text model."""
        from lfsam.api import ModelOptions, RunOptions, SegmentOptions

        widget = self.widget
        name, disparity = widget.model_box.currentText(), widget.disparity_box.currentText()
        if disparity not in ("estimate", "gt"):
            raise LfsamError("following a stream takes disparity estimate or gt (one per "
                             "frame), not a file; choose one in the Disparity box")
        keys = dict(widget._options)
        for key in SAM2_ONLY_OPTIONS if name == ORACLE else ("oracle_options",):
            keys.pop(key, None)
        model = ModelOptions(
            name=name, checkpoint=keys.get("checkpoint"),
            random_weights=bool(keys.get("random_weights")), device=keys.get("device") or "auto",
            amg=keys.get("amg_options"), oracle=keys.get("oracle_options"),
            seed=int(keys.get("seed") or 0), precision=keys.get("precision") or "auto",
            **{k: v for k, v in widget._text_options.items() if v is not None})
        run = RunOptions(references=widget.references_box.currentText(), progress=False,
                         cache_dir=None if widget._cache_dir is None else str(widget._cache_dir))
        pipeline = PipelineConfig(refine_views=widget._refine_views,
                                  consensus=widget.controls.consensus)  # sections 3.7, 3.9
        options = SegmentOptions(pipeline, model, run)
        return _showing_tracker()(None, disparity=disparity, options=options, auto=auto,
                                  texts=texts)

    # --- the stream's thread ---------------------------------------------------------------------
    def _run(self, follower: FrameFollower, tracker: Any, out: Path, latest: bool) -> None:
        """Load the model (the oracle is built per frame), then :func:`segment_stream`."""
        from lfsam.video.stream.live import segment_stream

        def emit(event: Any) -> None:
            with contextlib.suppress(RuntimeError):  # the dock is gone (the viewer closed)
                self._delivered.emit(event)

        def on_frame(timing: FrameTiming, result: SegmentationResult) -> None:
            hidden = tuple(hidden_now(result.meta.get("tracks", {})))
            emit(FrameShown(timing, tracker.last.views, result.labels,
                            tuple(tracker.object_ids), result.meta.get("refused_prompts"),
                            hidden))

        try:
            if tracker.name != ORACLE:
                try:
                    tracker.segmenter = tracker.options.model.build(keep_decoder_state=False)
                except LfsamError as exc:  # a configuration fault: no frame is looked at
                    raise LfsamError(f"{exc} (the stream stopped: nothing was written)"
                                     ) from exc
                emit(StatusLine(f"model {tracker.name} loaded; waiting for frames"))
            report = segment_stream(follower, tracker, out, on_frame=on_frame,
                                    on_skip=lambda line: emit(StatusLine(line)), latest=latest)
            emit(StreamEnded(report))
        except LfsamError as exc:  # the line says what was kept (segment_stream's Raises)
            emit(StreamEnded(None, str(exc)))
        except BaseException as exc:  # a bug: its traceback on stderr, one line in the dock
            traceback.print_exc()
            emit(StreamEnded(None, f"the stream stopped on an error: {exc!r}"))

    # --- in the GUI thread -----------------------------------------------------------------------
    def _on_event(self, event: Any) -> None:
        match event:
            case FrameShown():
                self._show(event)
            case StatusLine(line=line):
                self._status(line)
            case StreamEnded(report=report, error=error):
                self._ended(report, error)

    def _show(self, event: FrameShown) -> None:
        timing = event.timing
        if not self.layers or self.layers["image"] not in self.widget.viewer.layers:
            self._add_layers(event.views, event.labels)
        else:
            self.layers["image"].data = event.views
            self.layers["labels"].data = event.labels
            self.layers["points"].data = np.zeros((0, 4))  # clicks were on the last frame
        self.names.append(timing.name)
        self._next_id = max(self._next_id, max(event.ids, default=0) + 1)
        ids = [int(i) for i in np.unique(event.labels) if i > 0]
        older = f"{timing.superseded} older skipped, " if timing.superseded else ""
        line = (f"frame {timing.index} ({timing.name}): {timing.latency:.2f} s from arrival, "
                + older
                + (f"objects {ids}" if ids else "no object (click one: it is segmented from "
                   "the next frame on)"))
        line += self._hidden.update(timing.index, event.hidden)  # kept, searched for
        self._status(line + (f"; clicks left out: {event.refused}" if event.refused else ""))

    def _add_layers(self, views: np.ndarray, labels: np.ndarray) -> None:
        """The live image, labels and clicks layers, on the center view."""
        viewer = self.widget.viewer
        self._remove_layers()
        with self.widget.keeper.aside():  # not the dock's light field
            image = viewer.add_image(views, name=f"live: {self.folder.name}", rgb=True,
                                     contrast_limits=(0, 255), axis_labels=_AXES)
            masks = viewer.add_labels(labels, name="live masks", opacity=0.5, axis_labels=_AXES)
            points = L.make_layer(L.POINTS, labels.shape)
            points.name = "live clicks"
            viewer.layers.append(points)
        self.layers = {"image": image, "labels": masks, "points": points}
        points.mouse_drag_callbacks.insert(0, self.widget.prompts._on_press)  # T, Ctrl-click
        points.events.data.connect(self._on_points)
        points.mode = "add"
        viewer.layers.selection.active = points
        step = list(viewer.dims.current_step)
        step[-4:-2] = (labels.shape[0] // 2, labels.shape[1] // 2)
        viewer.dims.current_step = tuple(step)
        viewer.reset_view()

    def _remove_layers(self) -> None:
        for layer in self.layers.values():
            if layer in self.widget.viewer.layers:
                self.widget.viewer.layers.remove(layer)
        self.layers = {}

    def _on_points(self, event: Any) -> None:
        points = self.layers.get("points")
        if (points is None or not len(points.data)
                or not str(getattr(event, "action", "")).endswith("added")):
            return
        positive = bool(points.features["positive"].iloc[-1])
        self.widget.work.attempt(lambda: self.click(points.data[-1], positive))

    def click(self, position: Any, positive: bool = True) -> int:
        """A click at ``position`` ``(s, t, u, v)`` of the frame shown: a positive one becomes
        a new object, a negative one corrects the object it lands on; posted to the tracker
        for the next frame it starts. Returns the object's id; raises :class:`LfsamError`
        without a frame shown, or for a negative click on no object."""
        if not self.running or not self.layers:
            raise LfsamError("clicks go on a frame of a followed stream: Follow a frames folder "
                             "and click on a frame once it is shown")
        labels = self.layers["labels"].data
        obj = prompts_from_layers(1, np.asarray(position)[None], np.array([positive]), [],
                                  labels.shape[:2])
        point = obj.points[0]
        if positive:
            obj_id, self._next_id = self._next_id, self._next_id + 1
        else:
            u = min(max(round(point.y), 0), labels.shape[2] - 1)
            obj_id = int(labels[(*point.view, u, min(max(round(point.x), 0),
                                                     labels.shape[3] - 1))])
            if obj_id == 0:
                raise LfsamError("a negative click corrects the object it lands on, and this "
                                 "one lands on none: click inside an object's mask")
        self.tracker.post_prompts([ObjectPrompts(obj_id, (point,))])
        what = "new object" if positive else "negative click"
        self._status(f"object {obj_id} ({what} in view {point.view[0]},{point.view[1]}): "
                     "segmented from the next frame on")
        return obj_id

    def _ended(self, report: StreamReport | None, error: str | None) -> None:
        self.report, self.follower, self.thread = report, None, None
        self._buttons(following=False)
        if "points" in self.layers:
            self.layers["points"].mode = "pan_zoom"
        if report is None:
            self.widget._error(error)
            return
        unused = len(self.tracker.waiting_prompts) if self.tracker is not None else 0
        line = (f"stream ended ({ENDINGS.get(report.ended_by, report.ended_by)}) after "
                f"{report.frames} frame(s)"
                + (f", {len(report.skipped)} skipped" if report.skipped else "")
                + (f"; {self.out} holds them" if report.frames else "; nothing was written")
                + hidden_frames_text(report.hidden)
                + (f"; {unused} click(s) came after the last frame and were not used (no "
                   "frame followed them)" if unused else ""))
        self._status(line)
        if report.frames and self.widget.session is None:
            self.widget.work.attempt(lambda: self._open_followed(line))

    def _open_followed(self, line: str) -> None:
        """Show the frames segmented as a video with the result (as ``--result`` does)."""
        widget, folder, result = self.widget, self.folder, load_video_result(self.out)
        video = LightFieldVideo(_SegmentedFrames(folder, self.names),
                                meta={"source": str(folder), "format": "followed-frames"})
        self._remove_layers()
        widget.set_video(video)
        widget.show_tracked(result)
        step = widget.viewer.dims.current_step
        widget.viewer.dims.current_step = (len(video) - 1, *step[1:])  # the last frame shown
        widget.work.when_idle(lambda: self._status(
            f"{line}; shown as a video (frame slider): click and Track to change it, Save "
            "copies it"))

    def _buttons(self, following: bool) -> None:
        controls = self.widget.controls
        controls.follow_button.setEnabled(not following)
        controls.stop_follow_button.setEnabled(following)

    def _status(self, text: str) -> None:
        self.widget._set_status(text)

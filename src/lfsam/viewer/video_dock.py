"""The light-field video part of the napari dock (docs/design.md section 10): the frame slider,
tracking a video's objects through its frames in the worker, stopping it, and reopening a saved
track with its objects editable. A mixin of :class:`lfsam.viewer.widget.LightFieldWidget`, kept
beside it (the widget lays out and connects the dock; this module knows what a video adds).
"""

from __future__ import annotations

import os
import threading
from functools import partial
from typing import Any

from lfsam.errors import LfsamError
from lfsam.viewer import layers as L
from lfsam.viewer import worker as W
from lfsam.viewer.video_session import VideoSession

__all__ = ["VideoDock"]


class VideoDock:
    """What the dock does with a light-field video (mixed into the widget, which provides
    ``session``, ``viewer``, ``controls``, ``layers``, ``prompts``, ``work``,
    ``_start_session``, ``_when_loaded``, ``_refresh_objects`` and ``_set_status``)."""

    session: Any
    viewer: Any
    controls: Any
    layers: Any
    prompts: Any
    work: Any
    _stop_track: threading.Event | None = None

    def set_video(self, video: Any, layer: Any = None) -> None:
        """Show a light-field video (one lazy image layer with a ``frame`` slider) and create
        the prompt and mask layers, all with the frame axis (docs/design.md section 10)."""
        self._start_session(VideoSession, video, video.frame(0), layer, video=video)
        self.controls.track_button.setVisible(True)
        self.controls.stop_track_button.setVisible(True)

    @property
    def is_video(self) -> bool:
        """Whether the session is a light-field video's."""
        return isinstance(self.session, VideoSession)

    @property
    def _frame_axes(self) -> int:
        """Sliders before ``s`` and ``t``: 1 (the frame) for a video, else 0."""
        return 1 if self.is_video else 0

    def shown_frame(self) -> int:
        """The frame on the ``frame`` slider (0 for a single light field)."""
        if not self.is_video:
            return 0
        count = self.session.video.num_frames
        return min(max(int(self.viewer.dims.current_step[0]), 0), count - 1)

    def track(self, out: str | os.PathLike | None = None) -> None:
        """Ctrl-T: track every object of a video through all its frames in the worker (into
        ``out``, default a temporary folder); each frame's labels show as it finishes."""

        def run() -> None:
            if not self.is_video:
                raise LfsamError("Track follows objects through a light-field video; open a "
                                 "video (a folder of frames or an [F, S, T, U, V, 3] array)")
            self.session.sync_current()
            total = self.session.video.num_frames
            self._stop_track = threading.Event()
            self.work.start(partial(W.track_job, self.session, out, self._stop_track),
                            total + 1, f"tracking frame 1 of {total}")
            self.controls.stop_track_button.setEnabled(True)

        if self.session is not None:
            self.work.when_idle(lambda: self._when_loaded(run))

    def stop_tracking(self) -> None:
        """"Stop tracking": end the running track after the frame being tracked (the worker
        never stops mid-frame). Nothing of the stopped track is saved; the previous track, if
        any, is shown again (docs/design.md section 10)."""
        if self._stop_track is not None and not self._stop_track.is_set():
            self._stop_track.set()
            self.controls.stop_track_button.setEnabled(False)
            self._set_status("stopping after the frame being tracked…")

    def show_tracked(self, result: Any) -> None:
        """Reopen a saved track, a video result folder (``lfsam view VIDEO --result FOLDER``,
        or its labels layer opened with File > Open and reopened from the dock): its labels in
        the committed layer, read lazily, and its objects back in the object list, editable,
        with their prompts on the frames they were given on
        (:meth:`VideoSession.open_result`): edit one, click on any frame and Track again. Save
        copies the folder until the next Track. A folder that keeps no prompts (written before
        lfsam stored them, or tracked from automatic masks) is shown only: click its objects
        again and Track to change it.

        Raises
        ------
        LfsamError
            Without a video, or for a result :meth:`VideoSession.open_result` does not take
            (checked now, before anything changes).
        """
        session = self.session
        if not self.is_video:
            raise LfsamError("a video result needs its video: open the light-field video")
        session.check_result(result)

        def run() -> None:  # after the model's loading, which would overwrite the status
            ids = session.open_result(result)
            if ids:
                self.prompts.write(None, session.lightfield.center)
                self.layers[L.CURRENT].data.clear()
                self.layers[L.CURRENT].refresh()
            self.layers[L.COMMITTED].data.attach_result(result)
            self.layers[L.COMMITTED].refresh()
            self._refresh_objects()
            self._set_status(
                f"showing {result.path} ({len(result.object_ids)} object(s)); "
                + (f"its {len(ids)} prompted object(s) are editable: double-click one, click "
                   "on any frame and Track again" if ids else
                   "its prompts are not stored in it: to change it, click the objects and "
                   "Track again")
            )

        self.work.when_idle(run)

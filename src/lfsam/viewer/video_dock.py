"""The light-field video part of the napari dock (docs/design.md section 10): the frame slider,
tracking a video's objects through its frames in the worker, stopping it, and showing a saved
track. A mixin of :class:`lfsam.viewer.widget.LightFieldWidget`, kept beside it (the widget
lays out and connects the dock; this module knows what a video adds).
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
    ``session``, ``viewer``, ``controls``, ``layers``, ``work``, ``_start_session``,
    ``_when_loaded`` and ``_set_status``)."""

    session: Any
    viewer: Any
    controls: Any
    layers: Any
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
        """Show a video result folder's labels (``lfsam view VIDEO --result FOLDER``) in the
        committed layer, read lazily; Save copies it. Its objects are not editable (their
        prompts are not kept per frame): click them again and Track to change them."""
        session = self.session
        if not self.is_video:
            raise LfsamError("a video result needs its video: open the light-field video")
        if tuple(result.shape) != tuple(session.video.shape):
            raise LfsamError(
                f"the result has labels {tuple(result.shape)}, the video "
                f"{tuple(session.video.shape)}; open the result of this video"
            )

        def run() -> None:  # after the model's loading, which would overwrite the status
            session.tracked = result
            self.layers[L.COMMITTED].data.attach_result(result)
            self.layers[L.COMMITTED].refresh()
            self._set_status(f"showing {result.path} ({len(result.object_ids)} object(s)); "
                             "to change it, click the objects and Track again")

        self.work.when_idle(run)

"""The viewer's session on a light-field video (Qt-free): prompts on any frame, tracking.

docs/design.md sections 8 and 10. A :class:`VideoSession` is a
:class:`lfsam.viewer.session.ViewerSession` whose light field is the video's *current frame*:

- every object keeps its prompts over all frames, each point and box tagged with its frame
  (:attr:`VideoSession.video_objects`, :mod:`lfsam.video.tracking.prompts`);
- the predictor works on the current frame only, with each object's prompts at that frame
  (:func:`lfsam.video.tracking.prompts.prompts_at`), so a click on frame f segments frame f's light
  field at once, exactly as a single light field; :meth:`VideoSession.goto_frame` switches frames
  (the oracle is rebuilt from the new frame's labels, a SAM 2 model is kept);
- :meth:`VideoSession.track` runs :func:`lfsam.video.tracking.track.track_video` over the whole
  video with every object's frame-tagged prompts, into a result folder (temporary unless given),
  calling back after each frame; :meth:`VideoSession.save` copies that folder;
- :meth:`VideoSession.open_result` reopens a saved track (a video result folder): its objects
  come back editable with their frame-tagged prompts
  (:meth:`lfsam.video.io.result.VideoResult.stored_prompts`), its labels are the last track.

What a single light field offers but a video does not (segment everything, text prompts,
reopening a single light field's result or labels) raises a one-line :class:`LfsamError` saying
what to do instead.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lfsam.errors import LfsamError
from lfsam.prompts import ObjectPrompts, validate_objects
from lfsam.segmenters.registry import ORACLE
from lfsam.video.io.source import LightFieldVideo
from lfsam.video.tracking.prompts import prompts_at
from lfsam.viewer.session import ViewerSession

__all__ = ["VideoSession"]

#: The disparity sources a video takes (one per frame).
VIDEO_DISPARITIES = ("estimate", "gt")


def _unsupported(what: str, instead: str) -> LfsamError:
    return LfsamError(f"{what} works on single light fields, not videos; {instead}")


@dataclass
class VideoSession(ViewerSession):
    """One annotation session on a light-field video (see the module docstring).

    Parameters
    ----------
    lightfield : LightField
        The current frame (frame :attr:`frame` of :attr:`video`).
    video : LightFieldVideo
        The video.
    frame : int
        The current frame's index.
    Other parameters are :class:`ViewerSession`'s.

    Attributes
    ----------
    video_objects : dict of int to ObjectPrompts
        Every object's frame-tagged prompts (the current object's as the history has them).
    tracked : VideoResult or None
        The last track's result (:meth:`track`), or the saved track reopened
        (:meth:`open_result`).
    """

    video: LightFieldVideo | None = None
    frame: int = 0
    video_objects: dict[int, ObjectPrompts] = field(default_factory=dict)
    tracked: Any = None

    # --- model and frames -----------------------------------------------------------------------
    def _check_disparity(self) -> None:
        if not isinstance(self.disparity, str) or self.disparity not in VIDEO_DISPARITIES:
            raise LfsamError(
                "a light-field video takes disparity estimate or gt (one per frame), not a "
                "file; choose one in the Disparity box"
            )

    def load(self) -> None:
        """Build the segmenter and the predictor on the current frame, with each object's
        prompts at that frame (worker thread)."""
        self._check_disparity()
        old, self.predictor = self.predictor, None  # objects come from video_objects
        try:
            super().load()
        except BaseException:
            self.predictor = old
            raise
        self._place_objects()

    def goto_frame(self, frame: int) -> None:
        """Make ``frame`` the current frame: read it and set the predictor on it (worker
        thread; nothing to do when it already is). A SAM 2 model is kept; the oracle, which
        answers from a frame's labels, is rebuilt."""
        frame = int(frame) % self.video.num_frames
        if frame == self.frame and self.predictor is not None:
            return
        pred = self._require()
        lightfield = self.video.frame(frame)
        segmenter = None if self.model == ORACLE else pred.segmenter
        self.predictor = self._new_predictor(lightfield, segmenter)
        self.lightfield, self.frame = lightfield, frame
        self._place_objects()

    def _place_objects(self) -> None:
        """Give the predictor every object that has a positive prompt at the current frame."""
        for obj_id in list(self.predictor.object_ids):
            self.predictor.remove_object(obj_id)
        for obj in self.video_objects.values():
            own = prompts_at(obj, self.frame)
            if own is not None and own.has_positive:
                self.predictor.set_object(own)

    # --- objects ----------------------------------------------------------------------------------
    @property
    def object_ids(self) -> list[int]:
        """Every object with prompts on some frame, sorted."""
        return sorted(self.video_objects)

    def sync_current(self) -> Any | None:
        """Record the current object's frame-tagged prompts as the history has them, and give
        the predictor its prompts at the current frame."""
        obj = self.history.current
        obj_id = self.current_id
        if obj is None:
            self.video_objects.pop(obj_id, None)
        else:
            self.video_objects[obj_id] = obj
        pred = self.predictor
        if pred is not None:
            own = None if obj is None else prompts_at(obj, self.frame)
            if own is not None and own.has_positive:
                if pred.objects.get(obj_id) != own:
                    pred.set_object(own)
            elif obj_id in pred.object_ids:
                pred.remove_object(obj_id)
        return obj

    def has_positive_at(self, frame: int) -> bool:
        """Whether the current object has a positive click or its box on ``frame`` (what
        segmenting that frame's light field needs)."""
        obj = self.video_objects.get(self.current_id)
        own = None if obj is None else prompts_at(obj, frame)
        return own is not None and own.has_positive

    def current_prompts(self) -> Any | None:
        """The current object's frame-tagged prompts, or None."""
        return self.video_objects.get(self.current_id)

    def segment_current(self) -> Any:
        """Segment the current object on the current frame (nothing when it has no positive
        prompt there): :meth:`ViewerSession.segment_current`."""
        if self.predictor is None or self.current_id not in self.predictor.object_ids:
            return iter(())
        return super().segment_current()

    def commit(self) -> int:
        """Commit the current object; returns its id."""
        obj_id = self.current_id
        if obj_id not in self.video_objects:
            raise LfsamError("nothing to commit: add a point or a box to the object first")
        self.committed.add(obj_id)
        self.current_id = self.next_id()
        self.history.reset()
        return obj_id

    def edit(self, obj_id: int) -> Any | None:
        """Make object ``obj_id`` the one being edited; returns its frame-tagged prompts."""
        if obj_id not in self.video_objects:
            raise LfsamError(f"there is no object {obj_id}; pick one from the list")
        if self.current_id != obj_id and self.current_id in self.video_objects:
            self.committed.add(self.current_id)
        self.committed.discard(obj_id)
        self.current_id = obj_id
        obj = self.video_objects[obj_id]
        self.history.reset(obj)
        return obj

    def remove(self, obj_id: int) -> None:
        """Delete object ``obj_id`` (its prompts on every frame)."""
        self.video_objects.pop(obj_id, None)
        if self.predictor is not None and obj_id in self.predictor.object_ids:
            self.predictor.remove_object(obj_id)
        self.committed.discard(obj_id)
        if obj_id == self.current_id:
            self.history.reset()

    def clear_current(self) -> None:
        """Remove the current object's prompts on every frame (Shift-C)."""
        self.video_objects.pop(self.current_id, None)
        super().clear_current()

    # --- what videos do not offer ------------------------------------------------------------
    def generate(self, references: str = "center") -> Any:
        """Not for videos (raises)."""
        raise _unsupported("segment everything",
                           "click the objects, or run `lfsam segment VIDEO --auto`")

    def find(self, phrase: str, view: tuple[int, int] | None = None) -> Any:
        """Not for videos (raises)."""
        raise _unsupported("Find (text prompts)", "click the objects on any frame")

    def open_labels(self, labels: Any) -> list[int]:
        """Not for videos (raises): :meth:`open_result` takes a video's result folder."""
        return self.open_result(labels)

    # --- a saved track ----------------------------------------------------------------------------
    def check_result(self, result: Any) -> list[ObjectPrompts]:
        """Check that :meth:`open_result` can reopen ``result``; its prompted objects (empty
        for a folder that keeps none).

        Raises
        ------
        LfsamError
            What :meth:`open_result` raises.
        """
        if not hasattr(result, "stored_prompts"):  # a single light field's result or labels
            raise _unsupported("reopening a result",
                               "open the video's result folder (saved by Track and Save, or "
                               "`lfsam segment VIDEO --out FOLDER`), or click the objects "
                               "again and press Track")
        if tuple(result.shape) != tuple(self.video.shape):
            raise LfsamError(
                f"the result has labels {tuple(result.shape)}, the video "
                f"{tuple(self.video.shape)}; open the result of this video"
            )
        objects = result.stored_prompts() or []
        try:
            validate_objects(objects, self.video.grid_shape, self.video.view_shape,
                             self.video.num_frames)
        except LfsamError as exc:
            raise LfsamError(f"{result.path} does not fit this video: {exc}") from None
        if objects and self.video_objects:
            raise LfsamError(
                "the session has objects already; remove them (or Track and Save them) before "
                "reopening a result folder, whose objects replace them"
            )
        return objects

    def open_result(self, result: Any) -> list[int]:
        """Reopen a saved track (a :class:`lfsam.video.io.result.VideoResult`; docs/design.md
        section 10): its objects come back editable, committed, with their frame-tagged prompts
        (:meth:`~lfsam.video.io.result.VideoResult.stored_prompts`), and ``result`` becomes
        :attr:`tracked` (what Save writes until the next Track).

        Returns
        -------
        ids : list of int
            The objects reopened; empty for a folder that keeps no prompts (written before lfsam
            stored them, or tracked from automatic masks): it is :attr:`tracked`, not editable.

        Raises
        ------
        LfsamError
            A single light field's result or labels, another video's result, stored prompts
            that do not fit the video, or (for a folder with prompts) objects in the session
            already, which it would replace.
        """
        objects = self.check_result(result)
        fresh = not self.video_objects and self.history.current is None
        self.tracked = result
        if objects:
            self.video_objects = {obj.obj_id: obj for obj in objects}
            self.committed = set(self.video_objects)
            self.auto.clear()
            self.history.reset()
            if self.predictor is not None:
                self._place_objects()
        if objects or fresh:  # a new object gets an id after every id of the track
            self.current_id = max([0, *self.video_objects, *result.object_ids]) + 1
        return sorted(self.video_objects) if objects else []

    # --- tracking and output --------------------------------------------------------------------
    def track(self, out: str | os.PathLike | None = None,
              on_frame: Callable[[int, Any], None] | None = None) -> Any:
        """Track every object through the video (worker thread; docs/design.md section 10).

        Parameters
        ----------
        out : path-like, optional
            The result folder; default a new temporary one.
        on_frame : callable, optional
            ``track_video``'s callback: ``on_frame(index, SegmentationResult)`` per frame.

        Returns
        -------
        VideoResult
            Also kept as :attr:`tracked`.

        Raises
        ------
        LfsamError
            No object, a disparity file, or ``track_video``'s errors.
        """
        from lfsam.api import ModelOptions, RunOptions, SegmentOptions
        from lfsam.video.tracking.track import track_video

        self._check_disparity()
        objects = [self.video_objects[i] for i in sorted(self.video_objects)]
        if not objects:
            raise LfsamError("nothing to track: click an object on any frame first")
        pred = self._require()
        keywords = self.segmenter_keywords()
        model: Any = pred.segmenter  # a SAM 2 model is used as loaded
        model_options = ModelOptions(name=self.model)
        if self.model == ORACLE:  # rebuilt per frame from that frame's labels
            model = ORACLE
            model_options = ModelOptions(name=ORACLE, oracle=keywords.get("oracle_options"),
                                         seed=int(keywords.get("seed") or 0))
        options = SegmentOptions(
            pipeline=self.pipeline_config(),  # refine views and consensus (sections 3.7, 3.9)
            model=model_options,
            run=RunOptions(cache_dir=None if self.cache_dir is None else str(self.cache_dir),
                           progress=False),
        )
        if out is None:
            out = Path(tempfile.mkdtemp(prefix="lfsam-track-")) / "result"
        self.tracked = track_video(self.video, objects, out, model=model,
                                   disparity=self.disparity, options=options,
                                   on_frame=on_frame)
        return self.tracked

    def to_result(self) -> Any:
        """The last track's :class:`VideoResult`."""
        if self.tracked is None:
            raise LfsamError("nothing to save yet: press Track to track the objects through "
                             "the video first")
        return self.tracked

    def check_save(self, path: str | os.PathLike) -> Path:
        """Check that Save can write the folder ``path`` (new, empty or an earlier video
        result, in a folder that takes files), before any work."""
        from lfsam.fileutil import check_writable
        from lfsam.video.io.result import check_result_folder

        return check_writable(check_result_folder(path), folder=True, option="the folder to "
                              "save")

    def save(self, path: str | os.PathLike) -> Path:
        """Copy the last track's result folder to ``path`` (a new folder, atomic)."""
        from lfsam.fileutil import atomic_folder_output

        path = self.check_save(path)
        result = self.to_result()
        with atomic_folder_output(path) as tmp:
            for item in Path(result.path).iterdir():
                shutil.copy2(item, tmp / item.name)
        return path

"""Tracking objects through a light-field video (docs/design.md section 10).

:func:`track_video` is a loop over :class:`lfsam.video.tracking.online.OnlineTracker` (which holds
the tracking itself: SAM 2's video memory or constrained prompts, see its module): each frame of the
video is read, tracked and written before the next is read.

The result is written frame by frame (:mod:`lfsam.video.io.result`): memory stays flat in F. Its
manifest keeps each object's frame-tagged prompts as given (``meta["objects"]``), so that the
viewer reopens the folder editable (:meth:`lfsam.video.io.result.VideoResult.stored_prompts`), and
each object's state in every frame (``meta["tracks"]``: prompted, tracked, found, hidden or
waiting; issue 47).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from typing import Any

from tqdm.auto import tqdm

from lfsam.api import SegmentOptions
from lfsam.prompts import ObjectPrompts, validate_objects
from lfsam.result import SegmentationResult
from lfsam.segmenters.base import Segmenter
from lfsam.version import __version__
from lfsam.video.io.result import (
    VideoResult,
    load_video_result,
    record_states,
    video_result_writer,
)
from lfsam.video.io.source import LightFieldVideo
from lfsam.video.tracking.online import MAX_GROWTH, OnlineTracker

__all__ = ["MAX_GROWTH", "track_video"]



def track_video(
    video: LightFieldVideo,
    prompts: Sequence[ObjectPrompts] | None,
    out: str | os.PathLike,
    *,
    model: str | Segmenter | None = None,
    disparity: str = "estimate",
    options: SegmentOptions | None = None,
    memory: bool | None = None,
    on_frame: Callable[[int, SegmentationResult], None] | None = None,
) -> VideoResult:
    """Track objects through a light-field video and write the chunked result.

    Parameters
    ----------
    video : LightFieldVideo
    prompts : sequence of ObjectPrompts, or None
        Objects with frame-tagged prompts (:mod:`lfsam.video.tracking.prompts`); None: automatic
        mask generation on frame 0.
    out : path-like
        The result folder (:func:`lfsam.video.io.result.video_result_writer`).
    model : str or Segmenter, optional
        A model name (default ``options.model.name``; ``"oracle"`` is built per frame from
        that frame's labels) or a ready SAM 2 segmenter.
    disparity : {"estimate", "gt"}
        Where each frame's disparity comes from.
    options : SegmentOptions, optional
        Pipeline, model and run options, passed through to every frame.
    memory : bool, optional
        Track with SAM 2's video memory (True) or constrained prompts (False); default: the
        memory for SAM 2 segmenters, prompts for the others.
    on_frame : callable, optional
        Called as ``on_frame(index, result)`` with each frame's
        :class:`~lfsam.result.SegmentationResult` once it is written, in frame order and in the
        calling thread (the viewer shows frames as they finish, docs/design.md section 8). An
        exception it raises stops the run; nothing is left at ``out`` then.

    Returns
    -------
    VideoResult
        The written result, opened lazily; its :meth:`~VideoResult.stored_prompts` gives
        ``prompts`` back in id order, frames kept ([] in the automatic mode).

    Raises
    ------
    LfsamError
        Prompts that do not fit the video, a disparity other than a name, the video
        baseline method (single light fields only), ``memory=True`` without SAM 2, or a
        correction click outside the center view with SAM 2's memory.
    """
    options = options or SegmentOptions()
    tracker = OnlineTracker(model, disparity=disparity, options=options, memory=memory,
                            auto=prompts is None)
    objects = list(prompts) if prompts is not None else None
    if objects is not None:
        validate_objects(objects, video.grid_shape, video.view_shape, video.num_frames)
        tracker.add_prompts(objects)
    start = time.perf_counter()
    meta: dict[str, Any] = {
        "method": "lfsam-video", "input": video.meta.get("source"), "model": tracker.name,
        "frames": video.num_frames, "prompt_mode": "auto" if objects is None else "prompts",
        "package_version": __version__, "disparity": disparity,
    }
    bar = tqdm(total=video.num_frames, desc="tracking", unit="frame",
               disable=not options.run.progress)
    with video_result_writer(out, meta=meta, objects=objects or []) as writer:
        history: dict[str, list[str]] = {}
        meta["tracks"] = history
        for index in range(video.num_frames):
            frame_result = tracker.track(video.frame(index))
            meta["tracking"] = tracker.tracking
            record_states(history, frame_result.meta.get("tracks", {}), index)
            writer.write(frame_result)
            if on_frame is not None:
                on_frame(index, frame_result)
            bar.update(1)
    bar.close()
    result = load_video_result(out)
    result.meta["seconds"] = time.perf_counter() - start
    return result

"""Poses over a whole light-field video (:mod:`lfsam.poses`): :func:`poses_of_video` runs a
:class:`~lfsam.poses.tracker.PoseTracker` over ``(result, light field)`` frames with a disparity
source (``"estimate"``, ``"gt"``, a map) and a camera, as :mod:`lfsam.objects3d` does;
:class:`VideoPoses` does the same one frame at a time (a followed stream, the viewer's Poses).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from lfsam.camera import Camera
from lfsam.disparity.carried import ESTIMATE_MODES, estimate_views
from lfsam.disparity.source import load_disparity_spec, resolve_view_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField, check_result_shape
from lfsam.objects3d import resolve_camera
from lfsam.poses.tracker import (
    POSE_VIEWS,
    FramePose,
    ObjectPoses,
    PoseOptions,
    PoseTracker,
    ViewData,
    default_pose_views,
)
from lfsam.result import SegmentationResult

__all__ = ["VideoPoses", "poses_of_video"]


def _view_arrays(lightfield: LightField, result: SegmentationResult, spec, name: str,
                 views: str, estimate: str, device: str | None) -> list[ViewData]:
    present = lightfield.present & result.present_mask
    center = lightfield.center
    chosen = [tuple(int(x) for x in v) for v in np.argwhere(present)]
    if views == "center":
        chosen = [center]
    elif views == "corners":
        last_s, last_t = present.shape[0] - 1, present.shape[1] - 1
        chosen = [center] + [v for v in ((0, 0), (0, last_t), (last_s, 0), (last_s, last_t))
                             if present[v] and v != center]
    estimated = (estimate_views(lightfield, chosen, mode=estimate, device=device)
                 if isinstance(spec, str) and spec == "estimate" else {})
    out = []
    for view in chosen:
        if view in estimated:
            disparity, confidence = estimated[view]
        else:
            disparity, _, _ = resolve_view_disparity(spec, lightfield, view=view,
                                                     device=device, name=name)
            disparity, confidence = np.asarray(disparity), None
        out.append(ViewData((view[0] - center[0], view[1] - center[1]), lightfield.views[view],
                            result.labels[view], disparity, confidence))
    return out


def poses_of_video(
    frames: Iterable[tuple[SegmentationResult, LightField]],
    *,
    disparity: str | os.PathLike | np.ndarray = "estimate",
    camera: Camera | str | os.PathLike | None = None,
    views: str | None = None,
    estimate: str = "light",
    options: PoseOptions | None = None,
    device: str | None = None,
    on_frame: Callable[[int, list[FramePose]], None] | None = None,
) -> tuple[Camera, list[ObjectPoses]]:
    """Every object's motion and pose over ``(result, light field)`` frames (module docstring).

    Parameters
    ----------
    frames : iterable of (SegmentationResult, LightField)
        One pair per frame (a single pair: each object's pose, motion identity).
    disparity : {"estimate", "gt"}, .npy path or ndarray
        As :func:`lfsam.objects3d.objects_in_3d`; a map or file holds for every frame.
    camera : Camera, ``--camera`` JSON path, or None (the first frame's own)
    views : {"all", "corners", "center"}, optional
        The views whose pixels become points (:data:`POSE_VIEWS`; features use the center and
        the corners of these); default :func:`default_pose_views` (``"corners"`` with an
        estimate, else ``"all"``).
    estimate : {"light", "own", "carried"}
        With ``disparity="estimate"``: every used view's own estimate (one cost volume per view
        and frame: 5 with ``views="corners"``, 49 on a 7 x 7 grid with ``views="all"``) with the
        estimator's light settings (:data:`lfsam.disparity.carried.LIGHT_ESTIMATE`) or its
        defaults (``"own"``, about 3.5 times the time, more accurate), or the center view's
        estimate carried to the other views (one per frame, less accurate;
        :func:`lfsam.disparity.carried.estimate_views`; docs/design.md section 12, "Depth per
        frame").
    options : PoseOptions, optional
    on_frame : callable, optional
        Called with ``(frame, [FramePose, ...])`` after each frame (live output).

    Returns
    -------
    camera, list of ObjectPoses

    Raises
    ------
    LfsamError
        A result that does not match its light field, no camera, a bad disparity source.
    """
    session = VideoPoses(disparity=disparity, camera=camera, views=views, estimate=estimate,
                         options=options, device=device)

    def register(prepared: Future) -> None:
        entries = session.register(*prepared.result())
        if on_frame is not None:
            on_frame(session.frames - 1, entries)

    # the next frame is read and its views estimated while this one is registered: the
    # estimates are each frame's own, the registration runs frame after frame as before
    with ThreadPoolExecutor(max_workers=1) as ahead:
        pending: Future | None = None
        for number, (result, lightfield) in enumerate(frames):
            prepared = ahead.submit(session.prepare, result, lightfield, number)
            if pending is not None:
                register(pending)
            pending = prepared
        if pending is not None:
            register(pending)
    if session.camera is None:
        raise LfsamError("no frames to register")
    session.finish()
    return session.camera, session.objects


class VideoPoses:
    """:func:`poses_of_video` one frame at a time (a live stream: ``lfsam segment --follow
    --poses``): :meth:`add` each ``(result, light field)`` as it comes.

    Parameters are :func:`poses_of_video`'s. ``camera`` is resolved at the first frame when it
    is not a :class:`~lfsam.camera.Camera` (:meth:`check_camera` does it earlier).
    """

    def __init__(self, *, disparity: str | os.PathLike | np.ndarray = "estimate",
                 camera: Camera | str | os.PathLike | None = None, views: str | None = None,
                 estimate: str = "light", options: PoseOptions | None = None,
                 device: str | None = None) -> None:
        views = default_pose_views(disparity) if views is None else views
        if views not in POSE_VIEWS:
            raise LfsamError(f"views must be one of {POSE_VIEWS}, got {views!r}")
        if estimate not in ESTIMATE_MODES:
            raise LfsamError(f"estimate must be one of {ESTIMATE_MODES}, got {estimate!r}")
        self.estimate = estimate
        self.disparity, self.views, self.options, self.device = disparity, views, options, device
        self._camera_spec = camera
        self.camera: Camera | None = camera if isinstance(camera, Camera) else None
        self.tracker: PoseTracker | None = None
        self.frames = 0

    @property
    def objects(self) -> list[ObjectPoses]:
        """Every object seen so far."""
        return [] if self.tracker is None else self.tracker.objects

    def finish(self) -> list[FramePose]:
        """The video ended: objects still held back start at the last frame they were seen in
        (:meth:`lfsam.poses.PoseTracker.finish`); their first entries."""
        return [] if self.tracker is None else self.tracker.finish()

    def add(self, result: SegmentationResult, lightfield: LightField) -> list[FramePose]:
        """Register the objects of the next frame (module docstring): :meth:`prepare` then
        :meth:`register`."""
        return self.register(*self.prepare(result, lightfield))

    def prepare(self, result: SegmentationResult, lightfield: LightField,
                frame: int | None = None
                ) -> tuple[SegmentationResult, LightField, list[ViewData]]:
        """A frame's views as the tracker takes them, their disparity estimated or read; it
        touches no state of the session, so the next frame's can be made while one is
        registered (:func:`poses_of_video`; docs/design.md section 12, "Depth per frame").
        ``frame``: its number in messages (default the next one to register).

        Raises
        ------
        LfsamError
            A result that does not match its light field, a bad disparity source.
        """
        number = self.frames if frame is None else frame
        check_result_shape(result.labels.shape, lightfield, f"the result of frame {number}")
        spec, name = load_disparity_spec(self.disparity, lightfield)
        data = _view_arrays(lightfield, result, spec, name, self.views, self.estimate,
                            self.device)
        return result, lightfield, data

    def register(self, result: SegmentationResult, lightfield: LightField,
                 views: list[ViewData]) -> list[FramePose]:
        """Register the objects of the next frame from its :meth:`prepare`-d views."""
        if self.camera is None:
            self.camera = resolve_camera(lightfield, self._camera_spec)
        if self.tracker is None:
            categories = {int(k): str(v) for k, v in
                          (result.meta.get("categories") or {}).items() if v}
            self.tracker = PoseTracker(self.camera, lightfield.view_shape, self.options,
                                       categories)
        entries = self.tracker.add_frame(views, frame=self.frames)
        self.frames += 1
        return entries

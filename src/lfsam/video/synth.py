"""Synthetic light-field videos with exact ground truth (docs/design.md section 10).

Frame 0 is :func:`lfsam.synth.random_scene`; in the frames after it every object moves in the
image plane (a straight path bouncing off the frame border) and in depth (its disparity swings
by up to 15 % of the disparity range, its slope kept), so objects pass in front of and behind
each other: they occlude and uncover each other over time. One object (the first, label 2 with
the background labelled) leaves the frame through the nearest border and comes back along the
same path (fully out of every view around the middle frame, with ``frames >= 5``). Each frame is
rendered by :func:`lfsam.synth.render_scene`: exact per-view RGB, disparity and labels; an
object keeps its label in every frame. Deterministic per seed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_folder_output
from lfsam.io import write_lightfield
from lfsam.io.native import check_scene_target
from lfsam.lightfield import LightField
from lfsam.synth import PlanarObject, SceneSpec, random_scene, render_scene
from lfsam.video.frames_folder import VIDEO_MARKER

__all__ = ["generate_video", "video_specs", "write_video_frames"]

#: Largest image-plane speed, as a fraction of the view's smaller side per frame.
MAX_SPEED = 0.06
#: Largest change of an object's disparity over the video, as a fraction of the range.
DEPTH_SWING = 0.15


def _extent(obj: PlanarObject, grid: tuple[int, int], range_: tuple[float, float]) -> float:
    """How far (pixels) an object reaches beyond its center in any view, parallax included."""
    corners = obj.center_corners() - np.asarray(obj.center)[:, None]
    reach = max(grid) // 2
    return float(np.abs(corners).max() + max(abs(range_[0]), abs(range_[1])) * reach + 2)


def _moved(obj: PlanarObject, center: tuple[float, float], shift: float,
           band: tuple[float, float]) -> PlanarObject:
    """``obj`` with its center at ``center`` and its disparity raised by ``shift`` (clipped so
    the whole patch stays inside ``band``); slope and shape kept."""
    a, b, c = obj.plane
    corners = obj.center_corners()
    values = a + b * corners[0] + c * corners[1]
    shift = float(np.clip(shift, band[0] - values.min(), band[1] - values.max()))
    du, dv = center[0] - obj.center[0], center[1] - obj.center[1]
    return replace(obj, center=(float(center[0]), float(center[1])),
                   plane=(a - b * du - c * dv + shift, b, c))


def _bounce(start: float, speed: float, frame: int, low: float, high: float) -> float:
    """Position after ``frame`` steps of ``speed`` from ``start``, reflected into [low, high]."""
    if high <= low:
        return start
    period = 2 * (high - low)
    x = (start - low + speed * frame) % period
    return low + (x if x <= high - low else period - x)


def video_specs(
    grid: tuple[int, int] = (5, 5),
    size: tuple[int, int] = (96, 128),
    frames: int = 6,
    seed: int = 0,
    num_objects: int = 4,
    disparity_range: tuple[float, float] = (-2.0, 2.0),
) -> list[SceneSpec]:
    """The scenes of every frame (see the module docstring).

    Raises
    ------
    LfsamError
        For ``frames < 1`` or settings :func:`lfsam.synth.random_scene` rejects.
    """
    if frames < 1:
        raise LfsamError(f"--frames must be at least 1, got {frames}")
    first = random_scene(grid=grid, size=size, seed=seed, num_objects=num_objects,
                         disparity_range=disparity_range)
    rng = np.random.default_rng([seed, 25])
    height, width = first.size
    low, high = disparity_range
    band = (low + 0.25 * (high - low), high)
    background, *objects = first.objects
    paths = []
    for index, obj in enumerate(objects):
        extent = _extent(obj, first.grid, disparity_range)
        heading = rng.uniform(0, 2 * np.pi)
        speed = MAX_SPEED * min(height, width) * rng.uniform(0.4, 1.0)
        phase = rng.uniform(0, 2 * np.pi)
        leaves = index == 0 and frames >= 5
        if leaves:  # out through the nearest border and back along the same line
            u0, v0 = obj.center
            gaps = {(-1, 0): u0, (1, 0): height - u0, (0, -1): v0, (0, 1): width - v0}
            direction = min(gaps, key=gaps.get)
            middle = frames // 2
            speed = (gaps[direction] + extent) / max(middle - 0.5, 1)
            heading = np.arctan2(direction[1], direction[0])
        paths.append((extent, np.cos(heading) * speed, np.sin(heading) * speed, phase, leaves))
    specs = []
    for frame in range(frames):
        moved = []
        for obj, (extent, su, sv, phase, leaves) in zip(objects, paths, strict=True):
            if leaves:
                steps = frame if frame <= frames // 2 else frames // 2 - (frame - frames // 2)
                center = (obj.center[0] + su * steps, obj.center[1] + sv * steps)
            else:
                center = (
                    _bounce(obj.center[0], su, frame, min(extent, height / 2),
                            max(height - extent, height / 2)),
                    _bounce(obj.center[1], sv, frame, min(extent, width / 2),
                            max(width - extent, width / 2)),
                )
            swing = DEPTH_SWING * (high - low) * (np.sin(phase + frame * 0.9) - np.sin(phase))
            moved.append(_moved(obj, center, swing, band))
        meta = {**first.meta, "frame": frame, "frames": frames}
        specs.append(SceneSpec(first.grid, first.size, (background, *moved), meta))
    return specs


def generate_video(
    grid: tuple[int, int] = (5, 5),
    size: tuple[int, int] = (96, 128),
    frames: int = 6,
    seed: int = 0,
    num_objects: int = 4,
    disparity_range: tuple[float, float] = (-2.0, 2.0),
    supersample: int = 2,
) -> Iterator[LightField]:
    """Render the frames one after another (a generator: one frame in memory at a time).

    Examples
    --------
    >>> video = list(generate_video(grid=(3, 3), size=(24, 32), frames=2, num_objects=1))
    >>> len(video), video[1].labels.shape, video[1].meta["frame"]
    (2, (3, 3, 24, 32), 1)
    """
    for frame, spec in enumerate(
        video_specs(grid, size, frames, seed, num_objects, disparity_range)
    ):
        lf = render_scene(spec, supersample=supersample)
        lf.meta["frame"] = frame
        yield lf


def write_video_frames(lightfields: Iterator[LightField], path: str | os.PathLike,
                       meta: dict | None = None) -> Path:
    """Write frames as a video folder (``frame_0000/`` scene folders and the marker
    ``lfsam_video.json``), atomically: nothing is left at ``path`` if writing fails.

    Raises
    ------
    LfsamError
        If ``path`` exists and is not an earlier video or scene folder (or an empty folder).
    """
    path = Path(path)
    if path.exists() and not (path / VIDEO_MARKER).is_file():
        check_scene_target(path)
    count = 0
    with atomic_folder_output(path) as tmp:
        for count, lf in enumerate(lightfields, start=1):
            write_lightfield(lf, tmp / f"frame_{count - 1:04d}")
        marker = {"format": "lfsam-video", "version": 1, "frames": count, "meta": meta or {}}
        (tmp / VIDEO_MARKER).write_text(json.dumps(marker, indent=1), encoding="utf-8")
    return path

"""Synthetic light-field videos with exact ground truth (docs/design.md section 10).

Frame 0 is :func:`lfsam.synth.random_scene`; in the frames after it every object moves in the
image plane (a straight path bouncing off the frame border) and in depth (its disparity swings
by up to 15 % of the disparity range, its slope kept), so objects pass in front of and behind
each other: they occlude and uncover each other over time. One object (the first, label 2 with
the background labelled) leaves the frame through the nearest border and comes back along the
same path (fully out of every view around the middle frame, with ``frames >= 5``). Each frame is
rendered by :func:`lfsam.synth.render_scene`: exact per-view RGB, disparity and labels; an
object keeps its label in every frame. Deterministic per seed.

``hard=True`` (issue 47; default off, so the videos above stay byte-identical) adds the hard
cases of tracking through clutter, drawn from a random stream of their own: every other object
moves at 3-6 pixels per frame and its disparity swings by up to :data:`HARD_DEPTH_SWING` of the
range (depth order changes); with three objects or more, the largest object after the first
becomes a near occluder in the middle of the view moving 1 pixel per frame, and the smallest
one a small disc behind it that passes straight through its middle around the middle frame,
fully hidden there in the center view for several frames (``frames >= 10``: about 3-5; the
outer views may still see it by parallax), its disparity drifting. The first object still
leaves and comes back. ``meta["hard"]`` names the occluder and the hidden object.
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
from lfsam.video.io.frames_folder import VIDEO_MARKER

__all__ = ["generate_video", "video_specs", "write_video_frames"]

#: Largest image-plane speed, as a fraction of the view's smaller side per frame.
MAX_SPEED = 0.06
#: Largest change of an object's disparity over the video, as a fraction of the range.
DEPTH_SWING = 0.15
#: ``hard=True``: largest image-plane speed (pixels per frame) and depth swing (of the range).
HARD_SPEED = 6.0
HARD_DEPTH_SWING = 0.3


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
    hard: bool = False,
) -> list[SceneSpec]:
    """The scenes of every frame (see the module docstring; ``hard``: the hard cases).

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
    swings = [DEPTH_SWING] * len(objects)
    pair: tuple[int, int] | None = None
    hidden_path = None
    if hard:
        objects, paths, swings, pair, hidden_path = _hard_cases(
            objects, paths, first.size, frames, seed, disparity_range, first.grid)
    specs = []
    for frame in range(frames):
        moved = []
        for index, (obj, (extent, su, sv, phase, leaves)) in enumerate(
                zip(objects, paths, strict=True)):
            if pair is not None and index == pair[1]:
                moved.append(obj)  # placed once its occluder is (below)
                continue
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
            swing = swings[index] * (high - low) * (np.sin(phase + frame * 0.9) - np.sin(phase))
            moved.append(_moved(obj, center, swing, band))
        if pair is not None and hidden_path is not None:
            moved[pair[1]] = hidden_path(moved[pair[0]], frame)
        meta = {**first.meta, "frame": frame, "frames": frames}
        if hard:
            meta["hard"] = {"occluder": None if pair is None else objects[pair[0]].label,
                            "hidden": None if pair is None else objects[pair[1]].label}
        specs.append(SceneSpec(first.grid, first.size, (background, *moved), meta))
    return specs


def _hard_cases(objects, paths, size, frames, seed, disparity_range, grid):
    """``hard=True`` (module docstring): faster objects with larger depth swings, and an
    occluder with an object passing behind it. Returns the objects, their paths, their depth
    swings, the (occluder, hidden) indices (None with fewer than three objects) and the hidden
    object's position as a function of the occluder's moved patch and the frame."""
    rng = np.random.default_rng([seed, 47])
    height, width = size
    low, high = disparity_range
    span = high - low
    objects, paths = list(objects), list(paths)
    swings = [DEPTH_SWING] * len(objects)
    for index, (extent, su, sv, phase, leaves) in enumerate(paths):
        if leaves:
            continue
        speed = HARD_SPEED * rng.uniform(0.5, 1.0)
        norm = max(float(np.hypot(su, sv)), 1e-9)
        paths[index] = (extent, su / norm * speed, sv / norm * speed, phase, leaves)
        swings[index] = HARD_DEPTH_SWING
    others = [i for i in range(len(objects)) if not paths[i][4]]
    if len(others) < 2:
        return objects, paths, swings, None, None
    area = [objects[i].half_size[0] * objects[i].half_size[1] for i in others]
    a_index = others[int(np.argmax(area))]
    b_index = min((i for i in others if i != a_index),
                  key=lambda i: objects[i].half_size[0] * objects[i].half_size[1])
    small = min(height, width)
    r_a, r_b = 0.2 * small, 0.08 * small
    depth_a, depth_b = high - 0.05 * span, low + 0.45 * span
    center_a = (height / 2 + rng.uniform(-4, 4), width / 2 + rng.uniform(-4, 4))
    occluder = replace(objects[a_index], shape="ellipse", center=center_a,
                       half_size=(r_a, 1.25 * r_a), plane=(depth_a, 0.0, 0.0))
    heading = rng.uniform(0, 2 * np.pi)
    paths[a_index] = (_extent(occluder, grid, disparity_range), np.cos(heading),
                      np.sin(heading), paths[a_index][3], False)
    swings[a_index] = 0.0
    objects[a_index] = occluder
    hidden = replace(objects[b_index], shape="ellipse", half_size=(r_b, r_b), angle=0.0,
                     plane=(depth_b, 0.0, 0.0))
    objects[b_index] = hidden
    swings[b_index] = 0.0
    middle = frames // 2
    speed_b = HARD_SPEED - 1.0  # with the occluder's 1 pixel per frame: at most HARD_SPEED
    heading_b = rng.uniform(0, 2 * np.pi)
    step = (np.cos(heading_b) * speed_b, np.sin(heading_b) * speed_b)
    drift = rng.uniform(-0.1, 0.1) * span

    def hidden_at(moved_occluder: PlanarObject, frame: int) -> PlanarObject:
        u, v = moved_occluder.center
        center = (u + step[0] * (frame - middle), v + step[1] * (frame - middle))
        return _moved(hidden, center, drift * frame / max(frames - 1, 1),
                      (low, depth_a - 0.1 * span))

    return objects, paths, swings, (a_index, b_index), hidden_at


def generate_video(
    grid: tuple[int, int] = (5, 5),
    size: tuple[int, int] = (96, 128),
    frames: int = 6,
    seed: int = 0,
    num_objects: int = 4,
    disparity_range: tuple[float, float] = (-2.0, 2.0),
    supersample: int = 2,
    hard: bool = False,
) -> Iterator[LightField]:
    """Render the frames one after another (a generator: one frame in memory at a time).

    Examples
    --------
    >>> video = list(generate_video(grid=(3, 3), size=(24, 32), frames=2, num_objects=1))
    >>> len(video), video[1].labels.shape, video[1].meta["frame"]
    (2, (3, 3, 24, 32), 1)
    """
    for frame, spec in enumerate(
        video_specs(grid, size, frames, seed, num_objects, disparity_range, hard)
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

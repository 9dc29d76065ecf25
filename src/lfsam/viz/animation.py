"""Animations running through the views in snake order (GIF, or MP4 with imageio-ffmpeg).

The paper's supplementary material shows results as video; playing the views in snake order
(row 0 left to right, row 1 right to left, ...; :func:`lfsam.lightfield.snake_order`, the frame
order of the SAM 2 video baseline, docs/design.md section 4) makes every frame step a single view
step, so a consistent segmentation moves smoothly with the parallax and a flickering label stands
out.

Each frame is the view's overlay with, below it, a small map of the view grid on which the
current view is lit (:func:`indicator_strip`). Besides telling the viewer where they are, it makes
consecutive frames differ, so GIF writers never merge identical views into one frame: a GIF
always has ``S * T`` frames.
"""

from __future__ import annotations

import importlib.util
import itertools
import os
import warnings
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from PIL import Image
from tqdm.auto import tqdm

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.lightfield import snake_order
from lfsam.viz.layout import _matching_labels, _to_numpy, as_rgb_uint8, blank
from lfsam.viz.overlay import overlay_view

__all__ = [
    "ANIMATION_SUFFIXES",
    "animation_frames",
    "ffmpeg_available",
    "indicator_strip",
    "write_animation",
]

#: File suffixes :func:`write_animation` understands.
ANIMATION_SUFFIXES = (".gif", ".mp4")

_INDICATOR_BG = (40, 40, 40)
_INDICATOR_OFF = (110, 110, 110)
_INDICATOR_ON = (255, 220, 0)


def _indicator_cell(grid_shape: tuple[int, int], width: int) -> int:
    """Cell size of the grid map: up to 4 px, small enough for ``T`` cells to fit ``width``."""
    return int(np.clip((width - 1) // grid_shape[1] - 1, 1, 4))


def indicator_strip(
    grid_shape: tuple[int, int], current: tuple[int, int], width: int
) -> np.ndarray:
    """A strip with a map of the ``S x T`` view grid, the ``current`` view lit in yellow.

    Cells are ``c = clip((width - 1) // T - 1, 1, 4)`` pixels with 1-pixel gaps, drawn from the
    strip's top-left corner (cropped on the right if ``width`` is too small for the grid).

    Returns
    -------
    strip : ndarray, shape (S * (c + 1) + 1, width, 3), uint8
    """
    s_count, t_count = grid_shape
    c = _indicator_cell(grid_shape, width)
    height = s_count * (c + 1) + 1
    full_w = max(width, t_count * (c + 1) + 1)
    strip = blank(height, full_w, _INDICATOR_BG)
    ys = 1 + np.arange(s_count)[:, None] * (c + 1) + np.arange(c)[None, :]  # (S, c)
    xs = 1 + np.arange(t_count)[:, None] * (c + 1) + np.arange(c)[None, :]  # (T, c)
    strip[np.ix_(ys.ravel(), xs.ravel())] = _INDICATOR_OFF
    s, t = current
    strip[np.ix_(ys[s], xs[t])] = _INDICATOR_ON
    return strip[:, :width]


def animation_frames(
    views: ArrayLike,
    labels: ArrayLike | None = None,
    *,
    order: Sequence[tuple[int, int]] | None = None,
    alpha: float = 0.5,
    boundaries: bool = True,
    masks=None,
    indicator: bool = True,
) -> Iterator[np.ndarray]:
    """Overlay frames of the views, one per view, in snake order.

    Parameters
    ----------
    views : (S, T, U, V, 3) array_like, uint8
    labels : (S, T, U, V) array_like of int, optional
    order : sequence of (s, t), optional
        Frame order; default :func:`lfsam.lightfield.snake_order`.
    alpha, boundaries, masks
        As in :func:`lfsam.viz.grid.view_grid`.
    indicator : bool
        Add the grid map below each frame (:func:`indicator_strip`).

    Yields
    ------
    frame : ndarray, uint8
        ``(U + h, V, 3)``, where ``h`` is the indicator's height (0 without it); the top
        ``U x V`` block is ``overlay_labels(views[s, t], labels[s, t])``.
    """
    views = _to_numpy(views)
    labels = _matching_labels(views, labels)
    grid = views.shape[:2]
    for s, t in snake_order(grid) if order is None else order:
        frame = overlay_view(views, labels, masks, s, t, alpha=alpha, boundaries=boundaries)
        if indicator:
            frame = np.concatenate([frame, indicator_strip(grid, (s, t), frame.shape[1])], axis=0)
        yield frame


def ffmpeg_available() -> bool:
    """Whether MP4 can be written (the optional ``imageio-ffmpeg`` package is installed)."""
    return importlib.util.find_spec("imageio_ffmpeg") is not None


def _write_gif(path: Path, frames: list[np.ndarray], fps: float, loop: int) -> None:
    # Quantise each frame to its own 256-colour palette with Pillow's fast octree (about 25x
    # faster than the median cut Pillow's GIF writer would otherwise apply to RGB frames).
    images = [Image.fromarray(f).quantize(256, method=Image.Quantize.FASTOCTREE) for f in frames]
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(20, round(1000.0 / fps)),
        loop=loop,
        optimize=False,
    )


def _write_mp4(path: Path, frames: Iterable[np.ndarray], fps: float) -> None:
    import imageio.v2 as imageio  # the legacy ffmpeg plugin, backed by imageio-ffmpeg

    writer = imageio.get_writer(
        path,
        format="FFMPEG",
        mode="I",
        fps=fps,
        codec="libx264",
        quality=8,
        pixelformat="yuv420p",
        macro_block_size=1,
        ffmpeg_log_level="error",
    )
    try:
        for frame in frames:
            # yuv420p needs even sizes: pad the last row/column by edge replication.
            pad_h, pad_w = frame.shape[0] % 2, frame.shape[1] % 2
            if pad_h or pad_w:
                frame = np.pad(frame, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")
            writer.append_data(frame)
    finally:
        writer.close()


def write_animation(
    path: str | os.PathLike,
    frames: Iterable[np.ndarray],
    *,
    fps: float = 8.0,
    loop: int = 0,
    progress: bool | None = None,
    total: int | None = None,
) -> Path:
    """Write frames as an animated GIF or an MP4 video, atomically.

    Parameters
    ----------
    path : path-like
        ``.gif`` (Pillow) or ``.mp4`` (H.264 via the optional ``imageio-ffmpeg``; frames of odd
        size are padded by one row/column). When ``imageio-ffmpeg`` is missing, an ``.mp4`` request
        writes a GIF next to it (same name, ``.gif``) and warns how to get MP4.
    frames : iterable of (H, W, 3) uint8 arrays
        All of one size, e.g. from :func:`animation_frames`.
    fps : float
        Frames per second (GIF stores delays in 10 ms steps, at least 20 ms).
    loop : int
        GIF loop count, 0 = forever.
    progress : bool or None
        Show a progress bar (None: only on a terminal).
    total : int, optional
        Number of frames, for the progress bar.

    Returns
    -------
    path : Path
        The file written (the ``.gif`` when MP4 fell back to GIF).

    Raises
    ------
    LfsamError
        If the suffix is not ``.gif`` or ``.mp4``, or there are no frames.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in ANIMATION_SUFFIXES:
        raise LfsamError(
            f"cannot write an animation to {str(path)!r}; give a file ending in .gif or .mp4"
        )
    if fps <= 0:
        raise LfsamError(f"frames per second must be > 0, got {fps}")
    if suffix == ".mp4" and not ffmpeg_available():
        path = path.with_suffix(".gif")
        suffix = ".gif"
        warnings.warn(
            f"MP4 needs the imageio-ffmpeg package (pip install imageio-ffmpeg); "
            f"wrote a GIF instead: {path}",
            UserWarning,
            stacklevel=2,
        )
    bar = tqdm(
        frames,
        desc="frames",
        unit="frame",
        total=total,
        disable=None if progress is None else not progress,
    )
    stream = (as_rgb_uint8(f) for f in bar)
    first = next(stream, None)
    if first is None:
        raise LfsamError("no frames to write; the light field has no views")
    stream = itertools.chain([first], stream)
    with atomic_output(path) as tmp:
        if suffix == ".gif":
            _write_gif(tmp, list(stream), fps, loop)
        else:
            _write_mp4(tmp, stream, fps)
    return path

"""Animations over the frames of a light-field video (docs/design.md section 10).

One animation frame per video frame: either one view (``view=(s, t)``, its overlay) or the
whole view grid (:func:`lfsam.viz.grid.view_grid`), with a time bar below
(:func:`time_strip`): the elapsed part of the video lit, so consecutive frames always differ
(GIF writers never merge them) and the viewer sees where in the video they are. Frames are
drawn one at a time from an iterable, so a long video is never in memory (MP4 streams; GIF
collects the drawn frames).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from lfsam.viz.grid import view_grid
from lfsam.viz.layout import blank
from lfsam.viz.overlay import overlay_view

__all__ = ["time_frames", "time_strip"]

_BAR_HEIGHT = 6
_BAR_BG = (40, 40, 40)
_BAR_DONE = (255, 220, 0)


def time_strip(index: int, count: int, width: int) -> np.ndarray:
    """A bar ``(6, width, 3)`` uint8 whose first ``round(width * (index + 1) / count)``
    columns are lit (frame ``index`` of ``count``).

    Examples
    --------
    >>> bar = time_strip(1, 4, 8)
    >>> bar.shape, int((bar[1, :, 0] == 255).sum())
    ((6, 8, 3), 4)
    """
    strip = blank(_BAR_HEIGHT, width, _BAR_BG)
    strip[1:-1, : round(width * (index + 1) / max(count, 1))] = _BAR_DONE
    return strip


def time_frames(
    frames: Iterable[tuple[np.ndarray, np.ndarray | None]],
    count: int,
    *,
    view: tuple[int, int] | None = None,
    alpha: float = 0.5,
    boundaries: bool = True,
) -> Iterator[np.ndarray]:
    """Animation frames of a light-field video.

    Parameters
    ----------
    frames : iterable of (views, labels)
        Per video frame, views ``(S, T, U, V, 3)`` uint8 and labels ``(S, T, U, V)`` (or None).
    count : int
        Number of video frames (for the time bar).
    view : (s, t), optional
        Show this view only; default the whole grid.
    alpha, boundaries
        As in :func:`lfsam.viz.overlay.overlay_labels`.

    Yields
    ------
    frame : (H + 6, W, 3) uint8 ndarray
        The view's overlay or the grid figure, the time bar below.
    """
    for index, (views, labels) in enumerate(frames):
        if view is not None:
            image = overlay_view(views, labels, None, view[0], view[1], alpha=alpha,
                                 boundaries=boundaries)
        else:
            image = view_grid(views, labels, which="all", alpha=alpha, boundaries=boundaries,
                              progress=False)
        yield np.concatenate([image, time_strip(index, count, image.shape[1])], axis=0)

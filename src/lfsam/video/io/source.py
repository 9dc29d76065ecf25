"""The light-field video data model: :class:`LightFieldVideo` (docs/design.md section 10).

A light-field video is ``L[f, s, t, u, v, c]``: ``F`` frames, each a light field in the
convention of docs/design.md section 1, all with the same grid and view size. Frames are read
on demand by a *frame source* (any object with ``read(index) -> LightField``, ``num_frames``,
``grid_shape``, ``view_shape`` and ``close()``), so a 300-frame 9x9x480x640 video (about 22 GB
of pixels) never sits in memory: only the frame asked for does.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Protocol

from lfsam.errors import FrameError, LfsamError
from lfsam.lightfield import LightField

__all__ = ["FrameSource", "LightFieldVideo", "check_frame"]


class FrameSource(Protocol):
    """What :class:`LightFieldVideo` needs from a reader."""

    num_frames: int
    grid_shape: tuple[int, int]
    view_shape: tuple[int, int]
    has_disparity: bool
    has_labels: bool

    def read(self, index: int) -> LightField:
        """Frame ``index`` (0-based, in range) as a light field."""

    def close(self) -> None:
        """Release open files."""


def check_frame(lf: LightField, index: int, grid: tuple[int, int], size: tuple[int, int],
                where: str) -> LightField:
    """Check that frame ``index`` has the video's grid and view size; return it.

    Raises
    ------
    FrameError
        One line naming the frame, its shape and the video's (an :class:`LfsamError`).
    """
    if lf.grid_shape != tuple(grid) or lf.view_shape != tuple(size):
        raise FrameError(
            f"frame {index} of {where} has {lf.grid_shape[0]} x {lf.grid_shape[1]} views of "
            f"{lf.view_shape[0]} x {lf.view_shape[1]}, but frame 0 has {grid[0]} x {grid[1]} "
            f"views of {size[0]} x {size[1]}; every frame needs the same grid and view size"
        )
    return lf


class LightFieldVideo:
    """A sequence of light fields read lazily, frame by frame.

    Parameters
    ----------
    source : FrameSource
        The reader (:mod:`lfsam.video.io.detect` picks one from a path).
    meta : dict, optional
        ``source`` (the path), ``format`` (the reader) and reader notes.

    Examples
    --------
    >>> import numpy as np
    >>> from lfsam.video.io.arrays import ArrayFrames
    >>> video = LightFieldVideo(ArrayFrames(np.zeros((4, 3, 3, 8, 10, 3), np.uint8)))
    >>> len(video), video.shape, video.frame(2).grid_shape
    (4, (4, 3, 3, 8, 10), (3, 3))
    >>> video.describe_line()
    '4 frames of 3 x 3 views of 8 x 10'
    """

    def __init__(self, source: FrameSource, meta: dict[str, Any] | None = None) -> None:
        if source.num_frames < 1:
            raise LfsamError("a light-field video needs at least one frame")
        self._source = source
        self.meta: dict[str, Any] = dict(meta or {})

    def __len__(self) -> int:
        return self._source.num_frames

    @property
    def num_frames(self) -> int:
        """F."""
        return self._source.num_frames

    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(S, T)``."""
        return tuple(self._source.grid_shape)

    @property
    def view_shape(self) -> tuple[int, int]:
        """``(U, V)``."""
        return tuple(self._source.view_shape)

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        """``(F, S, T, U, V)``."""
        return (self.num_frames, *self.grid_shape, *self.view_shape)

    @property
    def center(self) -> tuple[int, int]:
        """The reference view ``(S // 2, T // 2)`` of every frame."""
        return self.grid_shape[0] // 2, self.grid_shape[1] // 2

    @property
    def has_disparity(self) -> bool:
        """Whether frames carry ground-truth disparity."""
        return bool(self._source.has_disparity)

    @property
    def has_labels(self) -> bool:
        """Whether frames carry ground-truth labels."""
        return bool(self._source.has_labels)

    def frame(self, index: int) -> LightField:
        """Frame ``index`` (negative counts from the end) as a :class:`LightField`, read now.

        Raises
        ------
        LfsamError
            For an index outside the video, or a frame that does not fit the video.
        """
        count = self.num_frames
        if not -count <= int(index) < count:
            raise LfsamError(f"frame {index} is outside the video (frames 0..{count - 1})")
        index = int(index) % count
        lf = self._source.read(index)
        lf.meta.setdefault("source", self.meta.get("source", "<video>"))
        lf.meta["frame"] = index
        return lf

    def __iter__(self) -> Iterator[LightField]:
        for index in range(self.num_frames):
            yield self.frame(index)

    def describe_line(self) -> str:
        """``"6 frames of 5 x 5 views of 96 x 128"``."""
        (s, t), (u, v) = self.grid_shape, self.view_shape
        noun = "frame" if self.num_frames == 1 else "frames"
        return f"{self.num_frames} {noun} of {s} x {t} views of {u} x {v}"

    def describe(self) -> dict[str, Any]:
        """A JSON-ready summary (``lfsam info``)."""
        return {
            "source": self.meta.get("source"),
            "format": self.meta.get("format"),
            "frames": self.num_frames,
            "grid": list(self.grid_shape),
            "view_size": list(self.view_shape),
            "center": list(self.center),
            "disparity": "per frame" if self.has_disparity else None,
            "labels": "per frame" if self.has_labels else None,
            "summary": self.describe_line(),
        }

    def close(self) -> None:
        """Close the reader's files (also on ``with`` exit)."""
        self._source.close()

    def __enter__(self) -> LightFieldVideo:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

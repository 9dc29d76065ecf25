"""Light-field videos in napari: lazy array-likes for the views and the labels (Qt-free).

docs/design.md sections 8 and 10. A light-field video is shown as one RGB image layer
``(F, S, T, U, V, 3)`` whose first axis is the ``frame`` slider. napari needs only ``shape``,
``dtype``, ``ndim`` and ``__getitem__`` of a layer's data and slices one frame at a time, so
:class:`VideoFrames` reads the frame asked for through :meth:`LightFieldVideo.frame` and keeps a
few in a small cache: a 300-frame 9x9x480x640 video never sits in memory.

The mask layers of a video are :class:`FrameStore` objects ``(F, S, T, U, V)``: frames the
viewer has written (an interactive segmentation of the frame shown, or a tracked frame as it
finishes) are held in memory up to a budget and spilled to compressed files beyond it; frames of
a finished track are read from the result folder (:class:`lfsam.video.io.result.VideoResult`);
every other frame reads as zeros, without being stored.
"""

from __future__ import annotations

import tempfile
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.video.io.source import LightFieldVideo

__all__ = ["VIDEO_KEY", "FrameStore", "VideoFrames", "frames_of", "video_layers"]

#: Metadata key of the image layer that shows a video.
VIDEO_KEY = "lfsam_video"
#: Axis labels of a video's layers (the first is the frame slider).
VIDEO_AXES = ("frame", "s", "t", "u", "v")


def frames_of(key: Any, count: int) -> tuple[list[int], Any, bool]:
    """Split an index on a ``(F, ...)`` array into frames and the index of one frame.

    Returns
    -------
    frames : list of int
        The frames the index selects.
    rest : tuple
        The index into one frame.
    single : bool
        Whether the frame axis is dropped (an integer frame index).
    """
    key = key if isinstance(key, tuple) else (key,)
    if key and key[0] is Ellipsis:
        key = (slice(None), *key) if len(key) > 1 else (slice(None),)
    first, rest = (key[0], key[1:]) if key else (slice(None), ())
    if isinstance(first, (int, np.integer)):
        return [int(first) % count], rest, True
    return list(np.arange(count)[first].reshape(-1)), rest, False


class _LazyFrames:
    """An ``(F, ...)`` array-like whose frames come from :meth:`_frame` (subclasses)."""

    shape: tuple[int, ...]
    dtype: np.dtype

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self.shape)

    @property
    def size(self) -> int:
        """Number of elements (never read)."""
        return int(np.prod(self.shape))

    def __len__(self) -> int:
        return self.shape[0]

    def _frame(self, index: int) -> np.ndarray:
        raise NotImplementedError

    def __getitem__(self, key: Any) -> np.ndarray:
        frames, rest, single = frames_of(key, self.shape[0])
        if single:
            return self._frame(frames[0])[rest]
        parts = [self._frame(f)[rest] for f in frames]
        if not parts:
            return np.zeros((0, *self.shape[1:]), self.dtype)[(slice(None), *rest)]
        return np.stack(parts)

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        """Every frame (napari asks only for small videos' whole data, e.g. to save a layer)."""
        out = self[:]
        return out if dtype is None else out.astype(dtype)


class VideoFrames(_LazyFrames):
    """The views of a video, ``(F, S, T, U, V, 3)`` uint8, read one frame at a time.

    Parameters
    ----------
    video : LightFieldVideo
    cache : int
        Frames kept after reading (the last ones read).

    Attributes
    ----------
    reads : int
        How many frames were read from the video (tests count them).
    """

    def __init__(self, video: LightFieldVideo, cache: int = 3) -> None:
        self.video = video
        self.shape = (*video.shape, 3)
        self.dtype = np.dtype(np.uint8)
        self.reads = 0
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._size = max(1, int(cache))

    def _frame(self, index: int) -> np.ndarray:
        if index in self._cache:
            self._cache.move_to_end(index)
            return self._cache[index]
        views = self.video.frame(index).views
        self.reads += 1
        self._cache[index] = views
        while len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return views


class FrameStore(_LazyFrames):
    """Labels ``(F, S, T, U, V)`` int32 filled frame by frame (a video's mask layer).

    Parameters
    ----------
    shape : (F, S, T, U, V)
    budget_mb : float
        Memory held by written frames; beyond it the least recently used are spilled to
        compressed ``.npz`` files in a temporary folder (labels compress well).
    """

    def __init__(self, shape: tuple[int, ...], budget_mb: float = 256.0) -> None:
        self.shape = tuple(int(x) for x in shape)
        self.dtype = np.dtype(np.int32)
        frame_bytes = int(np.prod(self.shape[1:])) * self.dtype.itemsize
        self._keep = max(2, int(budget_mb * 2**20 // max(frame_bytes, 1)))
        self._live: OrderedDict[int, np.ndarray] = OrderedDict()
        self._spilled: set[int] = set()
        self._folder: tempfile.TemporaryDirectory | None = None
        self.result: Any = None

    # --- reading --------------------------------------------------------------------------------
    def _frame(self, index: int) -> np.ndarray:
        if index in self._live:
            self._live.move_to_end(index)
            return self._live[index]
        if index in self._spilled:
            with np.load(self._spill_path(index)) as npz:
                return npz["labels"]
        if self.result is not None:
            return np.asarray(self.result.frame(index).labels, dtype=self.dtype)
        return np.zeros(self.shape[1:], self.dtype)

    def written(self) -> list[int]:
        """The frames written into the store (held or spilled), sorted."""
        return sorted({*self._live, *self._spilled})

    # --- writing --------------------------------------------------------------------------------
    def frame_array(self, index: int) -> np.ndarray:
        """Frame ``index`` as a writable array kept by the store (edits stay)."""
        index = int(index) % self.shape[0]
        if index not in self._live:
            self.put(index, self._frame(index).copy())
        self._live.move_to_end(index)
        return self._live[index]

    def put(self, index: int, labels: np.ndarray) -> None:
        """Set frame ``index`` to ``labels`` ``(S, T, U, V)``.

        Raises
        ------
        ValueError
            For labels of another shape (the caller's code is at fault).
        """
        labels = np.asarray(labels)
        if labels.shape != self.shape[1:]:
            raise ValueError(f"labels {labels.shape} do not fit frames {self.shape[1:]}")
        index = int(index) % self.shape[0]
        self._spilled.discard(index)
        self._live[index] = labels.astype(self.dtype, copy=True)
        self._live.move_to_end(index)
        while len(self._live) > self._keep:
            old, array = self._live.popitem(last=False)
            np.savez_compressed(self._spill_path(old), labels=array)
            self._spilled.add(old)

    def __setitem__(self, key: Any, value: Any) -> None:
        """Write through an index on ``(F, S, T, U, V)``: an integer or slice of frames, or
        napari's painting index (one coordinate array per axis), frame by frame."""
        key = key if isinstance(key, tuple) else (key,)
        if key and isinstance(key[0], np.ndarray) and key[0].ndim == 1 and len(key) > 1:
            frames = np.asarray(key[0]).astype(int)
            values = np.asarray(value)
            for frame in np.unique(frames):
                chosen = frames == frame
                part = values[chosen] if values.ndim and values.shape[0] == len(frames) else values
                self.frame_array(int(frame))[tuple(np.asarray(k)[chosen] for k in key[1:])] = part
            return
        frames, rest, single = frames_of(key, self.shape[0])
        values = np.asarray(value)
        for i, frame in enumerate(frames):
            part = values if single or values.ndim < self.ndim else values[i]
            self.frame_array(frame)[rest] = part

    def clear(self) -> None:
        """Forget every written frame (a result attached stays)."""
        self._live.clear()
        self._spilled.clear()

    def attach_result(self, result: Any) -> None:
        """Read frames from ``result`` (a :class:`VideoResult`) from now on; written frames are
        dropped (the result holds them)."""
        self.clear()
        self.result = result

    def _spill_path(self, index: int) -> Path:
        if self._folder is None:
            self._folder = tempfile.TemporaryDirectory(prefix="lfsam-view-")
        return Path(self._folder.name) / f"frame_{index:06d}.npz"


def video_layers(video: LightFieldVideo, name: str | None = None) -> list[tuple]:
    """Layer data tuples for a video: one lazy RGB image layer ``(F, S, T, U, V, 3)``.

    Parameters
    ----------
    video : LightFieldVideo
    name : str, optional
        Layer name; default the source's file name.

    Returns
    -------
    list of (data, kwargs, "image")
        The image layer; its metadata keeps the video (:data:`VIDEO_KEY`).
    """
    source = video.meta.get("source")
    name = name or (Path(str(source)).name if source else "light-field video")
    kwargs = {
        "name": name,
        "rgb": True,
        "contrast_limits": (0, 255),  # napari would otherwise read frames to find the range
        "axis_labels": VIDEO_AXES,
        "metadata": {VIDEO_KEY: video},
    }
    return [(VideoFrames(video), kwargs, "image")]

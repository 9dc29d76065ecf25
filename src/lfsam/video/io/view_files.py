"""A light-field video as one video file per view (docs/design.md section 10).

A folder of ``view_SS_TT.mp4`` (0-based view row ``SS`` and column ``TT``; ``.mp4``, ``.mkv``,
``.avi``, ``.mov`` or ``.webm``; any ``[prefix_]ROW_COL`` name, 0- or 1-based, is accepted and
shifted to start at 0), decoded with imageio-ffmpeg (the optional ``video`` extra; it ships its
own ffmpeg). Every view keeps one open decoder, so reading frames in order decodes each video
once; asking for an earlier frame restarts that view's decoder with a seek. The per-view video
codec is lossy unless written losslessly: frames come back as decoded.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["VIDEO_SUFFIXES", "ViewVideoFrames", "list_view_videos", "write_view_videos"]

VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi", ".mov", ".webm")
_NAME = re.compile(r"^(?:.*?[_-])?(\d+)[_-](\d+)$")


def _ffmpeg() -> Any:
    try:
        import imageio_ffmpeg
    except ImportError:
        raise LfsamError(
            "reading per-view video files needs imageio-ffmpeg; install lfsam[video]"
        ) from None
    return imageio_ffmpeg


def list_view_videos(folder: Path) -> dict[tuple[int, int], Path]:
    """Video files of a folder by 0-based ``(s, t)`` (empty if it holds none).

    Raises
    ------
    LfsamError
        If video files are there but their names do not form a complete grid.
    """
    files = [p for p in folder.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES
             and not p.name.startswith(".")]
    if not files:
        return {}
    parsed = {}
    for path in files:
        match = _NAME.match(path.stem)
        if match is None:
            raise LfsamError(
                f"cannot tell the view of {path.name} in {folder}; name per-view videos "
                "view_SS_TT.mp4 (view row, view column)"
            )
        parsed[(int(match[1]), int(match[2]))] = path
    rows = sorted({s for s, _ in parsed})
    cols = sorted({t for _, t in parsed})
    grid = {(s - rows[0], t - cols[0]): p for (s, t), p in parsed.items()}
    s_count, t_count = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    if len(grid) != s_count * t_count:
        missing = [f"{s},{t}" for s in range(s_count) for t in range(t_count)
                   if (s, t) not in grid]
        raise LfsamError(
            f"{folder} holds {len(grid)} view videos, not a full {s_count} x {t_count} grid "
            f"(missing views {', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''})"
        )
    return grid


class _Decoder:
    """One view's decoder, positioned at ``position`` (the next frame it yields)."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path, self.fps = path, fps
        self.frames: Iterator[Any] | None = None
        self.position = 0
        self.size: tuple[int, int] = (0, 0)

    def _open(self, start: int) -> None:
        self.close()
        params = ["-ss", f"{start / self.fps:.6f}"] if start > 0 else None
        self.frames = _ffmpeg().read_frames(str(self.path), input_params=params)
        meta = next(self.frames)
        self.size = tuple(int(x) for x in meta["size"])  # (width, height)
        self.position = start

    def read(self, index: int) -> np.ndarray:
        if self.frames is None or index < self.position:
            self._open(index)
        assert self.frames is not None
        data = None
        while self.position <= index:
            try:
                data = next(self.frames)
            except StopIteration:
                raise LfsamError(f"{self.path.name} ends before frame {index}") from None
            self.position += 1
        width, height = self.size
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3)

    def close(self) -> None:
        if self.frames is not None:
            self.frames.close()
            self.frames = None


class ViewVideoFrames:
    """Frames from a folder of per-view video files.

    Raises
    ------
    LfsamError
        No videos, names not a grid, or views with different frame counts or sizes.
    """

    has_disparity = False
    has_labels = False

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = Path(folder)
        grid = list_view_videos(self.folder)
        if not grid:
            raise LfsamError(f"no view videos (view_SS_TT.mp4) in {str(self.folder)!r}")
        ffmpeg = _ffmpeg()
        counts = {view: ffmpeg.count_frames_and_secs(str(path))[0]
                  for view, path in grid.items()}
        first = min(grid)
        if len(set(counts.values())) > 1:
            odd = next(v for v in sorted(counts) if counts[v] != counts[first])
            raise LfsamError(
                f"{grid[odd].name} has {counts[odd]} frames but {grid[first].name} has "
                f"{counts[first]}; every view video needs the same number of frames"
            )
        reader = ffmpeg.read_frames(str(grid[first]))
        meta = next(reader)
        reader.close()
        fps = float(meta.get("fps") or 25.0)
        self.num_frames = int(counts[first])
        self.grid_shape = (max(s for s, _ in grid) + 1, max(t for _, t in grid) + 1)
        width, height = (int(x) for x in meta["size"])
        self.view_shape = (height, width)
        self.decoders = {view: _Decoder(path, fps) for view, path in grid.items()}

    def read(self, index: int) -> LightField:
        """Frame ``index``: one image decoded from every view's video."""
        s_count, t_count = self.grid_shape
        views = np.empty((s_count, t_count, *self.view_shape, 3), dtype=np.uint8)
        for (s, t), decoder in self.decoders.items():
            image = decoder.read(index)
            if image.shape[:2] != self.view_shape:
                raise LfsamError(
                    f"{decoder.path.name} has frames of {image.shape[0]} x {image.shape[1]}, "
                    f"the other views {self.view_shape[0]} x {self.view_shape[1]}"
                )
            views[s, t] = image
        return LightField(views, meta={"source": str(self.folder)})

    def close(self) -> None:
        """Stop every decoder."""
        for decoder in self.decoders.values():
            decoder.close()


def write_view_videos(frames: Iterator[np.ndarray], folder: str | os.PathLike,
                      grid_shape: tuple[int, int], fps: float = 10.0,
                      lossless: bool = True) -> Path:
    """Write views ``[S, T, U, V, 3]`` frame after frame as ``view_SS_TT.mp4`` files.

    ``lossless`` encodes H.264 in RGB (``libx264rgb``, ``-qp 0``), so frames decode exactly;
    otherwise ``yuv420p`` as most players expect. The folder must exist.
    """
    ffmpeg = _ffmpeg()
    folder = Path(folder)
    s_count, t_count = grid_shape
    writers: dict[tuple[int, int], Any] = {}
    try:
        for frame in frames:
            for s in range(s_count):
                for t in range(t_count):
                    if (s, t) not in writers:
                        height, width = frame.shape[2:4]
                        codec = {"codec": "libx264rgb", "pix_fmt_out": "rgb24",
                                 "output_params": ["-qp", "0"]} if lossless else {}
                        writers[(s, t)] = ffmpeg.write_frames(
                            str(folder / f"view_{s:02d}_{t:02d}.mp4"), (width, height),
                            fps=fps, macro_block_size=1, **codec,
                        )
                        writers[(s, t)].send(None)
                    writers[(s, t)].send(np.ascontiguousarray(frame[s, t]))
    finally:
        for writer in writers.values():
            writer.close()
    return folder

"""A light-field video as a folder of frames (docs/design.md section 10).

Each entry of the folder is one frame, any light field :func:`lfsam.io.read_lightfield`
reads (a folder of views, an ``.npz``/``.npy``/``.h5``/``.mat`` file), in natural name order
(``frame_2`` before ``frame_10``). Hidden entries and the video marker
(:data:`VIDEO_MARKER`, written by ``lfsam synth --frames``) are skipped. Frame 0 is read when
the video is opened (it fixes the grid and view size); every other frame when asked for, and
checked then.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Container
from pathlib import Path
from typing import Any

from lfsam.errors import LfsamError
from lfsam.io import read_lightfield
from lfsam.lightfield import LightField
from lfsam.video.io.source import check_frame

__all__ = ["VIDEO_MARKER", "FolderFrames", "frame_entries", "read_marker"]

VIDEO_MARKER = "lfsam_video.json"
FRAME_FILE_SUFFIXES = (".npz", ".npy", ".h5", ".hdf5", ".mat")


def _natural_key(name: str) -> list[Any]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name)]


def frame_entries(folder: Path, skip: Container[str] = ()) -> list[Path]:
    """The frames of a folder: sub-folders and light-field files, in natural name order;
    names in ``skip`` left out before anything else is looked at (a followed folder's frames
    already seen: each look costs little however many frames the folder holds)."""
    with os.scandir(folder) as scan:
        entries = [
            Path(entry.path)
            for entry in scan
            if entry.name not in skip
            and not entry.name.startswith(".")
            and entry.name != VIDEO_MARKER
            and (entry.is_dir() or os.path.splitext(entry.name)[1].lower()
                 in FRAME_FILE_SUFFIXES)
        ]
    return sorted(entries, key=lambda entry: _natural_key(entry.name))


def read_marker(folder: Path) -> dict[str, Any]:
    """The video marker's JSON (``{}`` when absent or unreadable)."""
    try:
        data = json.loads((folder / VIDEO_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


class FolderFrames:
    """Frames read one at a time from a folder of light fields.

    Raises
    ------
    LfsamError
        For an empty folder, or when frame 0 is not a light field.
    """

    def __init__(self, folder: str | os.PathLike, value_range: int | None = None) -> None:
        self.folder = Path(folder)
        self.entries = frame_entries(self.folder)
        if not self.entries:
            raise LfsamError(
                f"folder {str(self.folder)!r} holds no frames; a light-field video folder holds "
                "one light field per frame (a folder of views or an .npz/.npy/.h5 file each)"
            )
        self.value_range = value_range
        first = self._read(0)
        self.num_frames = len(self.entries)
        self.grid_shape = first.grid_shape
        self.view_shape = first.view_shape
        self.has_disparity = first.disparity is not None
        self.has_labels = first.labels is not None

    def _read(self, index: int) -> LightField:
        path = self.entries[index]
        try:
            return read_lightfield(path, value_range=self.value_range)
        except LfsamError as exc:
            raise LfsamError(f"frame {index} ({path.name}) of {self.folder}: {exc}") from None

    def read(self, index: int) -> LightField:
        """Frame ``index``, read now and checked against frame 0."""
        lf = check_frame(self._read(index), index, self.grid_shape, self.view_shape,
                         str(self.folder))
        lf.meta["frame_source"] = str(self.entries[index])
        return lf

    def close(self) -> None:
        """Nothing stays open."""

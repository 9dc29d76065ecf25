"""Which input is a light-field video, and opening it (docs/design.md section 10).

- a file ``.npy``/``.npz``/``.h5`` whose views are 6-D ``[F, S, T, U, V, 3]``
  (:mod:`lfsam.video.io.arrays`);
- a folder of per-view video files ``view_SS_TT.mp4`` (:mod:`lfsam.video.io.view_files`);
- a folder with the video marker ``lfsam_video.json``, or one that holds no views of its own
  but sub-folders or light-field files: one frame each (:mod:`lfsam.video.io.frames_folder`).

Everything else is a single light field (:func:`lfsam.io.read_lightfield`).
:func:`input_kind` tells the four kinds of input of the commands apart (a light field, a
light-field video, a segmentation result, a video's result folder), so that each command can
say in one line what it was given when it is given one in the wrong role (docs/design.md
section 2, "Outputs and inputs on the command line").
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.io import detect_format, is_native
from lfsam.io.arrays import VIEW_KEYS
from lfsam.io.grid_folder import list_images
from lfsam.io.hci4d import is_hci4d
from lfsam.io.hci_old import is_hci_old
from lfsam.io.urbanlf import is_urbanlf
from lfsam.video.io.arrays import array_video_shape, npz_shapes, open_h5, open_npy, open_npz
from lfsam.video.io.frames_folder import VIDEO_MARKER, FolderFrames, frame_entries, read_marker
from lfsam.video.io.result import RESULT_MARKER
from lfsam.video.io.source import LightFieldVideo
from lfsam.video.io.view_files import VIDEO_SUFFIXES, ViewVideoFrames

__all__ = ["INPUT_KINDS", "input_kind", "is_video", "read_video", "video_kind"]

#: The kinds :func:`input_kind` tells apart.
INPUT_KINDS = ("lightfield", "video", "result", "video-result")


def video_kind(path: str | os.PathLike) -> str | None:
    """``"array"``, ``"view-videos"``, ``"frames"`` or None (not a video; also for a missing
    path). Cheap: reads headers and names only."""
    path = Path(path)
    if path.is_file():
        return "array" if array_video_shape(path) is not None else None
    if not path.is_dir():
        return None
    if (path / VIDEO_MARKER).is_file():
        return "frames"
    if any(p.suffix.lower() in VIDEO_SUFFIXES for p in path.iterdir()):
        return "view-videos"
    if is_native(path) or is_hci_old(path) or is_hci4d(path) or is_urbanlf(path):
        return None
    if list_images(path):
        return None
    return "frames" if frame_entries(path) else None


def is_video(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a light-field video (see the module docstring)."""
    return video_kind(path) is not None


def read_video(path: str | os.PathLike, value_range: int | None = None) -> LightFieldVideo:
    """Open a light-field video lazily (frames are read when asked for).

    Parameters
    ----------
    path : path-like
        Any form of the module docstring.
    value_range : {1, 255}, optional
        For frames stored as floats (see :func:`lfsam.lightfield.float_scale`).

    Raises
    ------
    LfsamError
        Missing path, not a video, or inconsistent frames or views (one line each).
    """
    path = Path(path)
    if not path.exists():
        raise LfsamError(f"no such file or folder: {str(path)!r}; check the path")
    kind = video_kind(path)
    meta: dict = {"source": str(path)}
    if kind == "array":
        suffix = path.suffix.lower()
        opener = open_npy if suffix == ".npy" else open_npz if suffix == ".npz" else open_h5
        source = opener(path)
        meta["format"] = f"video-{suffix[1:]}"
    elif kind == "view-videos":
        source = ViewVideoFrames(path)
        meta["format"] = "view-videos"
    elif kind == "frames":
        source = FolderFrames(path, value_range=value_range)
        meta["format"] = "frames-folder"
        marker = read_marker(path)
        if marker.get("meta"):
            meta["generator"] = marker["meta"]
    elif path.is_dir() and not any(path.iterdir()):
        raise LfsamError(
            f"folder {str(path)!r} is empty; a light-field video is a folder of frames, of "
            "view_SS_TT.mp4 files, or an [F, S, T, U, V, 3] array file"
        )
    else:
        raise LfsamError(
            f"{str(path)!r} is not a light-field video (a folder of frames, of view_SS_TT.mp4 "
            "files, or an .npy/.npz/.h5 array [F, S, T, U, V, 3])"
        )
    return LightFieldVideo(source, meta)


def _file_kind(path: Path) -> str | None:
    """:func:`input_kind` of a file."""
    suffix = path.suffix.lower()
    if suffix == ".npz":
        try:
            shapes = npz_shapes(path)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile):
            return None
        views = [name for name, shape in shapes.items()
                 if name in VIEW_KEYS or (len(shape) in (5, 6) and shape[-1] == 3)]
        if not views:  # labels without views: a result (any .npz with labels is one)
            return "result" if "labels" in shapes else None
    if video_kind(path) is not None:
        return "video"
    if suffix == ".npy":
        try:
            shape = np.load(path, mmap_mode="r", allow_pickle=False).shape
        except (OSError, ValueError):
            return None
        return "lightfield" if len(shape) == 5 else None
    try:
        detect_format(path)
    except LfsamError:
        return None
    return "lightfield"


def input_kind(path: str | os.PathLike) -> str | None:
    """What ``path`` holds, one of :data:`INPUT_KINDS`, from names and headers only.

    ``"result"`` is an ``.npz`` with ``labels`` and no views (:func:`lfsam.result.load_result`),
    ``"video-result"`` a folder with ``lfsam_video_result.json``
    (:mod:`lfsam.video.io.result`), ``"video"`` what :func:`video_kind` finds, ``"lightfield"``
    anything :func:`lfsam.io.detect_format` recognises (or an ``.npz`` / ``.npy`` with a
    5-D views array). Used to check that each input of a command is of a kind it takes
    (docs/design.md section 2, "Outputs and inputs on the command line"; :mod:`lfsam.cli.inputs`).

    Returns
    -------
    str or None
        None for a missing path or one that is none of these (its reader says why).

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> np.savez(folder / "r.npz", labels=np.zeros((3, 3, 4, 5), np.int32))
    >>> np.savez(folder / "lf.npz", views=np.zeros((3, 3, 4, 5, 3), np.uint8))
    >>> np.savez(folder / "clip.npz", views=np.zeros((2, 3, 3, 4, 5, 3), np.uint8))
    >>> [input_kind(folder / name) for name in ("r.npz", "lf.npz", "clip.npz", "none.npz")]
    ['result', 'lightfield', 'video', None]
    >>> import shutil; shutil.rmtree(folder)
    """
    path = Path(path)
    if path.is_file():
        return _file_kind(path)
    if not path.is_dir():
        return None
    if (path / RESULT_MARKER).is_file():
        return "video-result"
    if video_kind(path) is not None:
        return "video"
    try:
        detect_format(path)
    except LfsamError:
        return None
    return "lightfield"

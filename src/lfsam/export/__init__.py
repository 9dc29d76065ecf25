"""Exporting a segmentation result to the formats other tools read (docs/design.md section 8).

==========  ================================================================================
format      what is written into the output folder
==========  ================================================================================
png         ``view_SS_TT.png``: one 16-bit label PNG per view (value = object id)
masks       ``object_NNNN/view_SS_TT.png``: one 1-bit PNG per object and view
coco        ``annotations.json``: COCO, one image per view, one RLE annotation per object and
            view with ``track_id`` = object id
npy         ``labels.npy`` [S, T, U, V], ``masks.npy`` [K, S, T, U, V], ``ids.npy``,
            ``present.npy``
==========  ================================================================================

A light-field video's result (any iterable of per-frame results) is exported by
:func:`export_video`: ``frame_FFFF/`` folders in the formats above, or one COCO file over
frames and views (:mod:`lfsam.export.video`, docs/design.md section 10).

Every folder also gets ``lfsam_export.json`` (grid, view size, object ids, source, the views
present). Sorted view file names are row-major view order. Absent views of a partial grid are
never written, only flagged. The folder is written atomically: into a temporary folder renamed
into place at the end, so a failure leaves nothing behind.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.export.coco import write_coco
from lfsam.export.folder import atomic_folder, check_export_target
from lfsam.export.masks import write_masks
from lfsam.export.npy import write_npy
from lfsam.export.png import write_png
from lfsam.export.video import video_coco, write_video_frames, write_video_sidecar
from lfsam.result import SegmentationResult

__all__ = ["EXPORT_FORMATS", "check_export_target", "export_result", "export_video"]

_WRITERS: dict[str, Callable[[SegmentationResult, Path], list[str]]] = {
    "png": write_png,
    "masks": write_masks,
    "coco": write_coco,
    "npy": write_npy,
}

#: Formats accepted by :func:`export_result`.
EXPORT_FORMATS: tuple[str, ...] = tuple(_WRITERS)


def export_result(
    result: SegmentationResult,
    out: str | os.PathLike,
    to: str,
    force: bool = False,
) -> Path:
    """Write ``result`` into the folder ``out`` in format ``to``, atomically.

    Parameters
    ----------
    result : SegmentationResult
        The result (labels [S, T, U, V]; ``present`` flags absent views).
    out : path-like
        The folder to create.
    to : {"png", "masks", "coco", "npy"}
        The format.
    force : bool
        Replace ``out`` if it is a non-empty folder.

    Returns
    -------
    Path
        The folder written.

    Raises
    ------
    LfsamError
        For an unknown format, a non-empty ``out`` without ``force``, a missing parent folder,
        or ids that the format cannot hold.
    """
    if to not in _WRITERS:
        raise LfsamError(f"unknown export format {to!r}; choose one of {', '.join(_WRITERS)}")
    with atomic_folder(out, force) as tmp:
        _WRITERS[to](result, tmp)
    return Path(out)


def export_video(
    frames: Iterable[SegmentationResult],
    out: str | os.PathLike,
    to: str,
    force: bool = False,
) -> Path:
    """Write a light-field video's per-frame results into ``out`` in format ``to``,
    atomically (:mod:`lfsam.export.video`): ``frame_FFFF/`` folders, or for ``coco`` one
    ``annotations.json`` with ``frame_index``, ``view_row``, ``view_col`` per image and
    ``track_id`` per annotation.

    Parameters
    ----------
    frames : iterable of SegmentationResult
        The frames in order (read one at a time).
    out, to, force
        As :func:`export_result`.

    Returns
    -------
    Path
        The folder written.

    Raises
    ------
    LfsamError
        As :func:`export_result`, and for frames of different shapes or no frame.
    """
    if to not in _WRITERS:
        raise LfsamError(f"unknown export format {to!r}; choose one of {', '.join(_WRITERS)}")
    with atomic_folder(out, force) as tmp:
        if to == "coco":
            description = video_coco(frames, tmp)
        else:
            description = write_video_frames(frames, tmp, to, _WRITERS[to])
        write_video_sidecar(tmp, description)
    return Path(out)

"""Exporting the result of a light-field video (docs/design.md section 10).

The frames come one at a time (any iterable of per-frame
:class:`~lfsam.result.SegmentationResult`, e.g. a lazily read video result), so memory stays
flat in F.

==========  ================================================================================
format      what is written into the output folder
==========  ================================================================================
png         ``frame_FFFF/view_SS_TT.png``: 16-bit label PNGs, one folder per frame
masks       ``frame_FFFF/object_NNNN/view_SS_TT.png``
npy         ``frame_FFFF/labels.npy`` ... (the single light field's files, per frame)
coco        ``annotations.json``: one image per frame and view (``file_name``
            ``frame_FFFF/view_SS_TT.png``, ``frame_index`` f, ``view_row`` s, ``view_col`` t),
            one video per view (``video_id``; its frames in time order, as video-instance
            formats such as TAO expect), one RLE annotation per object, frame and view with
            ``track_id`` = object id in every frame and view
==========  ================================================================================

Every frame folder holds the single light field's sidecar; the top folder's
``lfsam_export.json`` gives frames, grid, view size and object ids over all frames.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.export.coco import ANNOTATIONS, category_table, view_annotations
from lfsam.export.common import SIDECAR, object_ids, view_name, view_names
from lfsam.result import SegmentationResult
from lfsam.version import __version__

__all__ = ["frame_folder", "video_coco", "write_video_frames", "write_video_sidecar"]


def frame_folder(index: int) -> str:
    """``frame_0003``."""
    return f"frame_{index:04d}"


def write_video_frames(frames: Iterable[SegmentationResult], folder: Path, to: str,
                       writer: Any) -> dict[str, Any]:
    """Write every frame with the single light field's ``writer`` into ``frame_FFFF/``;
    the top sidecar's fields."""
    ids: set[int] = set()
    shape = None
    count = 0
    for index, result in enumerate(frames):
        shape = _check_shape(result, shape, index)
        sub = folder / frame_folder(index)
        sub.mkdir()
        writer(result, sub)
        ids.update(object_ids(result).tolist())
        count += 1
    return _description(to, count, shape, ids)


def video_coco(frames: Iterable[SegmentationResult], folder: Path) -> dict[str, Any]:
    """Write ``annotations.json`` of every frame (see the module docstring); the top
    sidecar's fields."""
    images: list[dict[str, Any]] = []
    annotations: list[dict[str, Any]] = []
    named: dict[int, str] = {}
    ids: set[int] = set()
    shape = None
    count = 0
    source = ""
    for index, result in enumerate(frames):
        shape = _check_shape(result, shape, index)
        s_count, t_count, rows, cols = shape
        frame_ids = object_ids(result)
        ids.update(frame_ids.tolist())
        named.update({int(k): str(v) for k, v in (result.meta.get("categories") or {}).items()})
        source = source or str(result.meta.get("input", result.meta.get("source", "")))
        for (s, t), name in view_names(result).items():
            image_id = (index * s_count + s) * t_count + t + 1
            images.append({
                "id": image_id, "file_name": f"{frame_folder(index)}/{name}",
                "height": rows, "width": cols, "frame_index": index, "view_row": s,
                "view_col": t, "video_id": s * t_count + t + 1, "frame_id": index,
            })
            for item in view_annotations(result.labels[s, t], frame_ids):
                item.update(id=len(annotations) + 1, image_id=image_id, iscrowd=0)
                annotations.append(item)
        count += 1
    if shape is None:
        raise LfsamError("a video result needs at least one frame")
    table, category_of = category_table(named, sorted(ids))
    for item in annotations:
        item["category_id"] = category_of[item["track_id"]]
    s_count, t_count, rows, cols = shape
    coco = {
        "info": {
            "description": "lfsam light-field video segmentation: one image per frame and view",
            "version": __version__, "source": source, "frames": count,
            "grid": [s_count, t_count], "view_size": [rows, cols],
        },
        "licenses": [],
        "videos": [{"id": s * t_count + t + 1, "name": view_name(s, t, (s_count, t_count), ""),
                    "view_row": s, "view_col": t}
                   for s in range(s_count) for t in range(t_count)],
        "images": images,
        "annotations": annotations,
        "categories": table,
    }
    (folder / ANNOTATIONS).write_text(json.dumps(coco))
    return {**_description("coco", count, shape, ids), "files": [ANNOTATIONS]}


def write_video_sidecar(folder: Path, description: dict[str, Any]) -> None:
    """The top folder's :data:`~lfsam.export.common.SIDECAR`."""
    (folder / SIDECAR).write_text(json.dumps(description, indent=2) + "\n")


def _check_shape(result: SegmentationResult, shape, index: int) -> tuple[int, ...]:
    here = tuple(int(x) for x in np.shape(result.labels))
    if shape is not None and here != shape:
        raise LfsamError(f"frame {index} has labels {here}, frame 0 {shape}")
    return here


def _description(to: str, count: int, shape, ids: set[int]) -> dict[str, Any]:
    if shape is None:
        raise LfsamError("a video result needs at least one frame")
    return {
        "format": f"lfsam-video-export-{to}", "lfsam_version": __version__, "frames": count,
        "grid": list(shape[:2]), "view_size": list(shape[2:]),
        "object_ids": sorted(int(i) for i in ids),
        "frame_folders": "frame_FFFF (0-based frame index)",
    }

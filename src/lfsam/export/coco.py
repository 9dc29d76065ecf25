"""Export as COCO instance annotations with tracks (docs/design.md section 8).

One ``annotations.json`` in the COCO format that ``pycocotools.coco.COCO`` loads:

- ``images``: one per view present, ``file_name`` ``view_SS_TT.png``, with the view's grid
  position as extra fields ``view_row`` (s) and ``view_col`` (t), ``frame_id`` (row-major
  index) and ``video_id`` (1: the light field, as in video-instance formats);
- ``annotations``: one per object and view where the object has pixels: ``segmentation`` as
  compressed RLE (``pycocotools.mask.encode``), ``bbox`` [x, y, width, height] and ``area`` from
  the RLE, ``iscrowd`` 0, ``category_id`` and ``track_id`` (= ``instance_id``) the object's
  label id, the same in every view;
- ``categories``: the phrases of the text prompts that found objects (docs/design.md section 9;
  ``meta["categories"]``), in order of first use, then ``object`` for every other object (ids
  are instances, not classes); ``object`` alone when no text prompt was used;
- ``info``: grid, view size, source and the ``present`` flags (absent views have no image).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from pycocotools import mask as mask_utils

from lfsam.export.common import object_ids, view_names, write_sidecar
from lfsam.result import SegmentationResult
from lfsam.version import __version__

__all__ = ["ANNOTATIONS", "categories", "category_table", "coco_dict", "view_annotations",
           "write_coco"]

#: Name of the COCO file.
ANNOTATIONS = "annotations.json"


def view_annotations(labels: np.ndarray, ids: np.ndarray) -> list[dict[str, Any]]:
    """RLE, bbox and area of every object with pixels in one view's labels."""
    visible = ids[np.isin(ids, np.unique(labels))]
    if visible.size == 0:
        return []
    stack = np.asfortranarray((labels[..., None] == visible[None, None, :]).astype(np.uint8))
    rles = mask_utils.encode(stack)
    boxes = mask_utils.toBbox(rles)
    areas = mask_utils.area(rles)
    found = []
    for object_id, rle, box, area in zip(visible, rles, boxes, areas, strict=True):
        found.append(
            {
                "track_id": int(object_id),
                "instance_id": int(object_id),
                "segmentation": {"size": list(rle["size"]), "counts": rle["counts"].decode()},
                "bbox": [float(x) for x in box],
                "area": float(area),
            }
        )
    return found


def categories(result: SegmentationResult, ids: np.ndarray) -> tuple[list[dict], dict[int, int]]:
    """COCO categories of ``result`` and the category id of each object id in ``ids``."""
    return category_table(result.meta.get("categories") or {}, ids)


def category_table(named: dict, ids: Any) -> tuple[list[dict], dict[int, int]]:
    """COCO categories for objects ``ids`` given ``{id: phrase}`` of the text-prompted ones,
    and the category id of each object (see the module docstring)."""
    named = {int(k): str(v) for k, v in named.items()}
    names: list[str] = []
    for obj_id in sorted(named):
        if named[obj_id] not in names:
            names.append(named[obj_id])
    if not names or any(int(i) not in named for i in ids):
        names.append("object")
    number = {name: n + 1 for n, name in enumerate(names)}
    table = [{"id": number[n], "name": n, "supercategory": "object"} for n in names]
    return table, {int(i): number[named.get(int(i), "object")] for i in ids}


def coco_dict(result: SegmentationResult) -> dict[str, Any]:
    """The COCO dictionary of ``result`` (see the module docstring)."""
    s_count, t_count, rows, cols = result.labels.shape
    ids = object_ids(result)
    category_table, category_of = categories(result, ids)
    images, annotations = [], []
    for (s, t), name in view_names(result).items():
        image_id = s * t_count + t + 1
        images.append(
            {
                "id": image_id,
                "file_name": name,
                "height": rows,
                "width": cols,
                "view_row": s,
                "view_col": t,
                "frame_id": s * t_count + t,
                "video_id": 1,
            }
        )
        for item in view_annotations(result.labels[s, t], ids):
            item.update(
                id=len(annotations) + 1, image_id=image_id,
                category_id=category_of[item["track_id"]], iscrowd=0,
            )
            annotations.append(item)
    source = str(result.meta.get("input", result.meta.get("source", "")))
    return {
        "info": {
            "description": "lfsam light-field segmentation: one image per view",
            "version": __version__,
            "source": source,
            "grid": [s_count, t_count],
            "view_size": [rows, cols],
            "present": result.present_mask.tolist(),
        },
        "licenses": [],
        "videos": [{"id": 1, "name": source or "lightfield"}],
        "images": images,
        "annotations": annotations,
        "categories": category_table,
    }


def write_coco(result: SegmentationResult, folder: Path) -> list[str]:
    """Write ``annotations.json`` and the sidecar into ``folder``.

    Returns
    -------
    names : list of str
        ``["annotations.json"]``.
    """
    (folder / ANNOTATIONS).write_text(json.dumps(coco_dict(result)))
    write_sidecar(folder, result, "coco", {"files": [ANNOTATIONS]})
    return [ANNOTATIONS]

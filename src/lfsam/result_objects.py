"""A session's objects as a :class:`~lfsam.result.SegmentationResult`, and back.

A result keeps its objects (docs/design.md section 8): masks in id order
(``meta["object_ids"]``), and per object its reference view and either its prompts (JSON) or
``"mask": "automatic" | "given" | "text"`` (with ``"category"``, the phrase of a text prompt;
docs/design.md section 9; ``meta["categories"]`` maps ids to phrases), so
:meth:`lfsam.predictor.LightFieldPredictor.open_result` reopens it editable and ``predict``
reproduces it. Saving and loading the file itself is :mod:`lfsam.result`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.objects import TrackedObject, View
from lfsam.prompts import ObjectPrompts, prompts_from_json, prompts_to_json
from lfsam.result import PackedMasks, SegmentationResult

__all__ = ["GivenMask", "build_result", "result_objects", "stored_prompts"]


def build_result(
    lightfield: LightField,
    objects: Mapping[int, TrackedObject],
    labels: np.ndarray,
    timings: dict[str, float],
    meta: dict[str, Any],
) -> SegmentationResult:
    """The result of ``objects`` (every one refined: step 4, or steps 1-3 without refinement),
    in id order, with ``labels`` fused from them; ``meta`` is completed with the objects."""
    ids = sorted(objects)
    grid = lightfield.grid_shape
    entries = []
    for i in ids:
        obj = objects[i]
        entry: dict[str, Any] = {"id": i, "reference_view": list(obj.reference.view)}
        if obj.prompts is not None:
            entry.update(prompts_to_json([obj.prompts])[0])
        else:
            entry["mask"] = (
                "automatic" if obj.automatic else ("text" if obj.category else "given")
            )
        if obj.category is not None:
            entry["category"] = obj.category
        entries.append(entry)
    meta = {
        **meta,
        "prompt_mode": "auto" if ids and all(objects[i].prompts is None for i in ids)
        else "prompts",
        "num_masks": len(ids),
        "center": list(lightfield.center),
        "object_ids": ids,
        "objects": entries,
        "categories": {str(i): objects[i].category for i in ids if objects[i].category},
    }

    replaced = [objects[i].refined.replaced for i in ids]
    if ids and all(flags is not None for flags in replaced):  # the consensus ran (3.9)
        meta["consensus_replaced"] = int(sum(int(flags.sum()) for flags in replaced))
        meta["consensus_replaced_views"] = [
            [i, int(s), int(t)] for i, flags in zip(ids, replaced, strict=True)
            for s, t in zip(*np.nonzero(flags), strict=True)]

    def stacked(attr: str, empty: np.ndarray | None) -> np.ndarray | None:
        return np.stack([getattr(objects[i].refined, attr) for i in ids]) if ids else empty

    return SegmentationResult(
        labels=labels,
        masks=PackedMasks((len(ids), *grid, *lightfield.view_shape), stacked("bits", None)),
        scores=np.array([objects[i].reference.score for i in ids], dtype=np.float32),
        fallback=stacked("fallback", np.zeros((0, *grid), dtype=bool)),
        refine_iou=stacked("iou", np.zeros((0, *grid), dtype=np.float32)),
        timings=timings,
        meta=meta,
        present=lightfield.present.copy(),
    )


def stored_prompts(result: SegmentationResult) -> list[ObjectPrompts]:
    """The prompted objects stored in a result (to reopen it for editing)."""
    entries = [
        {k: v for k, v in e.items() if k in ("id", "points", "box")}
        for e in result.meta.get("objects", [])
        if "mask" not in e
    ]
    return [p for p in prompts_from_json(entries) if isinstance(p, ObjectPrompts)]


@dataclass(frozen=True)
class GivenMask:
    """An object of a result given by its mask in its reference view (automatic or imported)."""

    obj_id: int
    view: View
    mask: np.ndarray
    score: float
    category: str | None = None


def result_objects(
    result: SegmentationResult, lightfield: LightField
) -> list[ObjectPrompts | GivenMask]:
    """Every object of ``result`` in id order: prompted ones as their prompts, the others as
    their reference-view masks.

    Raises
    ------
    LfsamError
        If the result does not fit ``lightfield`` (another light field's result).
    """
    if tuple(result.labels.shape) != (*lightfield.grid_shape, *lightfield.view_shape):
        raise LfsamError(
            f"the result's labels have shape {result.labels.shape}, the light field is "
            f"{(*lightfield.grid_shape, *lightfield.view_shape)}; open the result with its own "
            "light field"
        )
    ids = result.meta.get("object_ids") or list(range(1, result.num_masks + 1))
    entries = {e["id"]: e for e in result.meta.get("objects", [])}
    prompted = {o.obj_id: o for o in stored_prompts(result)}
    objects: list[ObjectPrompts | GivenMask] = []
    for n, obj_id in enumerate(ids):
        if obj_id in prompted:
            objects.append(prompted[obj_id])
            continue
        view = tuple(entries.get(obj_id, {}).get("reference_view", lightfield.center))
        if result.masks is not None:
            mask = result.masks.mask(n)[view]
        else:
            mask = result.labels[view] == obj_id
        score = 1.0 if result.scores is None else float(result.scores[n])
        category = entries.get(obj_id, {}).get("category")
        objects.append(GivenMask(obj_id, view, mask, score, category))
    return objects

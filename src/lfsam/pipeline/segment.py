"""The LFSAM pipeline: view-consistent light-field masks from the center view.

Paper section 3 (Figure 1): (1) initial segmentation of the center view, (2) disparity
propagation of each mask into every view, (3) semantic occluding, (4) refinement by re-prompting
SAM 2, then label fusion. The light field is streamed view by view: each view is encoded exactly
once and its embedding serves both occluding and refinement, all N prompts of a view are decoded
in one batch, and masks are kept bit-packed (never N x S x T x U x V dense).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt
from lfsam.result import SegmentationResult
from lfsam.segmenters.base import Prompts, Segmenter

__all__ = ["objects_from_prompts", "segment_lightfield"]


def segment_lightfield(
    lightfield: LightField,
    segmenter: Segmenter,
    disparity: np.ndarray,
    prompts: Sequence[Prompts] | None = None,
    config: PipelineConfig | None = None,
    *,
    progress: bool = True,
) -> SegmentationResult:
    """Segment a light field from its center view (paper section 3).

    Parameters
    ----------
    lightfield : LightField
        Views ``[S, T, U, V, 3]``.
    segmenter : Segmenter
        SAM 2 or the oracle (:func:`lfsam.segmenters.load_segmenter`).
    disparity : (U, V) float ndarray
        Center-view disparity in the package convention (estimated or ground truth).
    prompts : sequence of Prompts, optional
        Center-view prompts, each prompt one object (labels follow their order); None for
        automatic mask generation.
    config : PipelineConfig, optional
        Switches and thresholds; default: the paper's full method (refinement + semantic
        occluding, ``t_sim = 0.7``, ``t_iou = 0.1``).
    progress : bool
        Show a progress bar over views.

    Returns
    -------
    SegmentationResult
        Labels, bit-packed masks, per-view fallback flags and IoUs, stage timings (the
        disparity's own time is not included; callers add it) and metadata.
    """
    from lfsam.predictor import LightFieldPredictor

    height, width = lightfield.view_shape
    if np.shape(disparity) != (height, width):
        raise ValueError(f"disparity has shape {np.shape(disparity)}, expected {(height, width)}")
    predictor = LightFieldPredictor(segmenter, config, progress=progress)
    predictor.set_lightfield(lightfield, disparity=np.asarray(disparity, dtype=np.float32))
    if prompts is None:
        predictor.generate()
    else:
        for group in prompts:
            for obj in objects_from_prompts(group, first_id=predictor.next_id()):
                predictor.set_object(obj)
    result = predictor.to_result()
    result.timings.pop("disparity", None)
    result.timings["total"] = predictor.seconds
    result.meta["prompt_mode"] = "auto" if prompts is None else "prompts"
    return result


def objects_from_prompts(prompts: Prompts, first_id: int = 1) -> list[ObjectPrompts]:
    """Center-view :class:`~lfsam.segmenters.base.Prompts` rows as objects ``first_id, ...``
    (padding points, label -1, are dropped)."""
    objects = []
    for n in range(len(prompts)):
        points = []
        if prompts.points is not None:
            for (x, y), label in zip(prompts.points[n], prompts.point_labels[n], strict=True):
                if label in (0, 1):
                    points.append(PointPrompt(float(x), float(y), bool(label == 1)))
        box = None if prompts.boxes is None else BoxPrompt(*map(float, prompts.boxes[n]))
        objects.append(ObjectPrompts(first_id + n, tuple(points), box))
    return objects

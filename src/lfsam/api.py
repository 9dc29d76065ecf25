"""High-level entry points: one call from a light field to a segmentation result.

:func:`run_segmentation` is what ``lfsam segment`` and ``lfsam evaluate`` call: it builds the
segmenter, resolves the disparity, and runs LFSAM (:func:`lfsam.pipeline.segment_lightfield`) or
the SAM 2 video baseline (:mod:`lfsam.baseline`), recording everything needed to reproduce the
run in the result's metadata.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline import PipelineConfig, segment_lightfield
from lfsam.result import SegmentationResult
from lfsam.segmenters.base import Prompts, Segmenter

__all__ = ["METHODS", "make_prompts", "run_segmentation"]

METHODS = ("lfsam", "video-baseline")


def make_prompts(
    points: Sequence[tuple[float, float]] = (),
    boxes: Sequence[tuple[float, float, float, float]] = (),
) -> list[Prompts] | None:
    """Prompts for the center view, each point or box one object.

    When as many points as boxes are given, point ``i`` and box ``i`` together prompt object
    ``i``; otherwise every point and every box is an object of its own (points first).

    Parameters
    ----------
    points : sequence of (x, y)
        Positive points, ``x`` = pixel column and ``y`` = pixel row.
    boxes : sequence of (x0, y0, x1, y1)

    Returns
    -------
    list of Prompts, or None when nothing was given (automatic generation)
    """
    points = [tuple(map(float, p)) for p in points]
    boxes = [tuple(map(float, b)) for b in boxes]
    if not points and not boxes:
        return None
    if points and boxes and len(points) == len(boxes):
        return [
            Prompts(
                points=np.array(points)[:, None, :],
                point_labels=np.ones((len(points), 1)),
                boxes=np.array(boxes),
            )
        ]
    groups = []
    if points:
        groups.append(
            Prompts(points=np.array(points)[:, None, :], point_labels=np.ones((len(points), 1)))
        )
    if boxes:
        groups.append(Prompts(boxes=np.array(boxes)))
    return groups


def run_segmentation(
    lightfield: LightField,
    *,
    method: str = "lfsam",
    model: str = "sam2.1-hiera-small",
    checkpoint: str | None = None,
    random_weights: bool = False,
    disparity: str | np.ndarray = "estimate",
    ablation: str | None = None,
    config: PipelineConfig | None = None,
    prompts: Sequence[Prompts] | None = None,
    device: str | None = None,
    amg_options: dict[str, Any] | None = None,
    segmenter: Segmenter | None = None,
    baseline_options: dict[str, Any] | None = None,
    progress: bool = True,
) -> SegmentationResult:
    """Segment a light field with LFSAM or the SAM 2 video baseline.

    Parameters
    ----------
    lightfield : LightField
    method : {"lfsam", "video-baseline"}
        Our method (paper section 3) or SAM 2 video tracking over the views in snake order
        (paper section 4).
    model : str
        Segmenter name (``lfsam models`` lists them; ``oracle`` answers from ground truth).
    checkpoint : str, optional
        SAM 2 weights file; default: the model hub's weights for ``model`` (cached).
    random_weights : bool
        Untrained SAM 2 (tests and speed benchmarks only; recorded in the metadata).
    disparity : {"estimate", "gt"}, path to a .npy, or array
        Center-view disparity for propagation (LFSAM only): any source
        :func:`lfsam.disparity.resolve_disparity` accepts.
    ablation : {"none", "ref", "ref+occ"}, optional
        A row of the paper's Table 2; overrides ``config``'s refinement and occluding.
    config : PipelineConfig, optional
        Pipeline switches and thresholds (default: the paper's full method).
    prompts : sequence of Prompts, optional
        Center-view prompts (see :func:`make_prompts`); None for automatic generation.
    device : str, optional
        ``cuda``, ``mps`` or ``cpu``; default: the best available.
    amg_options : dict, optional
        Overrides of the automatic mask generator's settings.
    segmenter : Segmenter, optional
        A ready segmenter (then ``model``, ``checkpoint``, ``random_weights`` are ignored).
    baseline_options : dict, optional
        Options of the video baseline (e.g. ``objects_per_pass``, ``start``).
    progress : bool
        Show progress bars.

    Returns
    -------
    SegmentationResult
    """
    if method not in METHODS:
        raise LfsamError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    from lfsam.segmenters import load_segmenter

    given_segmenter = segmenter is not None
    if segmenter is None:
        segmenter = load_segmenter(
            model,
            checkpoint=checkpoint,
            random_weights=random_weights,
            device=device,
            lightfield=lightfield,
            amg_options=amg_options,
        )
    run_meta: dict[str, Any] = {
        "input": str(lightfield.meta.get("source", "<array>")),
        "input_format": lightfield.meta.get("format"),
        "model": segmenter.name if given_segmenter else model,
        "random_weights": bool(segmenter.random_weights),
        "checkpoint": checkpoint,
        "grid": list(lightfield.grid_shape),
        "view_size": list(lightfield.view_shape),
    }
    if method == "video-baseline":
        from lfsam.baseline import video_baseline

        result = video_baseline(
            lightfield,
            segmenter,
            prompts=prompts,
            disparity=disparity,
            progress=progress,
            **(baseline_options or {}),
        )
        result.meta.update(run_meta)
        return result

    if ablation is not None:
        base = config or PipelineConfig()
        config = PipelineConfig.from_ablation(
            ablation,
            **{
                k: v
                for k, v in base.to_dict().items()
                if k not in ("refine", "occlusion")
            },
        )
    from lfsam.disparity import resolve_disparity

    start = time.perf_counter()
    disparity_map, disparity_source = resolve_disparity(
        disparity, lightfield, device=str(segmenter.device)
    )
    disparity_seconds = time.perf_counter() - start
    result = segment_lightfield(
        lightfield, segmenter, disparity_map, prompts, config, progress=progress
    )
    result.timings["disparity"] = disparity_seconds
    result.timings["total"] += disparity_seconds
    result.meta.update(run_meta)
    result.meta.update(
        {
            "disparity_source": disparity_source,
            "ablation": ablation,
        }
    )
    return result

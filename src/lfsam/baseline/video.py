"""The paper's baseline: SAM 2 video tracking through the views of a light field.

Paper section 4 (implementation details) and docs/design.md section 4: the views, ordered as a snake
(row 0 left to right, row 1 right to left, ...; :func:`lfsam.lightfield.snake_order`), are the
frames of a video; the first view is segmented by SAM 2's automatic mask generation; every mask
is added as an object on that frame (``add_new_mask``) and tracked through all frames by Meta's
``SAM2VideoPredictor``; the authors tracked 15 objects per pass, resetting the tracker between
passes. As in ``sam2``, each pass runs the image encoder on every frame again (the predictor
keeps the features of the latest frame only). The result has the same format as LFSAM's
(:class:`lfsam.result.SegmentationResult`), so every metric and viewer works on both.

Beyond the paper (both options, off by default where they change the baseline):

- center-view prompts instead of automatic generation: carried to the first view by disparity
  (:func:`lfsam.baseline.prompts.transfer_prompts`), or used as they are with ``start="center"``;
- ``start="center"``: tracking starts on the center view (its place in the snake) and runs
  forward to the last frame and in reverse to the first, a fairer comparison with LFSAM, which
  also starts from the center view with the same masks.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from lfsam.baseline.frames import FRAME_TRANSFORMS, init_video_state, video_frames
from lfsam.baseline.predictor import MASK_THRESHOLD, quiet_sam2_video, video_predictor_for
from lfsam.baseline.prompts import transfer_prompts
from lfsam.disparity import resolve_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import SourceMasks, initial_segmentation, validate_prompts
from lfsam.result import PackedMasks, SegmentationResult
from lfsam.segmenters.base import Prompts, Segmenter
from lfsam.segmenters.sam2.build import inference_context
from lfsam.timing import StageTimer
from lfsam.version import __version__

__all__ = ["BASELINE_STARTS", "video_baseline"]

BASELINE_STARTS = ("first", "center")
"""Where tracking starts: the first view of the snake (paper) or the center view."""


def video_baseline(
    lightfield: LightField,
    segmenter: Segmenter,
    *,
    prompts: Sequence[Prompts] | None = None,
    objects_per_pass: int = 15,
    start: str = "first",
    disparity: np.ndarray | str | None = None,
    frame_transform: str = "video",
    progress: bool = True,
) -> SegmentationResult:
    """Segment a light field by SAM 2 video tracking over its views in snake order.

    Parameters
    ----------
    lightfield : LightField
        Views ``[S, T, U, V, 3]``.
    segmenter : Segmenter
        A SAM 2 segmenter (:class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter`); its image
        model makes the start masks, and the video predictor runs with the same weights
        (:func:`lfsam.baseline.predictor.video_predictor_for`). The oracle cannot track video.
    prompts : sequence of Prompts, optional
        Center-view prompts, each prompt one object (labels follow their order, as in LFSAM).
        None: automatic mask generation on the start view (the paper's setting).
    objects_per_pass : int
        Objects tracked together; the tracker is reset between passes (the authors used 15).
    start : {"first", "center"}
        Start on the first view of the snake and track forward (paper), or on the center view
        and track forward and in reverse.
    disparity : (U, V) ndarray, {"gt", "estimate"} or path, optional
        Center-view disparity, used only to carry ``prompts`` to the first view
        (``start="first"``); default the ground truth when the light field has it, else the
        estimate (:func:`lfsam.disparity.resolve_disparity`).
    frame_transform : {"video", "image"}
        How views become frames (:func:`lfsam.baseline.frames.video_frames`): SAM 2's video
        loader (default) or the image predictor's transform.
    progress : bool
        Show a progress bar over tracked frames.

    Returns
    -------
    SegmentationResult
        Labels fused larger-first (by start-view area) with smaller masks on top, bit-packed
        tracked masks, the start masks' scores, no fallbacks (no refinement), stage timings
        (``frames``, ``initial``, ``tracking``, ``fuse``, ``disparity`` when used, ``total``)
        and metadata (``method="video-baseline"``).

    Raises
    ------
    LfsamError
        For a segmenter without a video model, an unknown ``start`` or ``frame_transform``, or
        ``objects_per_pass < 1``.
    """
    if start not in BASELINE_STARTS:
        raise LfsamError(
            f"unknown baseline start {start!r}; use one of {', '.join(BASELINE_STARTS)}"
        )
    if frame_transform not in FRAME_TRANSFORMS:
        raise LfsamError(
            f"unknown frame transform {frame_transform!r}; use one of {', '.join(FRAME_TRANSFORMS)}"
        )
    if int(objects_per_pass) != objects_per_pass or objects_per_pass < 1:
        raise LfsamError(f"--objects-per-pass must be a whole number >= 1, got {objects_per_pass}")
    objects_per_pass = int(objects_per_pass)
    predictor = video_predictor_for(segmenter)  # raises for the oracle before any work
    device = segmenter.device
    timer = StageTimer(device)
    s_count, t_count = lightfield.grid_shape
    height, width = lightfield.view_shape
    order = lightfield.snake_order()
    start_view = order[0] if start == "first" else lightfield.center
    start_frame = order.index(start_view)
    began = time.perf_counter()

    disparity_source = None
    start_prompts = prompts
    if prompts is not None and start_view != lightfield.center:
        for group in prompts:  # the user's prompts are center-view prompts, checked there
            validate_prompts(group, lightfield.view_shape)
        with timer("disparity"):
            disparity_map, disparity_source = _resolve_disparity(disparity, lightfield, device)
        offset = (start_view[0] - lightfield.center[0], start_view[1] - lightfield.center[1])
        start_prompts = [transfer_prompts(group, disparity_map, offset) for group in prompts]

    with timer("initial"):
        image = lightfield.views[start_view]
        embedding = segmenter.encode(image[None], keys=[start_view])[0]
        source: SourceMasks = initial_segmentation(segmenter, embedding, image, start_prompts)
        del embedding
    num_masks = len(source)
    packed = PackedMasks((num_masks, s_count, t_count, height, width))
    passes = math.ceil(num_masks / objects_per_pass)

    if num_masks:
        with timer("frames"):
            frames = video_frames(
                lightfield.views[tuple(np.array(order).T)],
                int(predictor.image_size),
                device,
                frame_transform,
            )
            state = init_video_state(predictor, frames, (height, width))
        start_masks = source.masks.to(device)
        bar = tqdm(
            total=passes * len(order), desc="video baseline", unit="frame",
            disable=not progress or None, leave=False,
        )
        with timer("tracking"), inference_context(device), quiet_sam2_video():
            for first in range(0, num_masks, objects_per_pass):
                objects = range(first, min(first + objects_per_pass, num_masks))
                _track_pass(
                    predictor, state, start_masks, objects, start_frame, order, packed, bar, timer
                )
        bar.close()
        del frames, state

    with timer("fuse"):
        labels = np.zeros((s_count, t_count, height, width), dtype=np.int32)
        paint_order = torch.as_tensor(source.paint_order, device=device)
        for s, t in order if num_masks else ():
            view_masks = torch.as_tensor(packed.view(s, t), device=device)
            labels[s, t] = fuse_labels(view_masks, paint_order).cpu().numpy()

    timings = dict(timer.seconds)
    timings["total"] = time.perf_counter() - began
    # Packing tracked masks into bits is bookkeeping, as LFSAM's "fuse" stage, not tracking.
    pack = timings.pop("pack", 0.0)
    if "tracking" in timings:
        timings["tracking"] -= pack
    timings["fuse"] = timings.get("fuse", 0.0) + pack
    meta: dict[str, Any] = {
        "method": "video-baseline",
        "package_version": __version__,
        "segmenter": getattr(segmenter, "describe", lambda: {"name": segmenter.name})(),
        "video_predictor": type(predictor).__name__,
        "objects_per_pass": objects_per_pass,
        "passes": passes,
        "start": start,
        "start_view": list(start_view),
        "frame_order": [list(st) for st in order],
        "frame_transform": frame_transform,
        "mask_threshold": MASK_THRESHOLD,
        "prompt_mode": "auto" if prompts is None else "prompts",
        "num_masks": num_masks,
        "center": list(lightfield.center),
        "disparity_source": disparity_source,
    }
    return SegmentationResult(
        labels=labels,
        masks=packed,
        scores=np.asarray(source.scores, dtype=np.float32),
        fallback=np.zeros((num_masks, s_count, t_count), dtype=bool),
        refine_iou=np.full((num_masks, s_count, t_count), np.nan, dtype=np.float32),
        timings=timings,
        meta=meta,
    )


def _track_pass(
    predictor: Any,
    state: dict[str, Any],
    start_masks: torch.Tensor,
    objects: range,
    start_frame: int,
    order: list[tuple[int, int]],
    packed: PackedMasks,
    bar: Any,
    timer: StageTimer,
) -> None:
    """Track one pass of objects from ``start_frame`` to both ends of the video."""
    predictor.reset_state(state)
    for obj in objects:
        predictor.add_new_mask(state, start_frame, obj, start_masks[obj])
    directions = [False] + ([True] if start_frame > 0 else [])
    for reverse in directions:
        for frame_idx, obj_ids, logits in predictor.propagate_in_video(
            state, start_frame_idx=start_frame, reverse=reverse
        ):
            if reverse and frame_idx == start_frame:
                continue  # already stored by the forward run
            if list(obj_ids) != list(objects):
                raise RuntimeError(f"tracker returned objects {obj_ids}, expected {list(objects)}")
            with timer("pack"):
                masks = (logits[:, 0] > MASK_THRESHOLD).flatten(1).cpu().numpy()
                s, t = order[frame_idx]
                packed.data[objects.start : objects.stop, s, t] = np.packbits(masks, axis=1)
            bar.update(1)


def _resolve_disparity(
    disparity: np.ndarray | str | None, lightfield: LightField, device: torch.device
) -> tuple[np.ndarray, str]:
    """The center disparity used to carry prompts to the start view, and where it came from."""
    if disparity is None:
        disparity = "gt" if lightfield.center_disparity is not None else "estimate"
    return resolve_disparity(disparity, lightfield, device=str(device))

"""The LFSAM pipeline: view-consistent light-field masks from the center view.

Paper section 3 (Figure 1): (1) initial segmentation of the center view, (2) disparity
propagation of each mask into every view, (3) semantic occluding, (4) refinement by re-prompting
SAM 2, then label fusion. The light field is streamed view by view: each view is encoded exactly
once and its embedding serves both occluding and refinement, all N prompts of a view are decoded
in one batch, and masks are kept bit-packed (never N x S x T x U x V dense).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import torch
from tqdm.auto import tqdm

from lfsam import __version__
from lfsam.geometry import view_offsets
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import SourceMasks, initial_segmentation
from lfsam.pipeline.occlusion import semantic_occlusion, source_features, uniform_weights
from lfsam.pipeline.propagation import propagate_masks
from lfsam.pipeline.refinement import refine_masks
from lfsam.result import PackedMasks, SegmentationResult
from lfsam.segmenters.base import Prompts, Segmenter
from lfsam.timing import StageTimer
from lfsam.warp import forward_warp

__all__ = ["segment_lightfield"]


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
    config = config or PipelineConfig()
    timer = StageTimer(segmenter.device)
    device = segmenter.device
    s_count, t_count = lightfield.grid_shape
    height, width = lightfield.view_shape
    center = lightfield.center
    if disparity.shape != (height, width):
        raise ValueError(f"disparity has shape {disparity.shape}, expected {(height, width)}")
    start = time.perf_counter()
    encodes_before = segmenter.encode_calls

    # (1) Initial segmentation of the center view.
    with timer("encode"):
        center_embedding = segmenter.encode(lightfield.center_view[None], keys=[center])[0]
    with timer("initial"):
        source: SourceMasks = initial_segmentation(
            segmenter, center_embedding, lightfield.center_view, prompts
        )
    num_masks = len(source)
    paint_order = torch.as_tensor(source.paint_order, device=device)
    disp = torch.as_tensor(np.asarray(disparity, dtype=np.float32), device=device)
    with timer("occlude"):
        sources = (
            source_features(segmenter, center_embedding, source.masks)
            if config.semantic and num_masks
            else None
        )
    del center_embedding

    labels = np.zeros((s_count, t_count, height, width), dtype=np.int32)
    packed = PackedMasks((num_masks, s_count, t_count, height, width))
    fallback = np.zeros((num_masks, s_count, t_count), dtype=bool)
    refine_iou = np.full((num_masks, s_count, t_count), np.nan, dtype=np.float32)
    with timer("fuse"):
        packed.set_view(*center, source.masks.cpu().numpy())
        labels[center] = fuse_labels(source.masks, paint_order).cpu().numpy()

    ds_grid, dt_grid = view_offsets((s_count, t_count), center)
    others = [st for st in lightfield.view_indices() if st != center]
    bar = tqdm(
        total=len(others), desc="views", unit="view", disable=not progress or None, leave=False
    )
    for batch_start in range(0, len(others) if num_masks else 0, config.encode_batch_size):
        batch = others[batch_start : batch_start + config.encode_batch_size]
        embeddings = [None] * len(batch)
        if config.needs_view_encoding:
            with timer("encode"):
                images = np.stack([lightfield.views[st] for st in batch])
                embeddings = segmenter.encode(images, keys=batch)
        for (s, t), embedding in zip(batch, embeddings, strict=True):
            ds, dt = float(ds_grid[s, t]), float(dt_grid[s, t])
            # (2) Disparity propagation (+ geometric occluding by z-buffer).
            with timer("propagate"):
                warp = forward_warp(disp, ds, dt)
                coarse = propagate_masks(
                    source.masks, disp, ds, dt, config.propagation, warp=warp,
                    fill_holes=config.fill_holes,
                    occlusion_tolerance=config.zbuffer_tolerance if config.geometric else None,
                )
            # (3) Semantic occluding.
            with timer("occlude"):
                if config.semantic:
                    weights = semantic_occlusion(
                        segmenter, embedding, coarse, sources, config.t_sim
                    )
                    coarse = weights.surviving_masks()
                else:
                    weights = uniform_weights(coarse) if config.refine else None
            # (4) Refinement.
            if config.refine:
                with timer("refine"):
                    seen = warp.seen((height, width))
                    outcome = refine_masks(
                        segmenter, embedding, coarse, weights, config.t_iou,
                        seen=seen, frame_runs=warp.frame_runs((height, width), seen),
                    )
                    view_masks = outcome.masks
                    fallback[:, s, t] = outcome.fallback.cpu().numpy()
                    refine_iou[:, s, t] = outcome.iou.cpu().numpy()
            else:
                view_masks = coarse
            with timer("fuse"):
                labels[s, t] = fuse_labels(view_masks, paint_order).cpu().numpy()
                packed.set_view(s, t, view_masks.cpu().numpy())
            bar.update(1)
    bar.close()

    timings = dict(timer.seconds)
    timings["total"] = time.perf_counter() - start
    meta = {
        "method": "lfsam",
        "package_version": __version__,
        "segmenter": segmenter.describe(),
        "config": config.to_dict(),
        "prompt_mode": "auto" if prompts is None else "prompts",
        "num_masks": num_masks,
        "center": list(center),
        "views_encoded": segmenter.encode_calls - encodes_before,
    }
    return SegmentationResult(
        labels=labels,
        masks=packed,
        scores=source.scores.astype(np.float32),
        fallback=fallback,
        refine_iou=refine_iou,
        timings=timings,
        meta=meta,
    )

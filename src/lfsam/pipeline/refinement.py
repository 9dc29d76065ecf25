"""Step 4 of the pipeline: segmentation refinement by re-prompting SAM 2 in each view.

Paper section 3.4 with the details of docs/design.md section 3.5: in view ``(s, t)`` each mask is
prompted with the box around its surviving coarse pixels and one positive point, the surviving
pixel nearest to their similarity-weighted centroid (a plain centroid can fall outside a
non-convex mask). Of the three multimask outputs the one with the highest IoU against the coarse
mask is kept, and only if that IoU exceeds ``t_iou`` (0.1 in the paper); otherwise the view falls
back to the coarse mask. All N prompts of a view go through the decoder in one batch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lfsam.pipeline.occlusion import OcclusionWeights
from lfsam.precision import wide_float
from lfsam.segmenters.base import Prompts, Segmenter, ViewEmbedding
from lfsam.segments import segment_lengths, segment_reduce
from lfsam.warp import FrameRuns

__all__ = ["RefinementOutcome", "mask_iou", "refine_masks", "refinement_prompts"]


@dataclass
class RefinementOutcome:
    """Refined masks of one view.

    Attributes
    ----------
    masks : (N, U, V) bool tensor
        Refined mask, or the coarse mask where refinement fell back.
    fallback : (N,) bool tensor
        True where the coarse mask was kept (IoU not above ``t_iou``, or nothing to prompt).
    iou : (N,) float tensor
        IoU of the chosen refined candidate with the coarse mask (NaN where not prompted).
    """

    masks: torch.Tensor
    fallback: torch.Tensor
    iou: torch.Tensor


def refinement_prompts(
    weights: OcclusionWeights, frame_runs: FrameRuns | None = None
) -> tuple[Prompts | None, torch.Tensor]:
    """Box and point prompt of each mask from its weighted surviving pixels (paper 3.4).

    Parameters
    ----------
    weights : OcclusionWeights
        Surviving coarse pixels (weight > 0) and their weights.
    frame_runs : FrameRuns, optional
        Strips at the view's frame border that the center view does not see
        (:meth:`lfsam.warp.ForwardWarp.frame_runs`). A box edge reaching such
        a strip within the box's extent is moved to the frame edge: the object may continue
        into content that was outside the center view's frame, which no propagated pixel can
        reach (beyond the paper, which leaves the frame border implicit).

    Returns
    -------
    prompts : Prompts or None
        One prompt per mask that has surviving pixels (None if no mask has any).
    prompted : (N,) bool tensor
        Which masks got a prompt (rows of ``prompts`` are these masks, in order).
    """
    n = weights.num_masks
    width = weights.view_size[1]
    device = weights.weight.device
    keep = weights.weight > 0
    mask_index = weights.mask_index[keep]
    pixel_index = weights.pixel_index[keep]
    wide = wide_float(device)
    w = weights.weight[keep].to(wide)
    rows = (pixel_index // width).to(wide)
    cols = (pixel_index % width).to(wide)

    lengths = segment_lengths(mask_index, n) if device.type == "cuda" else None

    def _reduce(values: torch.Tensor, how: str) -> torch.Tensor:
        return segment_reduce(values, mask_index, n, how, lengths)

    total = _reduce(w, "sum")
    prompted = total > 0
    if not bool(prompted.any()):
        return None, prompted
    safe_total = total.clamp(min=1e-12)
    centroid_r = _reduce(w * rows, "sum") / safe_total
    centroid_c = _reduce(w * cols, "sum") / safe_total

    # Nearest surviving pixel to the weighted centroid: per-mask argmin over the pairs.
    dist = (rows - centroid_r[mask_index]) ** 2 + (cols - centroid_c[mask_index]) ** 2
    best = _reduce(dist, "min")
    is_best = dist <= best[mask_index]
    # First pair reaching the minimum of each mask (pairs are sorted by mask index).
    position = torch.arange(mask_index.numel(), device=device, dtype=wide)
    unreached = torch.full_like(position, float(mask_index.numel()))
    first = _reduce(torch.where(is_best, position, unreached), "min")
    chosen = first[prompted].long()
    point_rc = torch.stack([rows[chosen], cols[chosen]], dim=1)

    boxes = torch.stack(
        [
            _reduce(cols, "min"),
            _reduce(rows, "min"),
            _reduce(cols, "max"),
            _reduce(rows, "max"),
        ],
        dim=1,
    )[prompted]
    if frame_runs is not None:
        boxes = _extend_to_unseen_edges(boxes, frame_runs, weights.view_size)
    points_xy = point_rc.flip(1)[:, None, :].cpu().numpy()
    return (
        Prompts(
            points=points_xy,
            point_labels=np.ones(points_xy.shape[:2], dtype=np.int64),
            boxes=boxes.cpu().numpy(),
        ),
        prompted,
    )


def _extend_to_unseen_edges(
    boxes: torch.Tensor, runs: FrameRuns, view_size: tuple[int, int]
) -> torch.Tensor:
    """Move each box edge that reaches an unseen frame strip to the frame edge."""
    height, width = view_size
    device = boxes.device
    rows = torch.arange(height, device=device, dtype=boxes.dtype)[None]
    cols = torch.arange(width, device=device, dtype=boxes.dtype)[None]
    in_rows = (rows >= boxes[:, 1:2]) & (rows <= boxes[:, 3:4])  # (N, U)
    in_cols = (cols >= boxes[:, 0:1]) & (cols <= boxes[:, 2:3])  # (N, V)

    def reach(run: torch.Tensor, inside: torch.Tensor) -> torch.Tensor:
        return (run.to(device=device, dtype=boxes.dtype)[None] * inside).amax(dim=1)

    left, right = reach(runs.left, in_rows), reach(runs.right, in_rows)
    top, bottom = reach(runs.top, in_cols), reach(runs.bottom, in_cols)
    out = boxes.clone()
    out[:, 0] = torch.where((left > 0) & (boxes[:, 0] <= left), 0.0, boxes[:, 0])
    out[:, 2] = torch.where(
        (right > 0) & (boxes[:, 2] >= width - 1 - right), width - 1.0, boxes[:, 2]
    )
    out[:, 1] = torch.where((top > 0) & (boxes[:, 1] <= top), 0.0, boxes[:, 1])
    out[:, 3] = torch.where(
        (bottom > 0) & (boxes[:, 3] >= height - 1 - bottom), height - 1.0, boxes[:, 3]
    )
    return out


def mask_iou(
    candidates: torch.Tensor, reference: torch.Tensor, region: torch.Tensor | None = None
) -> torch.Tensor:
    """IoU of each candidate mask with its reference mask, optionally within a region.

    Parameters
    ----------
    candidates : (N, K, U, V) bool tensor
    reference : (N, U, V) bool tensor
    region : (U, V) bool tensor, optional
        Count only these pixels.

    Returns
    -------
    (N, K) float tensor (0 where both are empty)
    """
    device = candidates.device
    n, k = candidates.shape[:2]
    flat = candidates.reshape(n, k, -1)

    def count(bits: torch.Tensor) -> torch.Tensor:
        # Summing bytes into int32 is about twice as fast as counting bools on CPU.
        return bits.view(torch.uint8).sum(dim=-1, dtype=torch.int32)

    cand_area = count(flat)
    ref = reference.to(device).reshape(n, -1)
    if region is not None:
        # Only pixels inside the region count; outside it is usually a thin strip, so remove
        # its pixels from the candidate areas by a gather instead of masking everything.
        region = region.to(device).reshape(-1)
        outside = torch.nonzero(~region, as_tuple=True)[0]
        cand_area = cand_area - count(flat[:, :, outside])
        ref = ref & region
    # Intersections by a gather at the reference pixels (sparse), not a dense AND.
    mask_index, pixel_index = torch.nonzero(ref, as_tuple=True)
    hits = flat[mask_index, :, pixel_index]  # (P, K)
    if device.type == "cuda":  # segment sums: no atomics (lfsam.segments)
        lengths = segment_lengths(mask_index, n)
        inter = torch.stack(
            [segment_reduce(hits[:, j].float(), mask_index, n, "sum", lengths) for j in range(k)],
            dim=1,
        ).to(torch.int32)
        ref_area = lengths.to(torch.int32)
    else:
        inter = torch.zeros((n, k), dtype=torch.int32, device=device)
        inter.index_add_(0, mask_index, hits.to(torch.int32))
        ref_area = torch.bincount(mask_index, minlength=n).to(torch.int32)
    union = cand_area + ref_area[:, None] - inter
    return inter.to(torch.float32) / union.clamp(min=1).to(torch.float32)


def refine_masks(
    segmenter: Segmenter,
    embedding: ViewEmbedding,
    coarse: torch.Tensor,
    weights: OcclusionWeights,
    t_iou: float = 0.1,
    seen: torch.Tensor | None = None,
    frame_runs: FrameRuns | None = None,
    chunk_size: int = 64,
    extra_points: tuple[np.ndarray, np.ndarray] | None = None,
) -> RefinementOutcome:
    """Re-prompt the segmenter in one view and keep refined masks that agree with the coarse ones.

    Parameters
    ----------
    segmenter : Segmenter
    embedding : ViewEmbedding
        The encoded view (encoded once; the same embedding served semantic occluding).
    coarse : (N, U, V) bool tensor
        Coarse masks of the view (after occluding): the IoU reference and the fallback.
    weights : OcclusionWeights
        Surviving pixels and weights for the prompts.
    t_iou : float
        A refined mask is kept only if its IoU with the coarse mask exceeds this.
    seen : (U, V) bool tensor, optional
        View pixels the propagation reaches; the IoU with the coarse mask is measured there
        only (the coarse mask knows nothing of content the center view does not see).
    frame_runs : FrameRuns, optional
        Unseen strips at the frame border; see :func:`refinement_prompts`.
    chunk_size : int
        Prompts decoded per batch (bounds memory; each batch is one decoder call).
    extra_points : ((N, P, 2) float, (N, P) int) ndarrays, optional
        The user's own clicks carried into this view (docs/design.md section 8): appended to
        each mask's prompt after the refinement point, labels 1 positive, 0 negative, -1 padding.

    Returns
    -------
    RefinementOutcome
    """
    n = coarse.shape[0]
    device = coarse.device
    masks = coarse.clone()
    fallback = torch.ones(n, dtype=torch.bool, device=device)
    iou = torch.full((n,), float("nan"), device=device)
    prompts, prompted = refinement_prompts(weights, frame_runs)
    if prompts is None:
        return RefinementOutcome(masks, fallback, iou)
    index = torch.nonzero(prompted, as_tuple=True)[0].to(device)
    # Prompts with the same number of carried clicks are decoded together, each group without
    # padding: SAM 2 attends to a padding point (label -1) like to any token, so padding one
    # mask's prompt to another's length would change its answer, and a mask's refinement would
    # depend on which other objects share the view (an incremental edit would differ from a
    # full run).
    groups = [(torch.arange(len(index), device=device), prompts)]
    if extra_points is not None and extra_points[0].shape[1] > 0:
        rows_np = index.cpu().numpy()
        carried = (extra_points[1][rows_np] != -1).sum(axis=1)
        groups = []
        for count in np.unique(carried):
            members = np.flatnonzero(carried == count)
            groups.append((
                torch.as_tensor(members, device=device),
                Prompts(
                    points=np.concatenate(
                        [prompts.points[members], extra_points[0][rows_np[members], :count]],
                        axis=1,
                    ),
                    point_labels=np.concatenate(
                        [prompts.point_labels[members],
                         extra_points[1][rows_np[members], :count]],
                        axis=1,
                    ),
                    boxes=None if prompts.boxes is None else prompts.boxes[members],
                ),
            ))
    # One batched decode per chunk of prompts, each chunk reduced to its chosen masks at once,
    # so the N x 3 x U x V candidates never exist together.
    for positions, group in groups:
        for start in range(0, len(positions), chunk_size):
            rows = index[positions[start : start + chunk_size]]
            prediction = segmenter.predict(
                embedding, group.subset(slice(start, start + chunk_size)), multimask_output=True
            )
            candidates = prediction.masks.to(device)
            best_iou, best_k = mask_iou(candidates, coarse[rows], seen).max(dim=1)
            chosen = candidates[torch.arange(len(rows), device=device), best_k]
            accept = best_iou > t_iou
            masks[rows[accept]] = chosen[accept]
            fallback[rows] = ~accept
            iou[rows] = best_iou
    return RefinementOutcome(masks, fallback, iou)

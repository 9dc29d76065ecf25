"""Step 4 of the pipeline: segmentation refinement by re-prompting SAM 2 in each view.

Paper section 3.4 with the details of docs/design.md section 3.5: in view ``(s, t)`` each mask is
prompted with the box around its surviving coarse pixels and one positive point, the surviving
pixel nearest to their similarity-weighted centroid (a plain centroid can fall outside a
non-convex mask). Of the three multimask outputs the one with the highest IoU against the coarse
mask is kept, and only if that IoU exceeds ``t_iou`` (0.1 in the paper); otherwise the view falls
back to the coarse mask. All N prompts of a view go through the decoder in one batch, and with
:func:`refine_many` the prompts of several views through one call of the segmenter
(:meth:`lfsam.segmenters.base.Segmenter.predict_many`; docs/design.md section 3.5, "batched
decoder"). Prompts are built on the device and stay there: no mask or prompt goes through
NumPy on its way from the coarse masks to the refined ones.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from lfsam.pipeline.occlusion import OcclusionWeights
from lfsam.precision import wide_float
from lfsam.result import pack_masks
from lfsam.segmenters.base import ABSENT_POINT, Prompts, Segmenter, ViewEmbedding
from lfsam.segments import segment_lengths, segment_reduce
from lfsam.warp import ForwardWarp, FrameRuns

__all__ = [
    "RefineRequest",
    "RefinementOutcome",
    "mask_iou",
    "read_back",
    "refine_many",
    "refine_masks",
    "refinement_prompts",
    "seen_per_mask",
]


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
        reach (beyond the paper, which leaves the frame border implicit). Masks propagated
        from different reference views see different strips: then each field holds one row
        per mask (:meth:`lfsam.warp.FrameRuns.stack`).

    Returns
    -------
    prompts : Prompts or None
        One prompt per mask that has surviving pixels (None if no mask has any), as tensors on
        the device of ``weights`` (float32 points and boxes, int64 labels).
    prompted : (N,) bool tensor
        Which masks got a prompt (rows of ``prompts`` are these masks, in order).
    """
    prompts, prompted, _ = _prompts_of(weights, frame_runs)
    return prompts, prompted


def _prompts_of(
    weights: OcclusionWeights, frame_runs: FrameRuns | None
) -> tuple[Prompts | None, torch.Tensor, torch.Tensor]:
    """:func:`refinement_prompts` and the prompted masks' numbers, ``(M,)`` int64: the host
    waits for the device twice (the sizes of the surviving pairs and of the prompted masks)."""
    n = weights.num_masks
    width = weights.view_size[1]
    device = weights.weight.device
    keep = torch.nonzero(weights.weight > 0, as_tuple=True)[0]
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
    index = torch.nonzero(prompted, as_tuple=True)[0]
    if index.numel() == 0:
        return None, prompted, index
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
    chosen = first[index].long()
    point_rc = torch.stack([rows[chosen], cols[chosen]], dim=1)

    boxes = torch.stack(
        [
            _reduce(cols, "min"),
            _reduce(rows, "min"),
            _reduce(cols, "max"),
            _reduce(rows, "max"),
        ],
        dim=1,
    )[index]
    if frame_runs is not None:
        if frame_runs.per_mask:
            frame_runs = frame_runs.rows(index)
        boxes = _extend_to_unseen_edges(boxes, frame_runs, weights.view_size)
    points_xy = point_rc.flip(1)[:, None, :].to(torch.float32)
    return (
        Prompts(
            points=points_xy,
            point_labels=torch.ones(points_xy.shape[:2], dtype=torch.int64, device=device),
            boxes=boxes.to(torch.float32),
            absent_points=False,
        ),
        prompted,
        index,
    )


def _extend_to_unseen_edges(
    boxes: torch.Tensor, runs: FrameRuns, view_size: tuple[int, int]
) -> torch.Tensor:
    """Move each box edge that reaches an unseen frame strip to the frame edge (``runs``
    shared by every box, or one row per box)."""
    height, width = view_size
    device = boxes.device
    rows = torch.arange(height, device=device, dtype=boxes.dtype)[None]
    cols = torch.arange(width, device=device, dtype=boxes.dtype)[None]
    in_rows = (rows >= boxes[:, 1:2]) & (rows <= boxes[:, 3:4])  # (N, U)
    in_cols = (cols >= boxes[:, 0:1]) & (cols <= boxes[:, 2:3])  # (N, V)

    def reach(run: torch.Tensor, inside: torch.Tensor) -> torch.Tensor:
        run = run.to(device=device, dtype=boxes.dtype)
        return ((run if run.dim() == 2 else run[None]) * inside).amax(dim=1)

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
    candidates: torch.Tensor,
    reference: torch.Tensor,
    region: torch.Tensor | None = None,
    dense: bool | None = None,
) -> torch.Tensor:
    """IoU of each candidate mask with its reference mask, optionally within a region.

    Parameters
    ----------
    candidates : (N, K, U, V) bool tensor
    reference : (N, U, V) bool tensor
    region : (U, V) or (N, U, V) bool tensor, optional
        Count only these pixels (the same for every mask, or one region per mask).
    dense : bool, optional
        Count by dense ANDs of whole masks (no pixel lists, so the host never waits for the
        device) instead of gathering at the reference pixels; default on CUDA, where memory
        bandwidth is plentiful. The counts, hence the IoUs, are the same either way.

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

    ref = reference.to(device).reshape(n, -1)
    per_mask = region is not None and region.dim() == 3
    if device.type == "cuda" if dense is None else dense:
        if region is not None:
            inside = region.to(device).reshape(n if per_mask else 1, -1)
            flat, ref = flat & inside[:, None], ref & inside
        inter = count(flat & ref[:, None])
        union = count(flat) + count(ref)[:, None] - inter
        return inter.to(torch.float32) / union.clamp(min=1).to(torch.float32)
    if per_mask:  # one region per mask: the candidates' areas inside their own
        inside = region.to(device).reshape(n, -1)
        cand_area = count(flat & inside[:, None])
        ref = ref & inside
        region = None
    else:
        cand_area = count(flat)
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


@dataclass
class RefineRequest:
    """What refinement needs of one view (the parameters of :func:`refine_masks`)."""

    embedding: ViewEmbedding
    coarse: torch.Tensor
    weights: OcclusionWeights
    seen: torch.Tensor | None = None
    frame_runs: FrameRuns | None = None
    extra_points: tuple[np.ndarray, np.ndarray] | None = None


def seen_per_mask(
    warps: Sequence[ForwardWarp], counts: Sequence[int], view_size: tuple[int, int]
) -> tuple[torch.Tensor, FrameRuns]:
    """What the masks of one view, propagated from several reference views, each see there:
    the pixels their own warp reaches (:meth:`~lfsam.warp.ForwardWarp.seen`) and the frame
    strips it does not (:meth:`~lfsam.warp.ForwardWarp.frame_runs`), for a
    :class:`RefineRequest` (docs/design.md section 3.5, "one request per view").

    Parameters
    ----------
    warps : sequence of ForwardWarp
        The warp of each reference view into this view.
    counts : sequence of int
        How many masks (in order) came through each warp.
    view_size : (U, V)

    Returns
    -------
    seen : (U, V) bool tensor with one warp, else (N, U, V)
    runs : FrameRuns, shared with one warp, else one row per mask
    """
    seen = [warp.seen(view_size) for warp in warps]
    runs = [warp.frame_runs(view_size, shown) for warp, shown in zip(warps, seen, strict=True)]
    if len(warps) == 1:
        return seen[0], runs[0]
    return (torch.cat([shown[None].expand(c, -1, -1)
                       for shown, c in zip(seen, counts, strict=True)]),
            FrameRuns.stack(runs, list(counts)))


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
    seen : (U, V) or (N, U, V) bool tensor, optional
        View pixels the propagation reaches; the IoU with the coarse mask is measured there
        only (the coarse mask knows nothing of content the center view does not see). One
        map per mask where the masks come from different reference views.
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
    request = RefineRequest(embedding, coarse, weights, seen, frame_runs, extra_points)
    return refine_many(segmenter, [request], t_iou, chunk_size)[0]


def _prompt_groups(
    index: torch.Tensor,
    prompts: Prompts,
    extra_points: tuple[np.ndarray, np.ndarray] | None,
    merge: bool = False,
) -> list[tuple[torch.Tensor, Prompts]]:
    """The prompts of one view split by the number of carried clicks: ``(positions in index,
    prompts)`` per group.

    Prompts with the same number of carried clicks are decoded together, each group without
    padding: SAM 2 attends to a padding point (label -1) like to any token, so padding one
    mask's prompt to another's length would change its answer, and a mask's refinement would
    depend on which other objects share the view (an incremental edit would differ from a full
    run). With ``merge`` (a segmenter that
    :attr:`~lfsam.segmenters.base.Segmenter.skips_absent_points`) there is one group, the
    shorter prompts padded with absent points, which such a segmenter answers as without them
    (docs/design.md section 3.5). The clicks are the user's (host arrays); only with them are
    the prompted masks' numbers read back to group them.
    """
    device = index.device
    if extra_points is None or extra_points[0].shape[1] == 0:
        return [(torch.arange(len(index), device=device), prompts)]
    rows_np = index.cpu().numpy()
    carried = (extra_points[1][rows_np] != -1).sum(axis=1)
    points = torch.as_tensor(extra_points[0], dtype=torch.float32).to(device)
    labels = torch.as_tensor(extra_points[1], dtype=torch.int64).to(device)
    if merge:
        width = int(carried.max())
        labels = torch.where(labels == -1, ABSENT_POINT, labels)
        counts = [(width, torch.arange(len(index), device=device), carried.min() < width)]
    else:
        counts = [
            (int(count), torch.as_tensor(np.flatnonzero(carried == count), device=device), False)
            for count in np.unique(carried)
        ]
    groups = []
    for count, members, absent in counts:
        rows = index[members]
        groups.append((
            members,
            Prompts(
                points=torch.cat([prompts.points[members], points[rows, :count]], dim=1),
                point_labels=torch.cat(
                    [prompts.point_labels[members], labels[rows, :count]], dim=1
                ),
                boxes=None if prompts.boxes is None else prompts.boxes[members],
                absent_points=bool(absent),
            ),
        ))
    return groups


def _pad_points(prompts: Prompts, width: int) -> Prompts:
    """``prompts`` with absent points appended up to ``width`` points per prompt."""
    assert prompts.points is not None and prompts.point_labels is not None
    n, have = prompts.point_labels.shape
    if have >= width:
        return prompts
    points, labels = prompts.points, prompts.point_labels
    return Prompts(
        points=torch.cat([points, points.new_zeros((n, width - have, 2))], dim=1),
        point_labels=torch.cat(
            [labels, labels.new_full((n, width - have), ABSENT_POINT)], dim=1
        ),
        boxes=prompts.boxes,
        absent_points=True,
    )


def refine_many(
    segmenter: Segmenter,
    requests: Sequence[RefineRequest],
    t_iou: float = 0.1,
    chunk_size: int = 64,
) -> list[RefinementOutcome]:
    """:func:`refine_masks` in several views, their prompts decoded together.

    Each view's prompts are cut into the chunks :func:`refine_masks` decodes (at most
    ``chunk_size`` prompts, one group of carried clicks each); one call of
    :meth:`~lfsam.segmenters.base.Segmenter.predict_many` takes one chunk of every view whose
    prompts have the same shape. A segmenter that
    :attr:`~lfsam.segmenters.base.Segmenter.skips_absent_points` gets every prompt padded to
    the longest one with absent points instead: one shape, so one call takes every view
    (docs/design.md section 3.5, "one decoder call for prompts of different lengths").
    A view's candidates of several groups are chosen among
    together (:func:`_choose` once per view where its prompts number fewer than
    ``chunk_size``: fewer kernel launches on a GPU), so memory stays bounded by
    ``2 * chunk_size`` candidates per view. A view's outcome does not depend on which views
    share its calls (on a CPU, bit for bit: tests/test_batched_decoder.py).

    Returns
    -------
    list of RefinementOutcome
        One per request, in order.
    """
    outcomes = []
    # shape of the prompts -> view -> its chunks (rows in the view's masks, prompts)
    jobs: dict[tuple[int, bool], dict[int, list[tuple[torch.Tensor, Prompts]]]] = defaultdict(
        lambda: defaultdict(list)
    )
    merge = segmenter.skips_absent_points
    groups: list[tuple[int, torch.Tensor, Prompts]] = []  # (view, rows in its masks, prompts)
    for k, request in enumerate(requests):
        n = request.coarse.shape[0]
        device = request.coarse.device
        outcomes.append(RefinementOutcome(
            request.coarse.clone(),
            torch.ones(n, dtype=torch.bool, device=device),
            torch.full((n,), float("nan"), device=device),
        ))
        prompts, _, index = _prompts_of(request.weights, request.frame_runs)
        if prompts is None:
            continue
        groups.extend((k, index[positions], group)
                      for positions, group in _prompt_groups(index, prompts,
                                                             request.extra_points, merge))
    if merge and groups:  # every view's prompts one length: one call for all views
        width = max(int(group.points.shape[1]) for _, _, group in groups)
        groups = [(k, rows, _pad_points(group, width)) for k, rows, group in groups]
    for k, rows, group in groups:
        shape = (int(group.points.shape[1]), group.boxes is not None)
        for start in range(0, len(rows), chunk_size):
            chunk = slice(start, start + chunk_size)
            jobs[shape][k].append((rows[chunk], group.subset(chunk)))
    # A view's candidates wait until ``chunk_size`` rows are in (or the last call), then are
    # chosen among at once: one choice per view, not per group of carried clicks.
    waiting: dict[int, list[tuple[torch.Tensor, torch.Tensor]]] = defaultdict(list)

    def choose_waiting(k: int) -> None:
        parts = waiting.pop(k)
        rows = torch.cat([r for r, _ in parts]) if len(parts) > 1 else parts[0][0]
        masks = torch.cat([m for _, m in parts]) if len(parts) > 1 else parts[0][1]
        _choose(outcomes[k], requests[k], rows, masks, t_iou)

    for per_view in jobs.values():
        while any(per_view.values()):
            views = [k for k, queue in per_view.items() if queue]
            batch = [per_view[k].pop(0) for k in views]
            predictions = segmenter.predict_many(
                [requests[k].embedding for k in views], [p for _, p in batch],
                multimask_output=True,
            )
            for k, (rows, _), prediction in zip(views, batch, predictions, strict=True):
                waiting[k].append((rows, prediction.masks))
                if sum(len(r) for r, _ in waiting[k]) >= chunk_size:
                    choose_waiting(k)
    for k in list(waiting):
        choose_waiting(k)
    return outcomes


def read_back(outcomes: Sequence[RefinementOutcome]) -> tuple[np.ndarray, np.ndarray]:
    """What the host keeps of several views' outcomes, in one read from the device each: the
    masks bit-packed (:func:`lfsam.result.pack_masks`), rows of all outcomes in order, and a
    ``(2, rows)`` float32 array of the fallback flags (0/1) and the IoUs."""
    masks = [o.masks for o in outcomes]
    bits = pack_masks(torch.cat(masks) if len(masks) > 1 else masks[0])
    flags = [torch.stack([o.fallback.to(o.iou.dtype), o.iou]) for o in outcomes]
    return bits, torch.cat(flags, dim=1).cpu().numpy()


def _choose(
    outcome: RefinementOutcome, request: RefineRequest, rows: torch.Tensor,
    candidates: torch.Tensor, t_iou: float,
) -> None:
    """Keep, for the masks ``rows``, the candidate of highest IoU with the coarse mask where
    that IoU exceeds ``t_iou`` (written into ``outcome``, without reading anything back)."""
    device = request.coarse.device
    candidates = candidates.to(device)
    seen = request.seen
    if seen is not None and seen.dim() == 3:
        seen = seen[rows]
    best_iou, best_k = mask_iou(candidates, request.coarse[rows], seen).max(dim=1)
    chosen = candidates[torch.arange(len(rows), device=device), best_k]
    accept = best_iou > t_iou
    outcome.masks[rows] = torch.where(accept[:, None, None], chosen, outcome.masks[rows])
    outcome.fallback[rows] = ~accept
    outcome.iou[rows] = best_iou

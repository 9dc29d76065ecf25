"""Masks of a view that is not refined, carried from the refined views nearest to it.

With ``--refine-views sparse`` or ``N`` (docs/design.md section 3.7) only some views are encoded
and refined; every other view takes each object's mask from the refined views nearest to it
(:func:`lfsam.pipeline.sparse.nearest_sources`). Each source's refined masks are moved into the
view with the source's disparity (per-pixel forward warping, :mod:`lfsam.warp`) and the
source's own z-buffer visibility test, as the coarse masks of step 2 are; the sources are then
combined pixel by pixel, so that a region one source cannot see (a disocclusion) comes from a
source that sees it:

1. what each source knows of a target pixel: a source pixel *landed* on it (best), it is a
   forward-warping hole the source fills from its neighbours (next), or the source does not see
   it (frame border strips, disocclusions too wide to fill);
2. the sources that know the pixel best vote on each object's membership, weighted by the
   inverse of their distance to the view (in view steps); more than half the weight decides.

3. where the sources disagree (a vote strictly between 0 and 1: mostly along mask edges), the
   vote is filtered with a guided filter steered by the view's own gray image (He, Sun & Tang,
   "Guided image filtering", TPAMI 2013; radius :data:`GUIDE_RADIUS`, regulariser
   :data:`GUIDE_EPS`) before it is thresholded at one half: where the image has an edge near
   the carried one, the mask edge moves onto it. Unanimous pixels keep the sources' answer
   (filtering them too gains nothing measurable and moves exact edges on textured objects).

Each source's nearest-pixel rounding misplaces a mask edge by up to half a pixel; sources at
other offsets round differently, and their vote puts the edge closer to where it is (on 9 x 9
synthetic views, 23% fewer wrong pixels than taking the nearest source alone); the guided filter
takes off another 16-29% (docs/performance.md, "Refining a few views"). A z-buffer *across*
sources (the closest surface wins) was tried and dropped: it grows every object by the rounding
of whichever source rounds outwards (docs/performance.md). Pixels no source sees keep the
``fallback`` (the coarse mask carried from the object's reference view). Which sources vote
depends on geometry only, not on the masks, so objects can be filled one at a time (incremental
edits) with the same answer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from lfsam.disparity.filters import guided_filter
from lfsam.warp import ForwardWarp, fill_warp_holes, splat_masks

__all__ = ["GUIDE_EPS", "GUIDE_RADIUS", "FillOutcome", "fill_from_sources", "source_knowledge"]

_LANDED, _HOLE = 2, 1

#: Guided filter of the vote (module docstring, step 3): window radius in pixels, and the
#: regulariser on the gray guide's variance (intensities in [0, 1]). Chosen on 9 x 9 synthetic
#: scenes among radius 1-2 and eps 1e-4 to 1e-1.
GUIDE_RADIUS = 1
GUIDE_EPS = 1e-2


@dataclass(frozen=True)
class FillOutcome:
    """Masks of one view filled from refined sources.

    Attributes
    ----------
    masks : (N, U, V) bool tensor
    voters : (K, U, V) bool tensor
        The sources that voted on each pixel (none where no source sees it and the fallback
        stays).
    """

    masks: torch.Tensor
    voters: torch.Tensor


def source_knowledge(warps: Sequence[ForwardWarp], view_size: tuple[int, int]) -> torch.Tensor:
    """What each source knows of each target pixel: 2 landed, 1 a hole it fills, 0 unseen.

    Parameters
    ----------
    warps : sequence of K ForwardWarp
        Each source's disparity forward-warped into the target view.
    view_size : (U, V)

    Returns
    -------
    (K, U, V) int tensor

    Examples
    --------
    A row seen from a source on its left and one on its right (disparity 1, one view step):
    each frame-edge pixel is seen by one source only.

    >>> from lfsam.warp import forward_warp
    >>> one = torch.ones((1, 3))
    >>> left, right = forward_warp(one, 0, 1), forward_warp(one, 0, -1)
    >>> source_knowledge([left, right], (1, 3)).tolist()
    [[[2, 2, 0]], [[0, 2, 2]]]
    """
    height, width = view_size
    status = []
    for warp in warps:
        landed = torch.isfinite(warp.zbuffer).reshape(height, width)
        seen = warp.seen(view_size)
        status.append(torch.where(landed, _LANDED, torch.where(seen, _HOLE, 0)))
    if not status:
        return torch.zeros((0, height, width), dtype=torch.int64)
    return torch.stack(status)


def fill_from_sources(
    source_masks: Sequence[torch.Tensor],
    source_disparities: Sequence[torch.Tensor],
    warps: Sequence[ForwardWarp],
    distances: Sequence[float],
    fallback: torch.Tensor,
    tolerance: float,
    guide: torch.Tensor | None = None,
    agree: Sequence[torch.Tensor | None] | None = None,
    contested: float = 0.0,
) -> FillOutcome:
    """The masks of one view carried from refined source views (module docstring).

    Parameters
    ----------
    source_masks : sequence of K (N, U, V) bool tensors
        Each source view's final (refined) masks of the same N objects.
    source_disparities : sequence of K (U, V) float tensors
        Each source view's disparity.
    warps : sequence of K ForwardWarp
        Each source's disparity forward-warped into this view
        (:func:`lfsam.warp.forward_warp` with the offset of this view from the source).
    distances : sequence of K floats
        Each source's distance from this view, in view steps (> 0); votes weigh ``1 / d``.
    fallback : (N, U, V) bool tensor
        What pixels no source sees keep: the coarse masks carried from the reference view.
    tolerance : float
        The sources' own z-buffer tolerance, pixels per view step
        (``PipelineConfig.zbuffer_tolerance``).
    guide : (U, V) float tensor, optional
        This view's gray image in [0, 1]: the vote is guided-filtered with it (step 3); None
        thresholds the vote as it is.
    agree : sequence of K (U, V) bool tensors or None, optional
        Where each source's landed surface is the one this view shows (the multi-view
        consensus, docs/design.md section 3.9): a landed pixel outside it counts as unseen by
        that source. None (or a None entry): every landed pixel counts.

    Returns
    -------
    FillOutcome

    Examples
    --------
    An object one pixel wide at disparity 1 in the views left and right of this one: both carry
    it onto the middle pixel.

    >>> from lfsam.warp import forward_warp
    >>> one = torch.ones((1, 3))
    >>> left = torch.tensor([[[False, False, True]]])
    >>> right = torch.tensor([[[True, False, False]]])
    >>> warps = [forward_warp(one, 0, 1), forward_warp(one, 0, -1)]
    >>> outcome = fill_from_sources([left, right], [one, one], warps, [1.0, 1.0],
    ...                             torch.zeros((1, 1, 3), dtype=torch.bool), 0.2)
    >>> outcome.masks.int().tolist()
    [[[0, 1, 0]]]
    """
    view_size = (int(fallback.shape[-2]), int(fallback.shape[-1]))
    status = source_knowledge(warps, view_size).to(fallback.device)
    for j, where in enumerate(agree or ()):
        if where is not None:
            status[j] = torch.where((status[j] == _LANDED) & ~where, 0, status[j])
    best = status.max(dim=0).values if len(status) else torch.zeros(view_size, dtype=torch.int64)
    voters = (status == best) & (best > 0)
    weights = torch.as_tensor(
        [1.0 / float(d) for d in distances], dtype=torch.float32, device=fallback.device
    )
    cast = voters.to(torch.float32) * weights[:, None, None]
    total = cast.sum(dim=0)
    votes = torch.zeros(fallback.shape, dtype=torch.float32, device=fallback.device)
    ask = _skip_idle_sources(fallback.device)
    for j, (masks, disparity, warp) in enumerate(
        zip(source_masks, source_disparities, warps, strict=True)
    ):
        if ask and not bool(voters[j].any()):
            continue
        keep = warp.visible(disparity, tolerance)
        carried = splat_masks(masks, warp, keep)
        if not ask or bool((voters[j] & (status[j] == _HOLE)).any()):  # its holes vote
            carried = fill_warp_holes(carried, masks, warp, keep)
        votes += carried.to(torch.float32) * cast[j]
    seen = best > 0
    share = torch.where(seen, votes / total.clamp(min=1e-12), fallback.to(torch.float32))
    decided = share > 0.5
    if guide is not None:
        _guide_contested(decided, share, guide.to(share), contested)
    masks = torch.where(seen, decided, fallback)
    return FillOutcome(masks=masks, voters=voters)


def _skip_idle_sources(device: torch.device) -> bool:
    """Whether :func:`fill_from_sources` asks which sources vote anywhere and skips the others'
    work: on a CPU; on a GPU asking costs a host round trip, more than the work, and a source
    that votes nowhere adds zero votes, so both give the same masks."""
    return device.type != "cuda"


def _guide_contested(decided: torch.Tensor, share: torch.Tensor, guide: torch.Tensor,
                     margin: float = 0.0) -> None:
    """Step 3 of the module docstring, in place on ``decided``: each object's vote is
    guided-filtered within the bounding box of its contested pixels plus the filter's reach,
    and the contested pixels take the filtered answer. A pixel's filtered value depends only on
    the vote within ``2 * GUIDE_RADIUS`` of it, so any box holding that reach gives the same
    answer: when the objects' boxes overlap much (masks covering most of the view), their votes
    are filtered together in one box (one batched filter), else box by box."""
    contested = (share > margin) & (share < 1 - margin)  # where the sources disagree
    rows, cols = contested.any(dim=2), contested.any(dim=1)
    # every object's box and the union's, read back to the host in one copy
    found, *box_rows = _reach_boxes(torch.cat([rows, rows.any(dim=0, keepdim=True)]),
                                    torch.cat([cols, cols.any(dim=0, keepdim=True)]))
    found = found[:-1]
    objects = [k for k, hit in enumerate(found) if hit]
    if not objects:
        return
    boxes = {k: box_rows[k] for k in objects}
    union = box_rows[-1]
    areas = sum(_area(box) for box in boxes.values())
    groups = ([(objects, union)] if len(objects) * _area(union) <= 2 * areas
              else [([k], box) for k, box in boxes.items()])
    for members, (r0, r1, c0, c1) in groups:
        filtered = guided_filter(guide[r0:r1, c0:c1], share[members, r0:r1, c0:c1],
                                 GUIDE_RADIUS, GUIDE_EPS)
        window = contested[members, r0:r1, c0:c1]
        decided[members, r0:r1, c0:c1] = torch.where(window, filtered > 0.5,
                                                     decided[members, r0:r1, c0:c1])


def _reach_boxes(rows: torch.Tensor, cols: torch.Tensor) -> list:
    """Per line ``k`` of the ``(K, U)`` flagged rows and ``(K, V)`` flagged columns: whether any
    is flagged, then its box ``(r0, r1, c0, c1)``: the first to one past the last flagged row
    and column, widened by the guided filter's reach (``2 * GUIDE_RADIUS``) within the view.

    Returns
    -------
    list
        ``[found, box_0, ..., box_{K-1}]``: ``found`` a list of K bools, each box a tuple of
        four ints (meaningless where nothing is flagged). One host copy for all of them.
    """
    reach = 2 * GUIDE_RADIUS
    height, width = rows.shape[-1], cols.shape[-1]

    def ends(flags: torch.Tensor, size: int) -> tuple[torch.Tensor, torch.Tensor]:
        first = flags.to(torch.uint8).argmax(dim=1)  # the first maximum: the first flag
        last = size - 1 - flags.flip(1).to(torch.uint8).argmax(dim=1)
        return (first - reach).clamp(min=0), (last + reach + 1).clamp(max=size)

    r0, r1 = ends(rows, height)
    c0, c1 = ends(cols, width)
    table = torch.stack([rows.any(dim=1).long(), r0, r1, c0, c1], dim=1).tolist()
    return [[bool(line[0]) for line in table], *[tuple(line[1:]) for line in table]]


def _area(box: tuple[int, int, int, int]) -> int:
    return (box[1] - box[0]) * (box[3] - box[2])

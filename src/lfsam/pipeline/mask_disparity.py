"""The disparity of an object the center view's estimate does not see, from its refined masks.

With ``--refine-views sparse`` or ``N`` and an estimated disparity (docs/design.md section 3.7),
a refined view's masks are carried into the views filled from it with the center view's
estimate forward-warped into that view (:meth:`lfsam.disparity.views.ViewDisparities.carried`).
An object hidden in the center view (prompted in another view, ``--references``) has no surface
there: every one of its pixels in the source is a hole of that warp, filled from the farther
side, i.e. with the background behind it, and the object is carried by the wrong amount (on a
9 x 9 benchmark scene by 0.4 pixel per view step, which loses a sliver of a few pixels wide).

Its own refined masks hold the answer: the object moves between the refined views by its
disparity. :func:`matched_disparity` finds the disparity that moves each of its masks onto the
others best, leaving out pixels where a closer surface covers it in either view (an occluder
cuts a hidden object differently in each view), and :func:`unseen_by_estimate` says when the
carried estimate knows nothing of the object (most of its pixels are holes of the warp).

* :func:`matched_disparity` — one disparity for an object from its masks in several views;
* :func:`unseen_by_estimate` — whether the carried disparity is filled in on most of a mask.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from lfsam.warp import shift_whole_pixels

__all__ = ["MATCH_STEP", "UNSEEN_SHARE", "matched_disparity", "unseen_by_estimate"]

#: Spacing of the disparities tried by :func:`matched_disparity`, pixels per view step.
MATCH_STEP = 0.01

#: :func:`unseen_by_estimate`: the share of an object's pixels that must be holes of the
#: carried disparity for the estimate to count as not seeing the object.
UNSEEN_SHARE = 0.5

View = tuple[int, int]


def unseen_by_estimate(masks: Sequence[torch.Tensor], holes: Sequence[torch.Tensor]) -> bool:
    """Whether at least :data:`UNSEEN_SHARE` of an object's pixels are holes of the carried
    disparity (pixels no center pixel landed on), over the given views.

    Parameters
    ----------
    masks : sequence of (U, V) bool tensors
        The object's masks in views whose disparity is the center's estimate warped.
    holes : sequence of (U, V) bool tensors
        The holes of each of those warps (:meth:`lfsam.disparity.views.ViewDisparities.
        carried_holes`).

    Returns
    -------
    bool
        False when the masks are empty.

    Examples
    --------
    >>> mask = torch.tensor([[True, True, True, False]])
    >>> unseen_by_estimate([mask], [torch.tensor([[True, True, False, False]])])
    True
    >>> unseen_by_estimate([mask], [torch.tensor([[True, False, False, True]])])
    False
    """
    total = sum(int(m.sum()) for m in masks)
    filled = sum(int((m & h).sum()) for m, h in zip(masks, holes, strict=True))
    return total > 0 and filled >= UNSEEN_SHARE * total


def matched_disparity(
    masks: Sequence[torch.Tensor],
    disparities: Sequence[torch.Tensor],
    views: Sequence[View],
    tolerance: float,
    step: float = MATCH_STEP,
) -> float | None:
    """The disparity that moves an object's masks onto each other best, across views.

    Every candidate disparity ``d`` (from the smallest to the largest value of ``disparities``
    around the masks, spaced ``step``) moves the mask of each view into each other view
    as a whole, by ``d`` times their offset rounded to the nearest pixel (the convention of
    :func:`lfsam.warp.forward_warp`: a pixel ``x`` lands at ``x - d (ds, dt)``). Pixels where
    either view shows a surface closer than ``d`` (disparity above ``d`` plus ``tolerance``
    times the views' distance) are left out: there the object may be hidden in one view and not
    in the other. The score of ``d`` is the share of the remaining pixels on which the moved
    mask and the view's own mask agree, among those covered by either, summed over all ordered
    pairs of views with a non-empty mask. The answer is the middle of the longest run of
    candidates with the best score.

    Parameters
    ----------
    masks : sequence of K (U, V) bool tensors
        The object's masks in K views (empty masks are ignored).
    disparities : sequence of K (U, V) float tensors
        Each view's disparity, for the test of closer surfaces.
    views : sequence of K (s, t)
        The views' grid positions.
    tolerance : float
        Pixels per view step (``PipelineConfig.zbuffer_tolerance``).
    step : float
        Spacing of the candidates.

    Returns
    -------
    float or None
        None when fewer than two masks are non-empty.

    Examples
    --------
    A 2-pixel bar at disparity 1 in three views of a row:

    >>> masks = [torch.zeros((1, 12), dtype=torch.bool) for _ in range(3)]
    >>> for k, col in enumerate((6, 5, 4)):
    ...     masks[k][0, col:col + 2] = True
    >>> flat = [torch.linspace(-2, 2, 12)[None] for _ in range(3)]
    >>> d = matched_disparity(masks, flat, [(0, 0), (0, 1), (0, 2)], 0.2)
    >>> round(d) == 1
    True
    """
    present = [k for k, m in enumerate(masks) if bool(m.any())]
    if len(present) < 2:
        return None
    device = masks[present[0]].device
    height, width = masks[present[0]].shape
    union = torch.stack([masks[k] for k in present]).any(dim=0)
    reach = max(
        math.hypot(views[a][0] - views[b][0], views[a][1] - views[b][1])
        for a in present for b in present
    )
    spread = float(torch.stack([d.abs().max() for d in disparities]).max())
    pad = math.ceil(spread * reach) + 1
    rows = torch.nonzero(union.any(dim=1), as_tuple=True)[0]
    cols = torch.nonzero(union.any(dim=0), as_tuple=True)[0]
    r0, r1 = max(int(rows[0]) - pad, 0), min(int(rows[-1]) + pad + 1, height)
    c0, c1 = max(int(cols[0]) - pad, 0), min(int(cols[-1]) + pad + 1, width)
    window = [(masks[k][r0:r1, c0:c1], disparities[k][r0:r1, c0:c1].float()) for k in present]
    lo = min(float(disp.min()) for _, disp in window)
    hi = max(float(disp.max()) for _, disp in window)
    candidates = torch.arange(lo, hi + step / 2, step, device=device, dtype=torch.float64)
    agree = torch.zeros(len(candidates), dtype=torch.float64, device=device)
    either = torch.zeros_like(agree)
    for a, (mask_a, disp_a) in enumerate(window):
        for b, (mask_b, disp_b) in enumerate(window):
            if a == b:
                continue
            ds = views[present[b]][0] - views[present[a]][0]
            dt = views[present[b]][1] - views[present[a]][1]
            # a pixel x of view a lands at x - d (ds, dt), rounded as the warps round
            shifts = torch.stack([-torch.round(candidates * ds), -torch.round(candidates * dt)], 1)
            for su, sv in torch.unique(shifts, dim=0).long().tolist():
                which = (shifts[:, 0] == su) & (shifts[:, 1] == sv)
                moved = shift_whole_pixels(mask_a, su, sv)
                inside = shift_whole_pixels(torch.ones_like(mask_a), su, sv)
                closer_a = shift_whole_pixels(disp_a, su, sv)
                level = candidates[which].to(disp_b.dtype)[:, None, None] + tolerance
                keep = inside & (disp_b <= level) & (closer_a <= level)
                agree[which] += (keep & moved & mask_b).sum(dim=(1, 2)).to(agree)
                either[which] += (keep & (moved | mask_b)).sum(dim=(1, 2)).to(agree)
    score = agree / either.clamp(min=1)
    best = torch.nonzero(score >= score.max() - 1e-12, as_tuple=True)[0]
    runs = torch.tensor_split(best, (torch.nonzero(best.diff() > 1, as_tuple=True)[0] + 1).cpu())
    longest = max(runs, key=len)
    return float(candidates[longest].mean())


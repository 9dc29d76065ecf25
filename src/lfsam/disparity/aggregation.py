"""Cost aggregation of the default disparity estimator: colour-guided filtering over a square
window and two line windows, the best window per pixel (docs/design.md section 3.2).

A square aggregation window assumes a fronto-parallel surface: on a surface slanted in depth it
averages cost curves whose minima lie at different disparities, which flattens the bottom of
the aggregated curve, and where it is flat the winner is decided by noise (the floor of HCI
antinous, whose disparity changes by 0.06 px per row, held 58 % of that scene's BadPix(0.07)
errors with a 7 x 7 window). Along a line of constant disparity (on a plane, a straight line)
the minima agree (a strip 3 pixels wide, not 1, keeps some robustness to noise). So every cost
slice is filtered three times, each time by the colour guided filter
(:class:`lfsam.disparity.filters.ColourGuidedFilter`, the reference view as guide, so that no
window crosses a colour edge: cost-volume filtering, Hosni et al., TPAMI 2013):

- over a ``(2 r + 1)^2`` square (``r = square_radius``),
- over a horizontal and a vertical strip of ``2 l + 1`` by 3 pixels (``l = line_radius``),

and every pixel keeps the volume whose lowest cost, averaged over a 5 x 5 neighbourhood so that
the choice is locally coherent, is the smallest; a line window has to be better by ``line_bias``
(in cost units), as the minimum over more candidates is biased low by noise. This is the
adaptive-window idea (Kanade & Okutomi, "A stereo matching algorithm with an adaptive window",
TPAMI 1994; Veksler, "Fast variable window for stereo correspondence using integral images",
CVPR 2003) reduced to three windows that filtering makes cheap.

At the frame's border a window averages only the pixels inside the frame (``border="shrink"``,
the normalised box filter of He et al.). Replicating the border instead (before issue 45's
second round) gave the outermost row or column up to ``(r + 1) / (2 r + 1)`` of a border pixel's
window, although its costs are the least reliable (fewer views see it): BadPix(0.07) over all
pixels went from 6.81 to 6.78 % on HCI antinous and from 2.49 to 2.35 % on cotton with the
shrinking windows (docs/performance.md, "Disparity", second round).
"""

from __future__ import annotations

import torch

from lfsam.disparity.filters import ColourGuidedFilter, box_blur, slice_chunks

__all__ = ["aggregate_costs"]


def aggregate_costs(
    cost: torch.Tensor,
    guide: torch.Tensor,
    *,
    square_radius: int = 4,
    line_radius: int = 8,
    eps: float = 1e-4,
    line_bias: float = 0.01,
    choice_radius: int = 2,
    border: str = "shrink",
) -> torch.Tensor:
    """The aggregated cost volume (module docstring).

    Parameters
    ----------
    cost : torch.Tensor, shape (D, U, V)
        Matching costs (lower = better), e.g. :func:`lfsam.disparity.cost_volume.build_cost_volume`.
    guide : torch.Tensor, shape (3, U, V) or (U, V)
        The reference view, RGB (or gray) in [0, 1].
    square_radius : int
        Radius of the square window.
    line_radius : int
        Half length of the strip windows (0: the square window only).
    eps : float
        Regulariser of the guided filter.
    line_bias : float
        How much lower a line window's best cost must be to be chosen (cost units).
    choice_radius : int
        Radius of the box over which the windows' best costs are compared.
    border : {"shrink", "replicate"}
        Windows at the frame's border: ``"shrink"`` (default since issue 45's second round)
        averages over the window's pixels inside the frame; ``"replicate"`` repeats the outermost
        row or column, which then weighs up to ``(r + 1) / (2 r + 1)`` of the window along that
        axis (:func:`lfsam.disparity.filters.box_blur_rect`; module docstring).

    Returns
    -------
    torch.Tensor, shape (D, U, V)
    """
    if guide.dim() == 2:
        guide = guide[None].expand(3, -1, -1)
    windows = [(square_radius, square_radius)]
    if line_radius > 0:
        windows += [(1, line_radius), (line_radius, 1)]
    filters = [ColourGuidedFilter(guide, window, eps, border) for window in windows]
    filtered = [torch.empty_like(cost) for _ in windows]
    for chunk in slice_chunks(cost.shape[0], cost[0].numel()):
        part = cost[chunk]
        products = filters[0].products(part)
        for guided, out in zip(filters, filtered, strict=True):
            out[chunk] = guided.apply(part, products)
    best = filtered[0]
    if line_radius <= 0:
        return best
    best_score = box_blur(best.amin(0), choice_radius)
    for line in filtered[1:]:
        score = box_blur(line.amin(0), choice_radius) + line_bias
        better = score < best_score
        best = torch.where(better[None], line, best)
        best_score = torch.where(better, score, best_score)
    return best

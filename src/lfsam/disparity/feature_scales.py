"""Two scales of matching features: the wider one away from edges (docs/design.md section 3.2).

The cost volume compares locally normalised intensities ``(g - mean_w) / (std_w + eps)``
(:func:`lfsam.disparity.cost_volume.matching_features`). A wider window ``w`` (5 x 5 instead of
3 x 3) gives features that are less noisy on dark, weakly textured surfaces (the floor of HCI
antinous, whose renders are noisy), but where the window straddles an edge between a bright
object and a dark background the features of the background pixels are dominated by the edge,
which moves with the object: the object's disparity then spreads over a wider band of the
background. Measured on HCI antinous (issue 45, third round; BadPix(0.07) over all pixels): the
5 x 5 features alone 5.88 % against 6.78 %, better away from depth edges (3.19 against 4.61 %
of those pixels) and worse within 5 px of them (29.9 against 26.2 %); on cotton 2.61 against
2.35 %. So the estimator runs both and keeps the 3 x 3 features' result near edges:

- within ``edge_radius`` pixels of a strong intensity edge of the reference view (the
  differences of its two neighbours along rows and along columns, their length above
  ``colour_edge``), where the wider window straddles the edge, and
- within ``edge_radius`` pixels of a depth jump of the 3 x 3 result (disparity spread over a
  ``(2 edge_radius + 1)^2`` window above ``depth_jump`` px per view step), where the two surfaces'
  features meet even without a visible edge,

and the 5 x 5 features' result everywhere else.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

__all__ = ["fine_scale_mask"]


def _dilate(mask: torch.Tensor, radius: int) -> torch.Tensor:
    """Binary dilation of a (U, V) mask by a ``(2 radius + 1)^2`` square."""
    if radius <= 0:
        return mask
    grown = F.max_pool2d(mask[None, None].float(), 2 * radius + 1, stride=1, padding=radius)
    return grown[0, 0] > 0.5


def fine_scale_mask(
    gray: torch.Tensor,
    disparity: torch.Tensor,
    *,
    colour_edge: float = 0.06,
    depth_jump: float = 1.0,
    edge_radius: int = 4,
) -> torch.Tensor:
    """The pixels that keep the fine (3 x 3) features' disparity (module docstring).

    Parameters
    ----------
    gray : torch.Tensor, shape (U, V)
        The reference view in gray levels, [0, 1].
    disparity : torch.Tensor, shape (U, V)
        The disparity estimated with the fine features (pixels per view step).
    colour_edge : float
        Length of the central differences ``(g(u+1, v) - g(u-1, v), g(u, v+1) - g(u, v-1))``
        (gray levels in [0, 1]) at a strong edge.
    depth_jump : float
        Disparity spread within the window that marks a depth jump.
    edge_radius : int
        How far from an edge or a jump the fine features are kept (pixels).

    Returns
    -------
    torch.Tensor, shape (U, V), bool
        True where the fine features' result is kept.
    """
    padded = F.pad(gray[None, None], (1, 1, 1, 1), mode="replicate")[0, 0]
    across_u = padded[2:, 1:-1] - padded[:-2, 1:-1]
    across_v = padded[1:-1, 2:] - padded[1:-1, :-2]
    edges = torch.hypot(across_u, across_v) > colour_edge
    size = 2 * edge_radius + 1
    high = F.max_pool2d(disparity[None, None], size, stride=1, padding=edge_radius)[0, 0]
    low = -F.max_pool2d(-disparity[None, None], size, stride=1, padding=edge_radius)[0, 0]
    return _dilate(edges, edge_radius) | (high - low > depth_jump)

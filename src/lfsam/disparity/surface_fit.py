"""A robust local surface fit of the disparity away from edges (docs/design.md section 3.2).

On a dark, weakly textured surface slanted in depth (the floor of HCI antinous: a noisy render,
0.06 px per view step more disparity per row) the cost volume's winner wanders by 0.07-0.2 px
from pixel to pixel, in horizontal streaks of both signs, while the surface itself is smooth.
Filling unsure pixels with constant values from their neighbours, or fitting planes over every
pixel, failed there before (docs/performance.md): a constant is wrong on a slant, and a window
that reaches across a depth edge or over a curved surface bends the fit. This step fits, per
pixel ``p``, a **quadratic** surface

    d(p + (du, dv)) ~ c0 + c1 x + c2 y + c3 x^2 + c4 x y + c5 y^2,   x = du / r, y = dv / r,

by weighted least squares over a ``(2 r + 1)^2`` window, and replaces ``d(p)`` by ``c0``, its
value at the centre. A quadratic keeps slants and curvature (a plane biased the curved surfaces
of HCI cotton: BadPix(0.07) over all pixels 2.33 -> 2.5-2.8 %). Each neighbour ``q`` is weighted
by

- ``mask(q)``: only pixels away from intensity edges and depth jumps take part (the wide
  feature scale's pixels of :mod:`lfsam.disparity.feature_scales`; the fit replaces only those),
- ``exp(-|I(q) - I(p)|^2 / (2 colour_sigma^2))``: the reference's colour, so that a window does
  not mix two surfaces of different colour (a bilateral weight, as the aggregation's guided
  filter),
- ``exp(-(d(q) - P_p(q))^2 / (2 range_sigma^2))``: the distance of ``d(q)`` from a first,
  unweighted plane ``P_p`` fitted over the same window, so that outliers and a second surface
  of the same colour count little (one step of iteratively reweighted least squares; the plane
  carries the slant, so the weight does not punish a slanted surface as a weight on
  ``d(q) - d(p)`` would).

A pixel whose window holds less than ``min_support`` of its area in weight keeps its value.
The result is a slant-aware smoothing whose support follows colour and depth: on a noisy
slanted surface the fitted centre averages the noise of about a hundred pixels, and on a
curved or textured one the quadratic follows the shape.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from lfsam.disparity.filters import BAND_ELEMENTS

__all__ = ["fit_surface"]

# The monomials x^i y^j (i + j <= 4) that the normal equations of a quadratic need, and where
# each entry of the 6 x 6 Gram matrix and of the right-hand side finds its moment.
_BASIS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
_MOMENTS = tuple(sorted({(a[0] + b[0], a[1] + b[1]) for a in _BASIS for b in _BASIS}))


def _plane_prefit(
    disparity: torch.Tensor, mask: torch.Tensor, radius: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The unweighted least-squares plane over each pixel's window (masked pixels only): its
    value at the pixel and its slopes along rows and columns (box-filtered moments)."""
    rows, cols = disparity.shape
    d = disparity.double()
    w = mask.double()
    u = torch.arange(rows, dtype=torch.float64, device=d.device)[:, None].expand(rows, cols)
    v = torch.arange(cols, dtype=torch.float64, device=d.device)[None, :].expand(rows, cols)
    size = 2 * radius + 1
    stack = torch.stack([w, w * u, w * v, w * u * u, w * u * v, w * v * v, w * d, w * u * d,
                         w * v * d])
    sums = F.avg_pool2d(stack[None], size, stride=1, padding=radius, count_include_pad=True)[0]
    total = sums[0].clamp(min=1e-12)
    mean_u, mean_v, mean_d = sums[1] / total, sums[2] / total, sums[6] / total
    c_uu = sums[3] / total - mean_u * mean_u + 1e-3
    c_uv = sums[4] / total - mean_u * mean_v
    c_vv = sums[5] / total - mean_v * mean_v + 1e-3
    c_ud = sums[7] / total - mean_u * mean_d
    c_vd = sums[8] / total - mean_v * mean_d
    det = c_uu * c_vv - c_uv * c_uv
    slope_u = (c_vv * c_ud - c_uv * c_vd) / det
    slope_v = (c_uu * c_vd - c_uv * c_ud) / det
    value = mean_d + slope_u * (u - mean_u) + slope_v * (v - mean_v)
    return value.float(), slope_u.float(), slope_v.float()


def fit_surface(
    disparity: torch.Tensor,
    mask: torch.Tensor,
    guide: torch.Tensor,
    *,
    radius: int = 7,
    colour_sigma: float = 0.02,
    range_sigma: float = 0.04,
    regulariser: float = 1e-4,
    min_support: float = 0.2,
) -> torch.Tensor:
    """The disparity with the masked pixels replaced by their robust local quadratic fit.

    Parameters
    ----------
    disparity : torch.Tensor, shape (U, V)
        Pixels per view step.
    mask : torch.Tensor, shape (U, V), bool
        The pixels that take part in the fits and that are replaced (away from edges and depth
        jumps; module docstring).
    guide : torch.Tensor, shape (3, U, V) or (U, V)
        The reference view, RGB or gray, in [0, 1].
    radius : int
        Window radius ``r`` (pixels).
    colour_sigma : float
        Scale of the colour weight (Euclidean distance of RGB in [0, 1]).
    range_sigma : float
        Scale of the weight on the distance from the first plane (pixels per view step).
    regulariser : float
        Ridge on the five non-constant coefficients, relative to the window's weight.
    min_support : float
        Fewest weight, as a share of the window's area, for a pixel to be replaced.

    Returns
    -------
    torch.Tensor, shape (U, V), the input's dtype
    """
    if radius <= 0 or not mask.any():
        return disparity
    if guide.dim() == 2:
        guide = guide[None]
    rows, cols = disparity.shape
    d = disparity.float()
    keep = mask.float()
    level, slope_u, slope_v = _plane_prefit(d, mask, radius)
    r = radius
    padded = F.pad(torch.cat([d[None], keep[None], guide.float()])[None], (r, r, r, r))[0]
    moments = torch.empty(len(_MOMENTS), rows, cols, device=d.device)
    rhs = torch.empty(len(_BASIS), rows, cols, device=d.device)
    # a band of rows at a time: its maps then stay in a CPU's cache
    band = max(1, BAND_ELEMENTS // max(cols, 1))
    for first in range(0, rows, band):
        last = min(first + band, rows)
        moments[:, first:last], rhs[:, first:last] = _window_moments(
            padded[:, first : last + 2 * r], guide[:, first:last], level[first:last],
            slope_u[first:last], slope_v[first:last], r, colour_sigma, range_sigma,
        )
    index = {m: k for k, m in enumerate(_MOMENTS)}
    gram = torch.stack(
        [torch.stack([moments[index[(a[0] + b[0], a[1] + b[1])]] for b in _BASIS], -1)
         for a in _BASIS], -2
    ).double()
    total = moments[index[(0, 0)]].double()
    ridge = torch.tensor([0.0, 1, 1, 1, 1, 1], dtype=torch.float64, device=d.device)
    gram = gram + torch.diag_embed(ridge * regulariser * total.clamp(min=1e-9)[..., None])
    gram[..., 0, 0] += 1e-9
    coefficients = torch.linalg.solve(gram, rhs.permute(1, 2, 0).double()[..., None])[..., 0]
    centre = coefficients[..., 0].float()
    supported = total.float() > min_support * (2 * r + 1) ** 2
    return torch.where(mask & supported, centre, d).to(disparity.dtype)



def _window_moments(
    padded: torch.Tensor,
    guide: torch.Tensor,
    level: torch.Tensor,
    slope_u: torch.Tensor,
    slope_v: torch.Tensor,
    r: int,
    colour_sigma: float,
    range_sigma: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The weighted moments ``sum w x^i y^j`` (:data:`_MOMENTS`) and right-hand sides
    ``sum w d x^i y^j`` (:data:`_BASIS`) of a band of rows: ``padded`` holds the band's
    disparity, mask and guide with ``r`` more rows and columns on each side.

    The sums over a window row (fixed ``du``) are gathered first as ``sum w y^j`` and
    ``sum w d y^j``; each window row then adds them times ``x^i`` (``x = du / r``), so the work
    per window position is the weight and eight accumulations.
    """
    rows, cols = level.shape
    moments = torch.zeros(len(_MOMENTS), rows, cols, device=level.device)
    rhs = torch.zeros(len(_BASIS), rows, cols, device=level.device)
    colour_scale = -0.5 / colour_sigma**2
    range_scale = -0.5 / range_sigma**2
    for du in range(-r, r + 1):
        plane_at_row = level + slope_u * du
        weight_sums = torch.zeros(5, rows, cols, device=level.device)  # sum w y^j, j = 0..4
        value_sums = torch.zeros(3, rows, cols, device=level.device)  # sum w d y^j, j = 0..2
        for dv in range(-r, r + 1):
            window = padded[:, r + du : r + du + rows, r + dv : r + dv + cols]
            value, keep, colour = window[0], window[1], window[2:]
            difference = colour[0] - guide[0]
            exponent = difference * difference
            for channel in range(1, guide.shape[0]):
                difference = colour[channel] - guide[channel]
                exponent.addcmul_(difference, difference)
            off = (value - plane_at_row).sub_(slope_v, alpha=dv)
            exponent.mul_(colour_scale).addcmul_(off, off, value=range_scale)
            weight = exponent.exp_().mul_(keep)
            weighted_value = weight * value
            y = dv / r
            for j in range(5):
                weight_sums[j].add_(weight, alpha=y**j)
            for j in range(3):
                value_sums[j].add_(weighted_value, alpha=y**j)
        x = du / r
        for k, (i, j) in enumerate(_MOMENTS):
            moments[k].add_(weight_sums[j], alpha=x**i)
        for k, (i, j) in enumerate(_BASIS):
            rhs[k].add_(value_sums[j], alpha=x**i)
    return moments, rhs

"""Edge-aware refinement of a disparity map (optional last step of the disparity estimator).

The local estimator (:mod:`lfsam.disparity.structure_tensor`) decides every pixel from a small
window, so it is noisy where the views have little texture (a dark wall) and wrong in thin bands
at occlusion edges. Both are repaired by averaging each pixel with neighbours that are likely to
lie on the same surface: close in the image plane, similar in colour in the center view, and
trusted by the estimator (confidence). This is the *joint* (cross) bilateral filter (Petschnigg
et al., "Digital photography with flash and no-flash image pairs", SIGGRAPH 2004; Kopf et al.,
"Joint bilateral upsampling", SIGGRAPH 2007) with confidence weights, as used for depth maps by
Yang et al. ("Spatial-depth super resolution for range images", CVPR 2007), in two passes:

1. *Robust reference.* Each pixel's value is the weighted mean of its window with weights
   ``spatial x colour x confidence``. Isolated gross errors (a wrong candidate, a fattened
   edge) have few similar-coloured, confident neighbours agreeing with them and are voted away.
2. *Surface-preserving denoising.* The window is averaged again, now also weighting each
   neighbour by how close its disparity is to the pass-1 reference of the pixel
   (``exp(-(d_q - ref_p)^2 / 2 sigma_d^2)``): neighbours across a depth edge of the same colour
   (which pass 1 mixed in) drop out, so sub-pixel detail survives while noise averages down.
   Using the reference instead of the pixel's own noisy value is one step of a robust
   (mean-shift) estimate started from pass 1.

Measured on the disparity benchmark (``benchmarks/bench_disparity.py``): it lowers BadPix(0.07)
on HCI antinous and the MSE on the +-3 px scene; the numbers with and without it are printed
there.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from lfsam.disparity.filters import BAND_ELEMENTS

__all__ = ["joint_bilateral_filter", "refine_disparity"]

# Added to the squared confidence so that a window of zero-confidence pixels still has a mean.
_CONFIDENCE_FLOOR = 1e-4


def joint_bilateral_filter(
    disparity: torch.Tensor,
    weight: torch.Tensor,
    image: torch.Tensor,
    *,
    radius: int,
    spatial_sigma: float,
    color_sigma: float,
    disparity_sigma: float | None = None,
    reference: torch.Tensor | None = None,
) -> torch.Tensor:
    """Weighted mean of ``disparity`` over a window, steered by a guide image.

    ``out_p = sum_q w_pq d_q / sum_q w_pq`` over ``|q - p|_inf <= radius`` with

        w_pq = exp(-|q - p|^2 / 2 s^2) exp(-|I_q - I_p|^2 / 2 c^2) weight_q
               [exp(-(d_q - ref_p)^2 / 2 sigma_d^2)]

    (the last factor only with ``disparity_sigma``; ``ref`` defaults to ``disparity``). Borders
    are replicated. The loop runs over the ``(2 radius + 1)^2`` window offsets, each a whole-image
    tensor operation.

    Parameters
    ----------
    disparity : torch.Tensor, shape (U, V)
        Values to filter.
    weight : torch.Tensor, shape (U, V)
        Non-negative per-pixel trust of each value.
    image : torch.Tensor, shape (C, U, V)
        Guide image (intensities in [0, 1]).
    radius : int
        Window radius in pixels.
    spatial_sigma, color_sigma : float
        Standard deviations of the spatial (pixels) and colour (intensity) kernels.
    disparity_sigma : float, optional
        Standard deviation of the disparity kernel (pixels per view step).
    reference : torch.Tensor, shape (U, V), optional
        The value each pixel's neighbours are compared with in the disparity kernel.

    Returns
    -------
    torch.Tensor, shape (U, V)
    """
    rows, cols = disparity.shape
    pad = (radius, radius, radius, radius)
    padded = F.pad(
        torch.cat([disparity[None], weight[None], image]).unsqueeze(0), pad, mode="replicate"
    )[0]
    reference = disparity if reference is None else reference
    out = torch.empty_like(disparity)
    # a band of rows at a time: its intermediates stay in a CPU's cache
    band = max(1, BAND_ELEMENTS // max(cols, 1))
    for first in range(0, rows, band):
        last = min(first + band, rows)
        out[first:last] = _filter_band(
            padded[:, first : last + 2 * radius], image[:, first:last], reference[first:last],
            radius, spatial_sigma, color_sigma, disparity_sigma,
        )
    return out



def _filter_band(
    padded: torch.Tensor,
    image: torch.Tensor,
    reference: torch.Tensor,
    radius: int,
    spatial_sigma: float,
    color_sigma: float,
    disparity_sigma: float | None,
) -> torch.Tensor:
    """:func:`joint_bilateral_filter` for a band of rows: ``padded`` holds the band's rows with
    ``radius`` more on each side (disparity, weight and guide), ``image`` and ``reference`` the
    band's own."""
    rows, cols = reference.shape
    numerator = torch.zeros_like(reference)
    denominator = torch.zeros_like(reference)
    color_scale = -0.5 / (color_sigma * color_sigma)
    for du in range(-radius, radius + 1):
        for dv in range(-radius, radius + 1):
            spatial = math.exp(-0.5 * (du * du + dv * dv) / (spatial_sigma * spatial_sigma))
            window = padded[:, radius + du : radius + du + rows, radius + dv : radius + dv + cols]
            d_q, w_q, i_q = window[0], window[1], window[2:]
            exponent = ((i_q - image) ** 2).sum(0) * color_scale
            if disparity_sigma is not None:
                exponent = exponent - 0.5 * ((d_q - reference) / disparity_sigma) ** 2
            w = torch.exp(exponent) * w_q * spatial
            numerator += w * d_q
            denominator += w
    return numerator / denominator.clamp(min=1e-30)


def refine_disparity(
    disparity: torch.Tensor,
    confidence: torch.Tensor,
    image: torch.Tensor,
    *,
    radius: int = 8,
    spatial_sigma: float = 5.0,
    color_sigma: float = 0.05,
    disparity_sigma: float = 0.3,
) -> torch.Tensor:
    """Two-pass confidence-weighted joint bilateral refinement (module docstring).

    Parameters
    ----------
    disparity : torch.Tensor, shape (U, V)
        The local estimate.
    confidence : torch.Tensor, shape (U, V), in [0, 1]
        Its confidence (structure-tensor coherence); neighbours are weighted by its square.
    image : torch.Tensor, shape (C, U, V)
        The center view, intensities in [0, 1].
    radius : int
        Window radius in pixels.
    spatial_sigma : float
        Spatial kernel standard deviation in pixels.
    color_sigma : float
        Colour kernel standard deviation (intensity, per channel summed in the squared distance).
    disparity_sigma : float
        Disparity kernel standard deviation of pass 2 (pixels per view step).

    Returns
    -------
    torch.Tensor, shape (U, V)
        The refined disparity.
    """
    weight = confidence * confidence + _CONFIDENCE_FLOOR
    options = {"radius": radius, "spatial_sigma": spatial_sigma, "color_sigma": color_sigma}
    reference = joint_bilateral_filter(disparity, weight, image, **options)
    return joint_bilateral_filter(
        disparity, weight, image, disparity_sigma=disparity_sigma, reference=reference, **options
    )

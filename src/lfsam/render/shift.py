"""Batched sub-pixel shift-and-add with ray-count normalisation (docs/design.md section 13).

The one sampling primitive of :mod:`lfsam.render`: every view is translated by its own constant
sub-pixel shift (bilinear, exact for whole-pixel shifts), weighted by a per-ray *keep* weight
(1 = the ray counts, 0 = left out, e.g. it hits an object), and the weighted colours and the
weights are summed over the views. Rays that land outside a view contribute neither colour nor
weight (zero padding, no wrap), so dividing by the summed weight normalises every pixel by the
rays that landed: no dark rim at the borders (Ng 2005; Vaish et al. 2004, 2006).

Torch inside, any device; one view at a time is added into one accumulator.
"""

from __future__ import annotations

import math

import torch

__all__ = ["shift_and_add", "translate"]

def _add_shifted(out: torch.Tensor, image: torch.Tensor, du: float, dv: float) -> None:
    """``out += image`` sampled at ``(u + du, v + dv)``, bilinear, zero outside (in place).

    Four whole-pixel slices, each added with its bilinear weight (``Tensor.add_`` with
    ``alpha``): no padded copy, exact for whole-pixel shifts.
    """
    height, width = image.shape[-2:]
    iu, iv = math.floor(du), math.floor(dv)
    a, b = du - iu, dv - iv
    for oy, wy in ((0, 1.0 - a), (1, a)):
        for ox, wx in ((0, 1.0 - b), (1, b)):
            weight = wy * wx
            ru, rv = iu + oy, iv + ox  # out[u, v] += weight * image[u + ru, v + rv]
            if weight == 0.0 or abs(ru) >= height or abs(rv) >= width:
                continue
            u0, u1 = max(0, -ru), min(height, height - ru)
            v0, v1 = max(0, -rv), min(width, width - rv)
            out[..., u0:u1, v0:v1].add_(
                image[..., u0 + ru:u1 + ru, v0 + rv:v1 + rv], alpha=weight
            )


def translate(images: torch.Tensor, du: torch.Tensor, dv: torch.Tensor) -> torch.Tensor:
    """Sample ``images[n]`` at ``(u + du[n], v + dv[n])``, bilinear, zero outside.

    Parameters
    ----------
    images : (N, C, U, V) float tensor
    du, dv : (N,) float tensors
        Shift of each image's sampling position, pixels (rows, columns).

    Returns
    -------
    (N, C, U, V) float tensor
        Whole-pixel shifts reproduce the pixels exactly (the bilinear weights are 1 and 0).

    Examples
    --------
    >>> import torch
    >>> x = torch.arange(6.0).reshape(1, 1, 2, 3)
    >>> translate(x, torch.tensor([0.0]), torch.tensor([1.0]))[0, 0].tolist()
    [[1.0, 2.0, 0.0], [4.0, 5.0, 0.0]]
    """
    out = torch.zeros_like(images)
    for k in range(images.shape[0]):
        _add_shifted(out[k], images[k], float(du[k]), float(dv[k]))
    return out


def shift_and_add(
    images: torch.Tensor,
    offsets: torch.Tensor,
    focus: float,
    keep: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Shift every view to focus at disparity ``focus`` and add, counting the rays that land.

    A center-view pixel ``(u, v)`` on the plane of disparity ``focus`` is seen in the view at
    offset ``(ds, dt)`` at ``(u - focus ds, v - focus dt)`` (docs/design.md section 1); each
    view is sampled there.

    Parameters
    ----------
    images : (N, C, U, V) float tensor
        The views (any channels).
    offsets : (N, 2) tensor
        ``(ds, dt)`` of each view from the reference view.
    focus : float
        Disparity of the focal plane, pixels per view step.
    keep : (N, U, V) float tensor, optional
        Weight of each ray in [0, 1] (0 = leave it out); default every ray 1.

    Returns
    -------
    total : (C, U, V) float tensor
        Sum over the views of ``keep * image`` at the shifted positions.
    weight : (U, V) float tensor
        Sum of the landed keep weights (the number of rays where every ray is kept); the
        refocused image is ``total / weight`` where ``weight > 0``.
    """
    n, channels, height, width = images.shape
    acc = images.new_zeros((channels + 1, height, width))
    offsets = torch.as_tensor(offsets, dtype=torch.float64).cpu()
    for k in range(n):
        if keep is None:
            stacked = torch.cat([images[k], images.new_ones((1, height, width))])
        else:
            w = keep[k].to(images.dtype)
            stacked = torch.cat([images[k] * w, w[None]])
        ds, dt = float(offsets[k, 0]), float(offsets[k, 1])
        _add_shifted(acc, stacked, -focus * ds, -focus * dt)
    return acc[:channels], acc[channels]

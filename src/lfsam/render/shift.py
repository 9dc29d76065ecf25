"""Batched sub-pixel shift-and-add with ray-count normalisation (docs/design.md section 13).

The one sampling primitive of :mod:`lfsam.render`: every view is translated by its own constant
sub-pixel shift (bilinear, or Lanczos-3 for refocusing; exact for whole-pixel shifts;
separable, each grid row's views summed before their common vertical shift), weighted by a per-
ray *keep* weight (1 = the ray counts, 0 = left out, e.g. it hits an object), and the weighted
colours and the weights are summed over the views. Rays that land outside a view contribute
neither colour nor weight (zero padding, no wrap), so dividing by the summed weight normalises
every pixel by the rays that landed: no dark rim at the borders (Ng 2005; Vaish et al. 2004,
2006).

Torch inside, any device; one view at a time is added into one accumulator per grid row.
"""

from __future__ import annotations

import math

import torch

__all__ = ["KERNELS", "kernel_taps", "shift_and_add", "translate"]

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
    rows = torch.zeros_like(images[0])
    for k in range(images.shape[0]):  # bilinear is separable: along the rows, then the columns
        rows.zero_()
        _add_along(rows, images[k], float(dv[k]), "linear", -1)
        _add_along(out[k], rows, float(du[k]), "linear", -2)
    return out


def _tent(x: float) -> float:
    return max(0.0, 1.0 - abs(x))


def _lanczos3(x: float) -> float:
    if abs(x) < 1e-6:  # sin(px) sin(px / 3) / (px^2 / 3) -> 1 (no underflow to 0 / 0)
        return 1.0
    if abs(x) >= 3.0:
        return 0.0
    px = math.pi * x
    return 3.0 * math.sin(px) * math.sin(px / 3.0) / (px * px)


#: Interpolation kernels of :func:`shift_and_add`: name -> (radius in pixels, kernel).
KERNELS = {"linear": (1, _tent), "lanczos3": (3, _lanczos3)}


def kernel_taps(shift: float, kernel: str) -> list[tuple[int, float]]:
    """Whole-pixel offsets and weights that sample a row at ``x + shift`` with ``kernel``.

    The weights sum to 1 (a constant stays constant); a whole-pixel shift is one tap of
    weight 1 (the pixels exactly), whatever the kernel.

    Examples
    --------
    >>> kernel_taps(2.0, "lanczos3")
    [(2, 1.0)]
    >>> [(o, round(w, 2)) for o, w in kernel_taps(0.25, "linear")]
    [(0, 0.75), (1, 0.25)]
    """
    radius, function = KERNELS[kernel]
    whole = math.floor(shift)
    fraction = shift - whole
    if fraction == 0.0:
        return [(whole, 1.0)]
    taps = [(whole + k, function(fraction - k)) for k in range(1 - radius, radius + 1)]
    taps = [(offset, weight) for offset, weight in taps if weight != 0.0]
    total = sum(weight for _, weight in taps)
    return [(offset, weight / total) for offset, weight in taps]


def _add_along(out: torch.Tensor, image: torch.Tensor, shift: float, kernel: str,
               axis: int) -> None:
    """``out += image`` sampled at ``x + shift`` along ``axis`` (-2 rows, -1 columns), zero
    outside (in place)."""
    length = image.shape[axis]
    for offset, weight in kernel_taps(shift, kernel):
        if abs(offset) >= length:
            continue
        lo, hi = max(0, -offset), min(length, length - offset)
        out.narrow(axis, lo, hi - lo).add_(image.narrow(axis, lo + offset, hi - lo), alpha=weight)


def shift_and_add(
    images: torch.Tensor,
    offsets: torch.Tensor,
    focus: float,
    keep: torch.Tensor | None = None,
    *,
    kernel: str = "linear",
) -> tuple[torch.Tensor, torch.Tensor]:
    """Shift every view to focus at disparity ``focus`` and add, counting the rays that land.

    A center-view pixel ``(u, v)`` on the plane of disparity ``focus`` is seen in the view at
    offset ``(ds, dt)`` at ``(u - focus ds, v - focus dt)`` (docs/design.md section 1); each
    view is sampled there with a separable kernel: each view is shifted along its rows, the
    views of one grid row (the same ``ds``, so the same vertical shift) are added, and each
    such sum is shifted along its columns once (a shift is linear: the same sum, in fewer
    passes).

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
    kernel : {"linear", "lanczos3"}
        Interpolation: bilinear (a ray counts from its four neighbours; what the keep weights
        of see-through and removal mean), or Lanczos-3 (six taps a side: sharp textures stay
        sharp when refocused, docs/design.md section 13). Whole-pixel shifts are exact with
        either.

    Returns
    -------
    total : (C, U, V) float tensor
        Sum over the views of ``keep * image`` at the shifted positions.
    weight : (U, V) float tensor
        Sum of the landed keep weights (the number of rays where every ray is kept); the
        refocused image is ``total / weight`` where ``weight > 0``.

    Raises
    ------
    ValueError
        For a ``kernel`` not in :data:`KERNELS` (the caller's code is at fault).
    """
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {sorted(KERNELS)}, got {kernel!r}")
    n, channels, height, width = images.shape
    acc = images.new_zeros((channels + 1, height, width))
    offsets = torch.as_tensor(offsets, dtype=torch.float64).cpu()
    rows: dict[float, list[int]] = {}
    for k in range(n):
        rows.setdefault(float(offsets[k, 0]), []).append(k)
    row_sum = images.new_empty((channels + 1, height, width))
    for ds, members in rows.items():
        row_sum.zero_()
        for k in members:
            if keep is None:
                stacked = torch.cat([images[k], images.new_ones((1, height, width))])
            else:
                w = keep[k].to(images.dtype)
                stacked = torch.cat([images[k] * w, w[None]])
            _add_along(row_sum, stacked, -focus * float(offsets[k, 1]), kernel, -1)
        _add_along(acc, row_sum, -focus * ds, kernel, -2)
    return acc[:channels], acc[channels]

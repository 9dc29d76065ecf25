"""Whole masks translated instead of warped pixel by pixel (:mod:`lfsam.warp`): each mask moved
by one sub-pixel shift (:func:`shift_masks`, the ``--propagation mean|median`` alternative to the
forward warp), optionally carrying its own disparity along (:func:`shift_masks_with_disparity`),
and one plane translated by whole pixels, exactly (:func:`shift_whole_pixels`).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

__all__ = ["shift_masks", "shift_masks_with_disparity", "shift_whole_pixels"]


def _shift(planes: torch.Tensor, shifts_uv: torch.Tensor) -> torch.Tensor:
    """Bilinear translation of ``(N, C, U, V)`` float planes, each of the N by its own shift."""
    n, _, height, width = planes.shape
    rows = torch.arange(height, device=planes.device, dtype=torch.float32)
    cols = torch.arange(width, device=planes.device, dtype=torch.float32)
    src_u = rows[None, :, None] - shifts_uv[:, 0, None, None]
    src_v = cols[None, None, :] - shifts_uv[:, 1, None, None]
    grid = torch.stack(
        [
            (2.0 * src_v / max(width - 1, 1) - 1.0).expand(n, height, width),
            (2.0 * src_u / max(height - 1, 1) - 1.0).expand(n, height, width),
        ],
        dim=-1,
    )
    return F.grid_sample(
        planes, grid, mode="bilinear", align_corners=True, padding_mode="zeros"
    )


def shift_masks(masks: torch.Tensor, shifts_uv: torch.Tensor) -> torch.Tensor:
    """Translate each mask by its own sub-pixel shift (bilinear resampling, threshold 0.5).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    shifts_uv : (N, 2) float tensor
        Row and column shift of each mask: output pixel ``(u, v)`` takes input ``(u - du, v - dv)``.

    Returns
    -------
    (N, U, V) bool tensor

    Examples
    --------
    >>> import torch
    >>> mask = torch.tensor([[[True, False, False, False]]])
    >>> shift_masks(mask, torch.tensor([[0.0, 2.0]])).int().tolist()
    [[[0, 0, 1, 0]]]
    """
    if masks.shape[0] == 0:
        return masks
    return _shift(masks[:, None].to(torch.float32), shifts_uv)[:, 0] >= 0.5


def shift_masks_with_disparity(
    masks: torch.Tensor, disparity: torch.Tensor, shifts_uv: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`shift_masks`, carrying each mask's own disparity along.

    The disparity a shifted mask shows at a target pixel is the bilinear average of the source
    disparity over the mask's own pixels around the point it came from (the same weights as the
    mask), so a slanted surface keeps its slant and nothing outside the mask leaks in.

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    disparity : (U, V) float tensor
        Source-view disparity.
    shifts_uv : (N, 2) float tensor
        As in :func:`shift_masks`.

    Returns
    -------
    shifted : (N, U, V) bool tensor
        Equal to ``shift_masks(masks, shifts_uv)``.
    shifted_disparity : (N, U, V) float tensor
        The mask's disparity at each pixel of ``shifted`` (``-inf`` outside it).
    """
    n, height, width = masks.shape
    if n == 0:
        return masks, torch.empty((0, height, width), device=masks.device)
    weight = masks.to(torch.float32)
    planes = torch.stack([weight, weight * disparity.to(torch.float32)[None]], dim=1)
    sampled = _shift(planes, shifts_uv)
    shifted = sampled[:, 0] >= 0.5
    values = sampled[:, 1] / sampled[:, 0].clamp(min=1e-6)
    return shifted, torch.where(shifted, values, torch.full_like(values, float("-inf")))


def shift_whole_pixels(plane: torch.Tensor, su: int, sv: int) -> torch.Tensor:
    """``plane`` translated by ``(su, sv)`` whole pixels: ``out[u + su, v + sv] = plane[u, v]``
    (the direction of :func:`shift_masks`); what enters from outside the view is zero (False).

    Parameters
    ----------
    plane : (U, V) tensor, any dtype
    su, sv : int
        Row and column shift.

    Returns
    -------
    (U, V) tensor

    Examples
    --------
    >>> import torch
    >>> shift_whole_pixels(torch.tensor([[1, 2, 3, 4]]), 0, -1).tolist()
    [[2, 3, 4, 0]]
    """
    height, width = plane.shape
    out = torch.zeros_like(plane)
    if abs(su) >= height or abs(sv) >= width:
        return out
    out[max(su, 0):height + min(su, 0), max(sv, 0):width + min(sv, 0)] = plane[
        max(-su, 0):height + min(-su, 0), max(-sv, 0):width + min(-sv, 0)
    ]
    return out

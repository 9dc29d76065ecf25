"""Step 2 of the pipeline: disparity propagation of reference-view masks into every view.

Paper section 3.2: a pixel ``(u, v)`` of a reference-view mask with disparity ``d`` moves to
``(u - d ds, v - d dt)`` in the view at offset ``(ds, dt)`` from the reference (convention of
:mod:`lfsam.geometry`; the reference is the center view in the paper, any view here). Two
variants (docs/design.md section 3.3):

* ``"pixel"`` — the paper's equation: every pixel moves by its own disparity (forward warping to
  the nearest pixel, :func:`lfsam.warp.forward_warp`); the gaps forward warping leaves where a
  surface is stretched are filled exactly by looking each gap's source up in the reference
  masks (:func:`lfsam.warp.fill_warp_holes`).
* ``"mean"`` / ``"median"`` — the authors' code: the whole mask moves by one shift, its mean (or
  median) disparity times the view offset, resampled with sub-pixel accuracy
  (:func:`lfsam.warp.shift_masks`).

Geometric occluding (docs/design.md section 3, beyond the paper) is the z-buffer of the same
forward warp; every mask pixel is compared with its own disparity in both variants.

The warp itself lives in :mod:`lfsam.warp`; its names are re-exported here. Everything is batched
over the N masks of a view and runs on the masks' device.
"""

from __future__ import annotations

import torch

from lfsam.errors import LfsamError
from lfsam.warp import (
    ForwardWarp,
    FrameRuns,
    fill_warp_holes,
    forward_warp,
    forward_warps,
    shift_masks,
    shift_masks_with_disparity,
    splat_masks,
)

__all__ = [
    "PROPAGATION_MODES",
    "ForwardWarp",
    "FrameRuns",
    "fill_warp_holes",
    "forward_warp",
    "forward_warps",
    "mask_disparities",
    "propagate_masks",
    "shift_masks",
    "splat_masks",
]

PROPAGATION_MODES = ("pixel", "mean", "median")


def mask_disparities(
    masks: torch.Tensor, disparity: torch.Tensor, statistic: str = "mean"
) -> torch.Tensor:
    """One disparity per mask: the mean or median of the disparity over the mask.

    Returns
    -------
    (N,) float tensor (0 for an empty mask)

    Raises
    ------
    LfsamError
        If ``statistic`` is not ``"mean"`` or ``"median"``.
    """
    n = masks.shape[0]
    flat = masks.reshape(n, -1)
    values = disparity.reshape(-1)
    if statistic == "mean":
        counts = flat.sum(1).clamp(min=1)
        return (flat.to(values.dtype) @ values) / counts
    if statistic == "median":
        filled = torch.where(flat, values[None], torch.full_like(values[None], float("nan")))
        return torch.nan_to_num(torch.nanmedian(filled, dim=1).values, nan=0.0)
    raise LfsamError(f"unknown statistic {statistic!r}; use mean or median")


def propagate_masks(
    masks: torch.Tensor,
    disparity: torch.Tensor,
    ds: float,
    dt: float,
    mode: str = "pixel",
    *,
    warp: ForwardWarp | None = None,
    keep: torch.Tensor | None = None,
    fill_holes: bool = True,
    occlusion_tolerance: float | None = None,
) -> torch.Tensor:
    """Coarse masks of one view: the reference masks moved by disparity (paper section 3.2).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
        Reference-view masks (the center view in the paper; any view works).
    disparity : (U, V) float tensor
        Reference-view disparity, package convention (:mod:`lfsam.geometry`).
    ds, dt : float
        Offset of the target view from the reference view.
    mode : {"pixel", "mean", "median"}
        Per-pixel propagation (the paper's equation) or a whole-mask shift (the authors' code).
    warp : ForwardWarp, optional
        Precomputed :func:`forward_warp` of ``disparity`` for this view, shared with the rest of
        the view's processing (built here when needed and not given).
    keep : (U * V,) bool tensor, optional
        ``"pixel"`` mode only: move only these reference pixels (e.g. those visible in the view).
    fill_holes : bool
        ``"pixel"`` mode only: fill forward-warping gaps (:func:`fill_warp_holes`).
    occlusion_tolerance : float, optional
        Geometric occluding (docs/design.md section 3): drop mask pixels that a reference pixel
        closer by more than this (pixels per view step) covers in the view. ``"pixel"`` mode
        keeps only :meth:`ForwardWarp.visible` pixels (unless ``keep`` is given); the
        whole-mask modes drop the pixels :meth:`ForwardWarp.hides`, each compared with the
        disparity the shifted mask carries there (:func:`shift_masks_with_disparity`). None:
        no geometric occluding.

    Returns
    -------
    coarse : (N, U, V) bool tensor

    Raises
    ------
    LfsamError
        If ``mode`` is not one of :data:`PROPAGATION_MODES`.

    Examples
    --------
    >>> import torch
    >>> mask = torch.zeros((1, 1, 6), dtype=torch.bool)
    >>> mask[0, 0, 1:3] = True
    >>> disparity = torch.full((1, 6), 1.0)
    >>> propagate_masks(mask, disparity, 0, -2).int().tolist()
    [[[0, 0, 0, 1, 1, 0]]]
    """
    if mode not in PROPAGATION_MODES:
        raise LfsamError(
            f"unknown propagation {mode!r}; use one of {', '.join(PROPAGATION_MODES)}"
        )
    if warp is None and (mode == "pixel" or occlusion_tolerance is not None):
        warp = forward_warp(disparity, ds, dt)
    if mode == "pixel":
        if keep is None and occlusion_tolerance is not None:
            keep = warp.visible(disparity, occlusion_tolerance)
        coarse = splat_masks(masks, warp, keep)
        return fill_warp_holes(coarse, masks, warp, keep) if fill_holes else coarse
    d = mask_disparities(masks, disparity, mode)
    shifts = torch.stack([-d * ds, -d * dt], dim=1)
    if occlusion_tolerance is None:
        return shift_masks(masks, shifts)
    coarse, shown = shift_masks_with_disparity(masks, disparity, shifts)
    return coarse & ~warp.hides(shown, occlusion_tolerance)

"""Step 2 of the pipeline: disparity propagation of center-view masks into every view.

Paper section 3.2: a pixel ``(u, v)`` of the center mask with disparity ``d`` moves to
``(u - d (s - s_c), v - d (t - t_c))`` in view ``(s, t)`` (sign fixed by the convention of
:mod:`lfsam.geometry`). Two variants (DESIGN.md section 3.3):

* ``"pixel"`` — the paper's equation: every pixel moves by its own disparity (forward warping to
  the nearest pixel); the small gaps forward warping leaves where a surface is stretched are
  closed by a 3 x 3 morphological closing.
* ``"mean"`` / ``"median"`` — the authors' code: the whole mask moves by one shift, its mean (or
  median) disparity times the view offset, resampled with sub-pixel accuracy.

Everything is batched over the N masks of a view and runs on the masks' device.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from lfsam.geometry import project_pixels

__all__ = [
    "ForwardWarp",
    "FrameRuns",
    "close_masks",
    "forward_warp",
    "mask_disparities",
    "propagate_masks",
    "shift_masks",
]

PROPAGATION_MODES = ("pixel", "mean", "median")


@dataclass
class FrameRuns:
    """Widths of the strips at a view's frame border that the center view does not see.

    Attributes
    ----------
    top, bottom : (V,) int tensor
        Unseen pixels from the top / bottom edge, per column.
    left, right : (U,) int tensor
        Unseen pixels from the left / right edge, per row.
    """

    top: torch.Tensor
    bottom: torch.Tensor
    left: torch.Tensor
    right: torch.Tensor


@dataclass
class ForwardWarp:
    """Where every center pixel lands in one view, and the z-buffer there.

    Attributes
    ----------
    target : (U * V,) int64 tensor
        Flat index of the nearest target pixel of each center pixel (undefined where not valid).
    valid : (U * V,) bool tensor
        The center pixel lands inside the view.
    zbuffer : (U * V,) float tensor
        Largest (closest) center disparity landing on each target pixel; ``-inf`` where none.
    """

    target: torch.Tensor
    valid: torch.Tensor
    zbuffer: torch.Tensor

    def seen(self, view_size: tuple[int, int]) -> torch.Tensor:
        """View pixels some center pixel lands on (closed 3 x 3), ``(U, V)`` bool.

        The rest of the view shows content the center view does not see (mostly a strip
        entering at the frame border), about which a propagated mask knows nothing.
        """
        landed = torch.isfinite(self.zbuffer).reshape(view_size)
        return close_masks(landed[None])[0]

    def frame_runs(
        self, view_size: tuple[int, int], seen: torch.Tensor | None = None
    ) -> FrameRuns:
        """Unseen runs from each frame edge (see :meth:`seen`), per row or column.

        ``seen`` may be passed when already computed.

        Returns
        -------
        FrameRuns
            ``top`` and ``bottom`` per column ``(V,)``, ``left`` and ``right`` per row ``(U,)``:
            the number of unseen pixels from that edge inwards.
        """
        if seen is None:
            seen = self.seen(view_size)
        unseen = (~seen).to(torch.int32)

        def run(edge_first: torch.Tensor) -> torch.Tensor:
            return torch.cumprod(edge_first, dim=1).sum(dim=1)

        return FrameRuns(
            top=run(unseen.T),
            bottom=run(unseen.flip(0).T),
            left=run(unseen),
            right=run(unseen.flip(1)),
        )

    def visible(self, disparity: torch.Tensor, tolerance: float) -> torch.Tensor:
        """Center pixels not hidden in this view by a closer center pixel (z-buffer test).

        A pixel is occluded when a center pixel with a disparity larger by more than
        ``tolerance`` lands on the same target pixel (DESIGN.md section 3, beyond the paper).

        Returns
        -------
        (U * V,) bool tensor
        """
        flat = disparity.reshape(-1)
        landed = self.zbuffer[self.target.clamp(min=0)]
        return self.valid & (flat >= landed - tolerance)


def forward_warp(disparity: torch.Tensor, ds: float, dt: float) -> ForwardWarp:
    """Forward-warp the center pixel grid into the view at offset ``(ds, dt)``.

    Parameters
    ----------
    disparity : (U, V) float tensor
        Center-view disparity (package convention).
    ds, dt : float
        View-row and view-column offsets of the target view from the center.

    Returns
    -------
    ForwardWarp
    """
    height, width = disparity.shape
    device = disparity.device
    rows = torch.arange(height, device=device, dtype=disparity.dtype)[:, None]
    cols = torch.arange(width, device=device, dtype=disparity.dtype)[None, :]
    target_u, target_v = project_pixels(rows, cols, disparity, ds, dt)
    iu = torch.round(target_u).long().reshape(-1)
    iv = torch.round(target_v).long().reshape(-1)
    valid = (iu >= 0) & (iu < height) & (iv >= 0) & (iv < width)
    target = torch.where(valid, iu * width + iv, torch.full_like(iu, -1))
    zbuffer = torch.full((height * width,), float("-inf"), device=device, dtype=disparity.dtype)
    zbuffer.scatter_reduce_(
        0, target[valid], disparity.reshape(-1)[valid], reduce="amax", include_self=True
    )
    return ForwardWarp(target=target, valid=valid, zbuffer=zbuffer)


def close_masks(masks: torch.Tensor, size: int = 3) -> torch.Tensor:
    """Morphological closing (dilation then erosion) of a batch of masks with a square window.

    Fills the one-pixel gaps forward warping leaves; does not grow a mask's outline.

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    size : int
        Odd window size.
    """
    if masks.numel() == 0:
        return masks
    pad = size // 2
    x = masks[:, None].to(torch.float32)
    dilated = F.max_pool2d(x, size, stride=1, padding=pad)
    # Erosion = 1 - dilation of the complement; pad with 1 so the frame border does not erode.
    eroded = 1.0 - F.max_pool2d(
        F.pad(1.0 - dilated, (pad, pad, pad, pad), value=0.0), size, stride=1
    )
    return eroded[:, 0] > 0.5


def splat_masks(masks: torch.Tensor, warp: ForwardWarp, keep: torch.Tensor | None = None):
    """Move every pixel of each mask to its target pixel (nearest-pixel forward warping).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    warp : ForwardWarp
    keep : (U * V,) bool tensor, optional
        Only these center pixels are moved (e.g. the pixels visible in the view).

    Returns
    -------
    (N, U, V) bool tensor
    """
    n, height, width = masks.shape
    source = warp.valid if keep is None else (warp.valid & keep)
    mask_idx, pix_idx = torch.nonzero(masks.reshape(n, -1) & source[None], as_tuple=True)
    out = torch.zeros((n, height * width), dtype=torch.bool, device=masks.device)
    out[mask_idx, warp.target[pix_idx]] = True
    return out.reshape(n, height, width)


def mask_disparities(
    masks: torch.Tensor, disparity: torch.Tensor, statistic: str = "mean"
) -> torch.Tensor:
    """One disparity per mask: the mean or median of the disparity over the mask.

    Returns
    -------
    (N,) float tensor (0 for an empty mask)
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
    raise ValueError(f"unknown statistic {statistic!r}; use 'mean' or 'median'")


def shift_masks(masks: torch.Tensor, shifts_uv: torch.Tensor) -> torch.Tensor:
    """Translate each mask by its own sub-pixel shift (bilinear resampling, threshold 0.5).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    shifts_uv : (N, 2) float tensor
        Row and column shift of each mask: output pixel ``(u, v)`` takes input ``(u - du, v - dv)``.
    """
    n, height, width = masks.shape
    if n == 0:
        return masks
    rows = torch.arange(height, device=masks.device, dtype=torch.float32)
    cols = torch.arange(width, device=masks.device, dtype=torch.float32)
    src_u = rows[None, :, None] - shifts_uv[:, 0, None, None]
    src_v = cols[None, None, :] - shifts_uv[:, 1, None, None]
    grid = torch.stack(
        [
            (2.0 * src_v / max(width - 1, 1) - 1.0).expand(n, height, width),
            (2.0 * src_u / max(height - 1, 1) - 1.0).expand(n, height, width),
        ],
        dim=-1,
    )
    sampled = F.grid_sample(
        masks[:, None].to(torch.float32), grid, mode="bilinear", align_corners=True,
        padding_mode="zeros",
    )
    return sampled[:, 0] >= 0.5


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
) -> torch.Tensor:
    """Coarse masks of one view: the center masks moved by disparity (paper section 3.2).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
        Center-view masks.
    disparity : (U, V) float tensor
        Center-view disparity, package convention (:mod:`lfsam.geometry`).
    ds, dt : float
        Offset of the target view from the center view.
    mode : {"pixel", "mean", "median"}
        Per-pixel propagation (the paper's equation) or a whole-mask shift (the authors' code).
    warp : ForwardWarp, optional
        Precomputed :func:`forward_warp` for this view (``"pixel"`` mode), shared with the
        geometric occlusion test.
    keep : (U * V,) bool tensor, optional
        ``"pixel"`` mode only: move only these center pixels (e.g. those visible in the view).
    fill_holes : bool
        ``"pixel"`` mode only: close forward-warping gaps with a 3 x 3 closing.

    Returns
    -------
    coarse : (N, U, V) bool tensor
    """
    if mode == "pixel":
        if warp is None:
            warp = forward_warp(disparity, ds, dt)
        coarse = splat_masks(masks, warp, keep)
        if not fill_holes:
            return coarse
        # Forward-warping holes are pixels nothing lands on; pixels a (closer) surface lands on
        # are not holes, so the closing may not claim them.
        unlanded = ~torch.isfinite(warp.zbuffer).reshape(coarse.shape[1:])
        return close_masks(coarse) & (coarse | unlanded)
    if mode in ("mean", "median"):
        d = mask_disparities(masks, disparity, mode)
        shifts = torch.stack([-d * ds, -d * dt], dim=1)
        return shift_masks(masks, shifts)
    raise ValueError(f"unknown propagation mode {mode!r}; use one of {PROPAGATION_MODES}")

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

from lfsam.errors import LfsamError
from lfsam.geometry import project_pixels

__all__ = [
    "ForwardWarp",
    "FrameRuns",
    "fill_warp_holes",
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
    ds, dt : float
        Offset of the view from the center view.
    """

    target: torch.Tensor
    valid: torch.Tensor
    zbuffer: torch.Tensor
    ds: float = 0.0
    dt: float = 0.0

    def hole_disparity(self, view_size: tuple[int, int]) -> torch.Tensor:
        """Disparity at each view pixel: the z-buffer, with holes filled from neighbours.

        Forward-warping holes (pixels no center pixel lands on) next to landed pixels take the
        smallest (farthest) disparity of their landed 3 x 3 neighbours: a hole opened by a
        stretched surface has that surface around it, and one opened by a disocclusion shows
        what lies behind, i.e. the farther side. Pixels with no landed neighbour stay ``-inf``.

        Returns
        -------
        (U, V) float tensor
        """
        zbuffer = self.zbuffer.reshape(view_size)
        landed = torch.isfinite(zbuffer)
        # Min over landed neighbours = -max over -z, with unlanded pixels at -inf (ignored).
        negated = torch.where(landed, -zbuffer, torch.full_like(zbuffer, float("-inf")))
        neighbour_min = -F.max_pool2d(negated[None, None], 3, stride=1, padding=1)[0, 0]
        return torch.where(landed, zbuffer, neighbour_min.nan_to_num(neginf=float("-inf")))

    def hole_sources(
        self, view_size: tuple[int, int]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Fillable holes and the center pixel each one shows.

        A hole ``q`` with disparity ``d`` (:meth:`hole_disparity`) shows center pixel
        ``q + d (ds, dt)`` under the convention of :mod:`lfsam.geometry`; holes whose source
        lies outside the center view are not fillable.

        Returns
        -------
        hole_u, hole_v, source_u, source_v : (K,) int64 tensors
        """
        height, width = view_size
        filled = self.hole_disparity(view_size)
        landed = torch.isfinite(self.zbuffer).reshape(view_size)
        hole_u, hole_v = torch.nonzero(~landed & torch.isfinite(filled), as_tuple=True)
        d = filled[hole_u, hole_v]
        src_u = torch.round(hole_u + d * self.ds).long()
        src_v = torch.round(hole_v + d * self.dt).long()
        ok = (src_u >= 0) & (src_u < height) & (src_v >= 0) & (src_v < width)
        return hole_u[ok], hole_v[ok], src_u[ok], src_v[ok]

    def seen(self, view_size: tuple[int, int]) -> torch.Tensor:
        """View pixels that propagation reaches: landed on or fillable holes, ``(U, V)`` bool.

        The rest of the view shows content the center view does not see (mostly a strip
        entering at the frame border), about which a propagated mask knows nothing.
        """
        seen = torch.isfinite(self.zbuffer).reshape(view_size).clone()
        hole_u, hole_v, _, _ = self.hole_sources(view_size)
        seen[hole_u, hole_v] = True
        return seen

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
    return ForwardWarp(target=target, valid=valid, zbuffer=zbuffer, ds=float(ds), dt=float(dt))


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


def fill_warp_holes(
    coarse: torch.Tensor,
    masks: torch.Tensor,
    warp: ForwardWarp,
    keep: torch.Tensor | None = None,
) -> torch.Tensor:
    """Fill forward-warping holes by looking their source up in the center masks.

    A hole pixel ``q`` gets the disparity ``d`` of :meth:`ForwardWarp.hole_disparity`; under the
    convention of :mod:`lfsam.geometry` it shows center pixel ``q + d (ds, dt)``
    (:meth:`ForwardWarp.hole_sources`), and takes that pixel's mask memberships (forward-warp
    the depth, backward-warp the masks). Cost is O(N x holes); no N x U x V filtering.

    Parameters
    ----------
    coarse : (N, U, V) bool tensor
        Splatted masks of the view (modified copy returned).
    masks : (N, U, V) bool tensor
        Center-view masks.
    warp : ForwardWarp
    keep : (U * V,) bool tensor, optional
        Center pixels allowed to contribute (e.g. visible ones).

    Returns
    -------
    (N, U, V) bool tensor
    """
    n, height, width = coarse.shape
    hole_u, hole_v, src_u, src_v = warp.hole_sources((height, width))
    if hole_u.numel() == 0 or n == 0:
        return coarse
    values = masks[:, src_u, src_v]
    if keep is not None:
        values = values & keep.reshape(height, width)[src_u, src_v][None]
    out = coarse.clone()
    out[:, hole_u, hole_v] = values
    return out


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
        ``"pixel"`` mode only: fill forward-warping gaps (:func:`fill_warp_holes`).

    Returns
    -------
    coarse : (N, U, V) bool tensor

    Raises
    ------
    LfsamError
        If ``mode`` is not one of :data:`PROPAGATION_MODES`.
    """
    if mode == "pixel":
        if warp is None:
            warp = forward_warp(disparity, ds, dt)
        coarse = splat_masks(masks, warp, keep)
        return fill_warp_holes(coarse, masks, warp, keep) if fill_holes else coarse
    if mode in ("mean", "median"):
        d = mask_disparities(masks, disparity, mode)
        shifts = torch.stack([-d * ds, -d * dt], dim=1)
        return shift_masks(masks, shifts)
    raise LfsamError(f"unknown propagation {mode!r}; use one of {', '.join(PROPAGATION_MODES)}")

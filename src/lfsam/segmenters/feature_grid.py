"""Mask-mean features and cosine similarities on a bilinearly sampled feature grid, exactly and
without sampling the C-channel features at every pixel.

Semantic occluding (paper section 3.3) compares SAM 2's image embedding, brought to image
resolution, with the mean embedding of a source mask. Brought to image resolution means bilinear
interpolation of a ``C x h x w`` grid (C = 256, 64 x 64 for SAM 2), so the feature of a pixel is
``f_p = sum_k w_pk E_k`` over the four grid cells ``k`` around it. Both quantities the pipeline
needs are then small computations on the grid:

- the sum of features over a mask, ``sum_p f_p = sum_k (sum_p w_pk) E_k``: splat the bilinear
  weights of the mask's pixels onto the grid, then one ``(N, h w) x (h w, C)`` product;
- the cosine similarity of ``f_p`` to a unit source feature ``s``:
  ``f_p . s = sum_k w_pk (E_k . s)`` (a ``(N, C) x (C, h w)`` product once per view, then four
  gathers per pixel) and ``|f_p|^2 = w_p^T G w_p`` with ``G`` the 4 x 4 Gram matrix of the
  cell's corner features (ten dot-product maps per view).

No pixels x C matrix is ever formed, which is what made semantic occluding cost about a tenth of
a second per view on a CPU. The sampling convention is that of
:meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.sample_features`: the view is resized to the
grid without padding, pixel ``r`` of ``U`` rows lies at grid coordinate ``(r + 0.5) h / U - 0.5``
(``F.interpolate(..., align_corners=False)``), and coordinates beyond the outermost cell centres
are clamped (``grid_sample(..., padding_mode="border")``).
"""

from __future__ import annotations

import functools

import torch
import torch.nn.functional as F

from lfsam.precision import wide_float

__all__ = [
    "BilinearCorners",
    "bilinear_corners",
    "grid_cosine_similarity",
    "grid_feature_sums",
    "pixel_feature_norms",
]

# the ten unordered corner pairs (i <= j) of a cell's 4 x 4 Gram matrix
_PAIRS = [(i, j) for i in range(4) for j in range(i, 4)]

#: :func:`grid_cosine_similarity` interpolates a mask's whole ``(E . s)`` map to the view
#: (``F.interpolate``, the same bilinear convention) instead of gathering four corners per
#: pixel when ``U x V <= INTERPOLATE_BELOW x`` the mask's pixels: one interpolated value costs
#: about a ninth of a four-corner gather on a CPU (measured on 240 x 320 views).
INTERPOLATE_BELOW = 8


class BilinearCorners:
    """The four grid cells around each pixel and their bilinear weights.

    Attributes
    ----------
    cell : (P,) int64 tensor
        Flat index ``y0 * w + x0`` of the top-left corner (it also indexes the Gram maps).
    index : (P, 4) int64 tensor
        Flat grid indices of the corners (y0, x0), (y0, x1), (y1, x0), (y1, x1).
    weight : (P, 4) float32 tensor
        Their weights (non-negative, summing to 1).
    """

    def __init__(self, cell: torch.Tensor, index: torch.Tensor, weight: torch.Tensor) -> None:
        self.cell = cell
        self.index = index
        self.weight = weight


def _axis(position: torch.Tensor, pixels: int, cells: int) -> tuple[torch.Tensor, ...]:
    """Lower cell, upper cell and upper weight along one axis (border-clamped)."""
    x = ((position.float() + 0.5) * (cells / pixels) - 0.5).clamp(0.0, cells - 1.0)
    low = x.floor().clamp(max=max(cells - 2, 0)).long()
    high = (low + 1).clamp(max=cells - 1)
    return low, high, x - low.float()


def bilinear_corners(
    rows: torch.Tensor, cols: torch.Tensor, image_size: tuple[int, int], grid_size: tuple[int, int]
) -> BilinearCorners:
    """Bilinear interpolation corners of pixels ``(rows, cols)`` of a ``U x V`` view on an
    ``h x w`` grid (module docstring for the convention).
    """
    u_size, v_size = image_size
    h, w = grid_size
    y0, y1, fy = _axis(rows, u_size, h)
    x0, x1, fx = _axis(cols, v_size, w)
    index = torch.stack([y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1], dim=1)
    weight = torch.stack(
        [(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx], dim=1
    )
    return BilinearCorners(y0 * w + x0, index, weight)


def grid_feature_sums(
    grid: torch.Tensor,
    mask_index: torch.Tensor,
    pixel_index: torch.Tensor,
    num_masks: int,
    image_size: tuple[int, int],
) -> torch.Tensor:
    """Sum of the interpolated features over each mask, ``(N, C)``.

    Parameters
    ----------
    grid : (C, h, w) tensor
        The feature grid.
    mask_index, pixel_index : (P,) int64 tensors
        The masks as (mask, flat pixel ``u * V + v``) pairs.
    num_masks : int
    image_size : (U, V)
    """
    channels, h, w = grid.shape
    width = image_size[1]
    corners = bilinear_corners(pixel_index // width, pixel_index % width, image_size, (h, w))
    splat = torch.zeros(num_masks * h * w, device=grid.device, dtype=torch.float32)
    target = (mask_index[:, None] * (h * w) + corners.index).reshape(-1)
    splat.index_add_(0, target.to(grid.device), corners.weight.reshape(-1).to(grid.device))
    return splat.view(num_masks, h * w) @ grid.reshape(channels, h * w).float().T


def _gram_maps(grid: torch.Tensor) -> torch.Tensor:
    """Per cell (y0, x0), the ten dot products of its corner features, ``(10, h * w)``."""
    _, h, w = grid.shape
    ys = torch.arange(h, device=grid.device)
    xs = torch.arange(w, device=grid.device)
    y1 = (ys + 1).clamp(max=h - 1)
    x1 = (xs + 1).clamp(max=w - 1)
    g = grid.to(wide_float(grid.device))
    corners = [g, g[:, :, x1], g[:, y1, :], g[:, y1][:, :, x1]]
    return torch.stack([(corners[i] * corners[j]).sum(0).reshape(-1) for i, j in _PAIRS])


@functools.lru_cache(maxsize=8)
def _view_corners(
    image_size: tuple[int, int], grid_hw: tuple[int, int], device: str
) -> BilinearCorners:
    """Bilinear corners of every pixel of a view (the same for every view of that size)."""
    u_size, v_size = image_size
    flat = torch.arange(u_size * v_size, device=device)
    return bilinear_corners(flat // v_size, flat % v_size, image_size, grid_hw)


def pixel_feature_norms(grid: torch.Tensor, image_size: tuple[int, int]) -> torch.Tensor:
    """Norm of the interpolated feature at every pixel of a view, ``(U * V,)`` float32.

    ``w^T G w`` with each cell's Gram matrix of its corner features (off-diagonal pairs counted
    twice), in float64 where the device has it (the corner products may cancel where
    neighbouring features point apart). Prompt-independent: computed once per view.
    """
    _, h, w = grid.shape
    u_size, v_size = image_size
    device = grid.device
    corners = _view_corners(tuple(image_size), (h, w), str(device))
    gram = _gram_maps(grid)[:, corners.cell]  # (10, U V)
    w64 = corners.weight.to(wide_float(device))
    norm_sq = torch.zeros(u_size * v_size, device=device, dtype=w64.dtype)
    for pair, (i, j) in enumerate(_PAIRS):
        factor = 1.0 if i == j else 2.0
        norm_sq += factor * w64[:, i] * w64[:, j] * gram[pair]
    return norm_sq.clamp(min=0.0).sqrt().clamp(min=1e-12).float()


def _interpolated(table, mask_index, pixel_index, grid_hw, image_size) -> torch.Tensor:
    """``sum_k w_pk table[n, k]`` per pair, from each row's map interpolated over the view."""
    maps = F.interpolate(
        table.view(-1, 1, *grid_hw), size=image_size, mode="bilinear", align_corners=False
    )
    return maps.reshape(-1)[mask_index * (image_size[0] * image_size[1]) + pixel_index]


def _gathered(table, mask_index, pixel_index, grid_hw, image_size) -> torch.Tensor:
    """The same sum per pair from its four grid corners (cached per view size)."""
    h, w = grid_hw
    corners = _view_corners(tuple(image_size), grid_hw, str(table.device))
    flat = mask_index[:, None] * (h * w) + corners.index[pixel_index]
    return (table.reshape(-1)[flat] * corners.weight[pixel_index]).sum(1)


def grid_cosine_similarity(
    grid: torch.Tensor,
    mask_index: torch.Tensor,
    pixel_index: torch.Tensor,
    sources: torch.Tensor,
    image_size: tuple[int, int],
    norms: torch.Tensor | None = None,
) -> torch.Tensor:
    """Cosine similarity of each pair's interpolated pixel feature to its mask's source feature.

    Parameters
    ----------
    grid : (C, h, w) tensor
        The feature grid of the view.
    mask_index, pixel_index : (P,) int64 tensors
        (mask, flat pixel ``u * V + v``) pairs.
    sources : (N, C) tensor
        Unit-norm source features (rows of zeros allowed: similarity 0).
    image_size : (U, V)
    norms : (U * V,) float32 tensor, optional
        :func:`pixel_feature_norms` of this view, when already computed (they depend on the
        view only, not on the masks).

    Returns
    -------
    (P,) float32 tensor

    Notes
    -----
    The numerator ``sum_k w_pk (E_k . s_n)`` is the bilinear interpolation of the ``(h, w)``
    map ``E . s_n``. For a mask that covers much of the view it is interpolated for the whole
    view at once (``F.interpolate``, :data:`INTERPOLATE_BELOW`); for the others the four
    corners of each pair are gathered. Both follow the module's convention and differ by float
    rounding only (about 1e-6). The choice is made per mask, from its own pixel count, so a
    mask's similarities do not depend on which other masks share the call (an incremental
    edit of one object gives the values of a full run).
    """
    channels, h, w = grid.shape
    device = grid.device
    pixel_index = pixel_index.to(device)
    mask_index = mask_index.to(device)
    if norms is None:
        norms = pixel_feature_norms(grid, image_size)
    # numerator: sum_k w_k (E_k . s_n), from the (N, h w) table of grid-to-source products
    table = sources.to(device).float() @ grid.reshape(channels, h * w).float()
    num_masks = table.shape[0]
    u_size, v_size = int(image_size[0]), int(image_size[1])
    pixels = torch.bincount(mask_index, minlength=num_masks)
    dense = pixels * INTERPOLATE_BELOW >= u_size * v_size  # (N,): the choice, per mask
    sizes = ((h, w), (u_size, v_size))
    if pixel_index.numel() == 0 or not bool(dense.any()):
        numerator = _gathered(table, mask_index, pixel_index, *sizes)
    elif bool(dense.all()):
        numerator = _interpolated(table, mask_index, pixel_index, *sizes)
    else:
        by_map = dense[mask_index]  # (P,) pairs of dense masks
        slot = torch.cumsum(dense, 0) - 1  # a dense mask's row among the dense ones
        numerator = torch.empty(pixel_index.numel(), device=device, dtype=table.dtype)
        numerator[by_map] = _interpolated(
            table[dense], slot[mask_index[by_map]], pixel_index[by_map], *sizes
        )
        sparse = ~by_map
        numerator[sparse] = _gathered(table, mask_index[sparse], pixel_index[sparse], *sizes)
    return numerator / norms[pixel_index]

"""The light-field disparity convention, written once for the whole package.

A scene point seen at pixel ``(u, v)`` of view ``(s, t)`` with disparity ``d`` is seen in view
``(s', t')`` at pixel ``(u - d (s' - s), v - d (t' - t))`` (docs/design.md section 1;
paper section 3.2, with the sign fixed by the HCI 4D benchmark's files). ``u`` is the pixel row,
``v`` the pixel column, ``s`` the view row (growing downwards) and ``t`` the view column (growing
rightwards). Disparity is in pixels per unit view step; larger is closer.

Every loader converts its data set to this convention, and every module that moves pixels between
views calls the functions below. They are torch-first, batched and device-agnostic (in the style
of kornia); NumPy arrays are accepted and returned as NumPy arrays.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

__all__ = [
    "project_pixels",
    "view_offsets",
    "warp_to_reference",
]


def view_offsets(
    grid_shape: tuple[int, int], reference: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Angular offsets ``(s - s_ref, t - t_ref)`` of every view of a grid.

    Parameters
    ----------
    grid_shape : (S, T)
        Number of view rows and view columns.
    reference : (s_ref, t_ref)
        The reference view, usually the center ``(S // 2, T // 2)``.

    Returns
    -------
    ds, dt : ndarray of int, shape (S, T)
        View-row and view-column offsets of each view from the reference.

    Examples
    --------
    >>> ds, dt = view_offsets((3, 3), (1, 1))
    >>> ds.tolist()
    [[-1, -1, -1], [0, 0, 0], [1, 1, 1]]
    >>> dt[0].tolist()
    [-1, 0, 1]
    """
    s_count, t_count = grid_shape
    ds, dt = np.meshgrid(
        np.arange(s_count) - reference[0], np.arange(t_count) - reference[1], indexing="ij"
    )
    return ds, dt


def project_pixels(u, v, disparity, ds, dt):
    """Move pixel coordinates from one view to another by the package's convention.

    ``u' = u - d * ds`` and ``v' = v - d * dt`` where ``(ds, dt) = (s' - s, t' - t)`` is the
    angular step from the source view to the target view (docs/design.md section 1). Inputs
    broadcast against each other; torch tensors and NumPy arrays are both accepted.

    Parameters
    ----------
    u, v : array_like
        Pixel rows and columns in the source view (may be sub-pixel).
    disparity : array_like
        Disparity of each pixel, in pixels per view step.
    ds, dt : array_like
        View-row and view-column steps from the source view to the target view.

    Returns
    -------
    u_target, v_target : array_like
        Pixel rows and columns in the target view.

    Examples
    --------
    A point at disparity 2 seen from one view row down and one view column left:

    >>> project_pixels(10.0, 20.0, 2.0, 1, -1)
    (8.0, 22.0)
    >>> import numpy as np
    >>> u, v = project_pixels(np.array([0.0, 5.0]), np.array([3.0, 3.0]), 0.5, 2, 0)
    >>> u.tolist(), v.tolist()
    ([-1.0, 4.0], [3.0, 3.0])
    """
    return u - disparity * ds, v - disparity * dt


def warp_to_reference(
    view: torch.Tensor | np.ndarray,
    reference_disparity: torch.Tensor | np.ndarray,
    ds: float,
    dt: float,
    mode: str = "bilinear",
) -> torch.Tensor | np.ndarray:
    """Backward-warp one view into the reference view using the reference view's disparity.

    Reference pixel ``(u, v)`` with disparity ``d`` is seen in the view at
    ``(u - d ds, v - d dt)`` (docs/design.md section 1), so the warped image samples the view there.
    Pixels that fall outside the view are NaN.

    Parameters
    ----------
    view : (U, V) or (U, V, C) array or tensor
        The view to warp (any dtype; computed in float32).
    reference_disparity : (U, V) array or tensor
        Disparity of the reference view.
    ds, dt : float
        View-row and view-column offsets of ``view`` from the reference view.
    mode : {"bilinear", "nearest"}
        Interpolation, as in :func:`torch.nn.functional.grid_sample`.

    Returns
    -------
    warped : same layout as ``view``, float32
        The view resampled onto the reference view's pixel grid.
    """
    is_numpy = isinstance(view, np.ndarray)
    image = torch.as_tensor(view).float()
    disp = torch.as_tensor(reference_disparity, device=image.device).float()
    squeeze = image.ndim == 2
    if squeeze:
        image = image[..., None]
    height, width = disp.shape
    rows = torch.arange(height, device=image.device, dtype=torch.float32)[:, None]
    cols = torch.arange(width, device=image.device, dtype=torch.float32)[None, :]
    src_u, src_v = project_pixels(rows, cols, disp, ds, dt)
    # align_corners=True maps -1 and 1 to the centres of the first and last pixels.
    grid = torch.stack(
        [2.0 * src_v / max(width - 1, 1) - 1.0, 2.0 * src_u / max(height - 1, 1) - 1.0], dim=-1
    )
    sampled = F.grid_sample(
        image.permute(2, 0, 1)[None], grid[None], mode=mode, align_corners=True,
        padding_mode="zeros",
    )[0].permute(1, 2, 0)
    inside = (src_u >= 0) & (src_u <= height - 1) & (src_v >= 0) & (src_v <= width - 1)
    sampled = torch.where(inside[..., None], sampled, torch.full_like(sampled, float("nan")))
    if squeeze:
        sampled = sampled[..., 0]
    return sampled.cpu().numpy() if is_numpy else sampled

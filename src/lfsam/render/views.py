"""Which views a rendering uses, and the input checks shared by :mod:`lfsam.render`.

The aperture (docs/design.md section 13): all present views, or those within ``radius`` view
steps of the center view (Euclidean in ``(s, t)``), as a wide or narrower synthetic lens.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable

import numpy as np
import torch

from lfsam.errors import LfsamError

__all__ = ["check_masks", "clip_focus", "select_views", "views_tensor"]


def select_views(
    grid_shape: tuple[int, int], present: np.ndarray | None = None, aperture: float | None = None
) -> tuple[list[tuple[int, int]], torch.Tensor]:
    """The views of the synthetic aperture and their offsets ``(ds, dt)`` from the center.

    Parameters
    ----------
    grid_shape : (S, T)
    present : (S, T) bool array, optional
        Views that exist (absent views are never used).
    aperture : float, optional
        Radius in view steps around the center view; None = every present view.

    Returns
    -------
    views : list of (s, t)
    offsets : (N, 2) float64 tensor

    Raises
    ------
    LfsamError
        For a negative radius.
    """
    s_count, t_count = grid_shape
    sc, tc = s_count // 2, t_count // 2
    if aperture is not None and not aperture >= 0:
        raise LfsamError(f"--aperture must be 'all' or a radius >= 0 in view steps, got {aperture}")
    chosen = []
    for s in range(s_count):
        for t in range(t_count):
            if present is not None and not present[s, t]:
                continue
            if aperture is not None and np.hypot(s - sc, t - tc) > aperture + 1e-9:
                continue
            chosen.append((s, t))
    offsets = torch.tensor([(s - sc, t - tc) for s, t in chosen], dtype=torch.float64)
    return chosen, offsets.reshape(-1, 2)


def views_tensor(views: np.ndarray, chosen: Iterable[tuple[int, int]],
                 device: torch.device) -> torch.Tensor:
    """The chosen views as an ``(N, 3, U, V)`` float32 tensor in [0, 255]."""
    array = np.stack([views[s, t] for s, t in chosen])
    return torch.from_numpy(array).to(device).permute(0, 3, 1, 2).float()


def check_masks(masks: np.ndarray, views: np.ndarray) -> np.ndarray:
    """``masks`` as bool ``(S, T, U, V)`` matching ``views`` ``(S, T, U, V, 3)``.

    Raises
    ------
    LfsamError
        If the shapes disagree (a result of another light field).
    """
    masks = np.asarray(masks)
    if masks.shape != views.shape[:4]:
        raise LfsamError(
            f"the masks are of a {masks.shape[0]}x{masks.shape[1]} grid of "
            f"{masks.shape[2]}x{masks.shape[3]} views but the light field is "
            f"{views.shape[0]}x{views.shape[1]} of {views.shape[2]}x{views.shape[3]}: "
            "a result of another light field?"
            if masks.ndim == 4 else f"masks must be (S, T, U, V), got shape {masks.shape}"
        )
    return masks.astype(bool)


def clip_focus(focus: float, disparity_range: tuple[float, float] | None) -> float:
    """``focus`` clipped into ``disparity_range`` with a warning when it lies outside."""
    if disparity_range is None:
        return float(focus)
    low, high = float(disparity_range[0]), float(disparity_range[1])
    if not low <= focus <= high:
        clipped = float(min(max(focus, low), high))
        warnings.warn(
            f"focus {focus:g} lies outside the scene's disparity range [{low:.3g}, {high:.3g}]; "
            f"using {clipped:.3g}",
            stacklevel=3,
        )
        return clipped
    return float(focus)


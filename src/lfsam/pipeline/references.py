"""Extra reference views for the automatic mode: finding objects the center view cannot see.

The paper's automatic mode (section 3.1) generates masks in the center view only; an object
hidden there behind a nearer one gets no label in any view. With ``--references`` (issue 16;
DESIGN.md section 8) automatic mask generation also runs in other views, but only where the
masks propagated so far do not already land, and each genuinely new object is propagated from its
own reference view. This module holds the pure parts of that:

- :func:`reference_views`: which views are references for a mode;
- :func:`uncovered_points`: SAM 2's automatic-generator point grid in a view, without the points
  that fall on pixels already covered;
- :func:`drop_covered_masks`: which new masks to keep (those not mostly on covered pixels).
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.precision import wide_float

__all__ = ["REFERENCE_MODES", "drop_covered_masks", "reference_views", "uncovered_points"]

#: Modes of ``--references``, from the paper's setting to every view.
REFERENCE_MODES = ("center", "corners", "ring", "all")


def reference_views(grid_shape: tuple[int, int], mode: str) -> list[tuple[int, int]]:
    """The reference views of an automatic run, the center view first.

    Parameters
    ----------
    grid_shape : (S, T)
        Views per column and row.
    mode : {"center", "corners", "ring", "all"}
        ``center``: the center view ``(S // 2, T // 2)`` only (the paper's setting);
        ``corners``: and the four corner views; ``ring``: and the outer ring's corners and
        edge midpoints (``(0, T // 2)``, ``(S - 1, T // 2)``, ``(S // 2, 0)``,
        ``(S // 2, T - 1)``); ``all``: every view.

    Returns
    -------
    list of (s, t)
        Distinct views: the center, then the others in row-major order (small grids, where
        corners coincide, give fewer views).

    Raises
    ------
    LfsamError
        For an unknown mode.
    """
    if mode not in REFERENCE_MODES:
        raise LfsamError(f"--references {mode}: use one of {', '.join(REFERENCE_MODES)}")
    s_count, t_count = int(grid_shape[0]), int(grid_shape[1])
    if s_count < 1 or t_count < 1:
        raise ValueError(f"grid shape must be positive, got {grid_shape}")
    center = (s_count // 2, t_count // 2)
    last_s, last_t = s_count - 1, t_count - 1
    if mode == "center":
        others: set[tuple[int, int]] = set()
    elif mode == "all":
        others = {(s, t) for s in range(s_count) for t in range(t_count)}
    else:
        others = {(0, 0), (0, last_t), (last_s, 0), (last_s, last_t)}
        if mode == "ring":
            others |= {(0, center[1]), (last_s, center[1]), (center[0], 0), (center[0], last_t)}
    others.discard(center)
    return [center, *sorted(others)]


def _grid(points_per_side: int) -> np.ndarray:
    """SAM 2's automatic-generator grid in ``[0, 1]^2``, ``(n^2, 2)`` as ``(x, y)``, rows of
    points top to bottom (the positions of ``sam2.utils.amg.build_point_grid``)."""
    n = int(points_per_side)
    side = (np.arange(n, dtype=np.float64) + 0.5) / n
    xs = np.broadcast_to(side[None, :], (n, n))
    ys = np.broadcast_to(side[:, None], (n, n))
    return np.stack([xs, ys], axis=-1).reshape(-1, 2)


def uncovered_points(
    points_per_side: int, covered: np.ndarray, *, normalized: bool = False
) -> np.ndarray:
    """SAM 2's automatic point grid in a view, minus the points on covered pixels.

    Parameters
    ----------
    points_per_side : int
        Points along each side (SAM 2's ``points_per_side``).
    covered : (U, V) bool array
        Pixels of the view where a mask already lands (e.g. the propagated labels ``> 0``).
    normalized : bool
        Return the points in ``[0, 1]^2`` (what ``SAM2AutomaticMaskGenerator(point_grids=...)``
        takes) instead of pixels.

    Returns
    -------
    (P, 2) float64 array
        ``(x, y)`` = (column, row) in pixels, SAM 2's point convention: the grid point
        ``((i + 0.5) / n, (j + 0.5) / n)`` scaled by ``(V, U)``, as SAM 2 scales its grid to the
        image; a point at ``(x, y)`` lies on pixel ``(floor(y), floor(x))``. Row-major order of
        the grid; ``(0, 2)`` when every point is covered.
    """
    if int(points_per_side) < 1:
        raise ValueError(f"points_per_side must be >= 1, got {points_per_side}")
    covered = np.asarray(covered, dtype=bool)
    if covered.ndim != 2:
        raise ValueError(f"covered must be (U, V), got shape {covered.shape}")
    height, width = covered.shape
    unit = _grid(points_per_side)
    pixels = unit * np.array([width, height], dtype=np.float64)
    cols = np.clip(np.floor(pixels[:, 0]).astype(np.int64), 0, width - 1)
    rows = np.clip(np.floor(pixels[:, 1]).astype(np.int64), 0, height - 1)
    keep = ~covered[rows, cols]
    return (unit if normalized else pixels)[keep]


def drop_covered_masks(masks, covered, max_overlap: float = 0.5):
    """Which new masks to keep: those not mostly on pixels already covered.

    Parameters
    ----------
    masks : (M, U, V) bool ndarray or tensor
        Candidate masks of one reference view.
    covered : (U, V) bool ndarray or tensor
        Pixels of that view where a mask already lands.
    max_overlap : float
        A mask is dropped when more than this fraction of its pixels is covered; empty masks
        are dropped too.

    Returns
    -------
    keep : (M,) bool
        Of the type (and device) of ``masks``.
    """
    as_numpy = not isinstance(masks, torch.Tensor)
    m = torch.as_tensor(np.asarray(masks)) if as_numpy else masks
    c = torch.as_tensor(np.asarray(covered)) if not isinstance(covered, torch.Tensor) else covered
    if m.ndim != 3 or tuple(c.shape) != tuple(m.shape[1:]):
        raise ValueError(f"masks (M, U, V) and covered (U, V) differ: {m.shape}, {c.shape}")
    m = m.to(torch.bool)
    c = c.to(device=m.device, dtype=torch.bool)
    area = m.flatten(1).sum(1)
    inside = (m & c[None]).flatten(1).sum(1)
    wide = wide_float(m.device)
    keep = (area > 0) & (inside.to(wide) <= max_overlap * area.to(wide))
    return keep.cpu().numpy() if as_numpy else keep

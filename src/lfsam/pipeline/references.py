"""Extra reference views for the automatic mode: finding objects the center view cannot see.

The paper's automatic mode (section 3.1) generates masks in the center view only; an object
hidden there behind a nearer one gets no label in any view. With ``--references`` (issue 16;
docs/design.md section 8) automatic mask generation also runs in other views, but only where the
masks propagated so far do not already land, and each genuinely new object is propagated from its
own reference view. This module holds the pure parts of that:

- :func:`reference_views`: which views are references for a mode;
- :func:`seen_from`: the pixels of a reference view whose surface the center view sees too (the
  center's generator has had its chance there, so asking again could only find the same
  surfaces, split another way);
- :func:`uncovered_points`: SAM 2's automatic-generator point grid in a view, without the points
  that fall on pixels already covered;
- :func:`extra_view_points`: the points an extra reference view asks at: that grid at half
  density, plus the deepest pixel of every uncovered region large enough to hold a new object
  that the thinned grid misses;
- :func:`unasked_region_points`: one point in every region still to explain that no point has
  been asked in (after a generator round: the regions no answer explains);
- :func:`drop_covered_masks`: which new masks to keep (those not mostly on covered pixels).

A pixel counts as covered when a propagated mask lands on it or when the center view sees it, so
an extra reference view asks only where the center view could not look: behind nearer objects
and beyond its frame. On a scene where the center view sees everything, the extra views ask
(almost) nowhere: they cost little and change no label.
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.precision import wide_float
from lfsam.warp import landing_pixels

__all__ = [
    "REFERENCE_MODES",
    "check_references",
    "drop_covered_masks",
    "extra_view_points",
    "reference_views",
    "seen_from",
    "unasked_region_points",
    "uncovered_points",
]

#: Modes of ``--references``, from the paper's setting to every view.
REFERENCE_MODES = ("center", "corners", "ring", "all")


def check_references(mode: str) -> str:
    """``mode`` if it is one of :data:`REFERENCE_MODES`, else a one-line :class:`LfsamError`."""
    if mode not in REFERENCE_MODES:
        raise LfsamError(f"--references {mode}: use one of {', '.join(REFERENCE_MODES)}")
    return mode


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
    ValueError
        For a grid shape with no views (the caller's code is at fault: a light field always
        has at least one view).
    """
    check_references(mode)
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


def seen_from(
    disparity: torch.Tensor,
    other_disparity: torch.Tensor,
    ds: float,
    dt: float,
    tolerance: float,
) -> torch.Tensor:
    """Pixels of a view whose surface another view also sees (a backward z-buffer test).

    Pixel ``p`` of the view, with disparity ``d``, shows a surface point that the other view,
    at offset ``(ds, dt)``, images at ``q = p - d (ds, dt)`` (:func:`lfsam.warp.landing_pixels`,
    docs/design.md section 1). The other view sees that point unless ``q`` is outside its frame
    or the other view's own disparity at ``q`` is larger than ``d`` by more than ``tolerance``
    (something nearer hides it there).

    Parameters
    ----------
    disparity : (U, V) float tensor
        Disparity of this view. Non-finite values count as not seen.
    other_disparity : (U, V) float tensor
        Disparity of the other view (e.g. the center view).
    ds, dt : float
        Offset of the other view from this one, ``(s_other - s, t_other - t)``.
    tolerance : float
        Pixels per view step (the pipeline's ``zbuffer_tolerance``).

    Returns
    -------
    (U, V) bool tensor
        On the device of ``disparity``.

    Examples
    --------
    A near bar (disparity 2) in front of a far plane (disparity 0); the other view is one step
    to the right, where the bar has moved two pixels left and hides the plane's first pixels:

    >>> import torch
    >>> view = torch.tensor([[0.0, 0.0, 2.0, 2.0, 0.0, 0.0]])
    >>> other = torch.tensor([[2.0, 2.0, 0.0, 0.0, 0.0, 0.0]])
    >>> seen_from(view, other, 0, 1, 0.2).int().tolist()
    [[0, 0, 1, 1, 1, 1]]
    >>> seen_from(other, view, 0, -1, 0.2).int().tolist()
    [[1, 1, 0, 0, 1, 1]]
    """
    disparity = disparity.float()
    target, valid = landing_pixels(disparity, ds, dt)
    there = other_disparity.float().to(disparity.device).reshape(-1)[target.clamp(min=0)]
    seen = valid & (there <= disparity.reshape(-1) + tolerance)
    return seen.reshape(disparity.shape)


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

    Raises
    ------
    ValueError
        For ``points_per_side < 1`` or a ``covered`` that is not 2-D (the caller's code is at
        fault; the CLI and the predictor check their inputs first).
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


def extra_view_points(
    points_per_side: int, covered: np.ndarray, min_region: int
) -> np.ndarray:
    """The points an extra reference view's generator asks at (docs/design.md section 8).

    What is left uncovered in an extra view (where no mask lands and the center view could not
    look, :func:`seen_from`) is thin: strips entering at the frame border and disocclusions
    along depth edges. SAM 2's full grid would put a point every few pixels along them. Here
    the grid is thinned to half its density per side (:func:`uncovered_points` with
    ``points_per_side // 2``), and every uncovered 8-connected region of at least
    ``min_region`` pixels that none of those points falls in gets one point at its deepest
    pixel (farthest from any covered pixel or the frame). A smaller region cannot hold the
    uncovered majority of a new object of ``2 * min_region`` pixels, which is what
    :func:`drop_covered_masks` would keep.

    Parameters
    ----------
    points_per_side : int
        The generator's ``points_per_side`` (halved here, at least 1).
    covered : (U, V) bool array
        Pixels covered already (masks landing there, or seen from the center view).
    min_region : int
        Smallest uncovered region that gets its own point (pixels, >= 1).

    Returns
    -------
    (P, 2) float64 array
        ``(x, y)`` pixel positions (a region's point at its pixel's centre), grid points first.

    Raises
    ------
    ValueError
        For a ``covered`` that is not 2-D (the caller's code is at fault).

    Examples
    --------
    A 9-pixel-wide uncovered column in a covered 40 x 40 view (two columns of the thinned 8 x 8
    grid fall in it: 16 points) and a 3 x 3 uncovered hole that the grid misses (one point, at
    its centre):

    >>> import numpy as np
    >>> covered = np.ones((40, 40), dtype=bool)
    >>> covered[:, 30:39] = False
    >>> covered[14:17, 14:17] = False
    >>> points = extra_view_points(16, covered, min_region=9)
    >>> len(points), points[-1].tolist()
    (17, [15.5, 15.5])
    """
    grid = uncovered_points(max(int(points_per_side) // 2, 1), covered)
    deepest = unasked_region_points(~np.asarray(covered, dtype=bool), min_region, grid)
    return np.concatenate([grid, deepest])


def unasked_region_points(free: np.ndarray, min_region: int, asked: np.ndarray) -> np.ndarray:
    """The deepest pixel of every free region that no point has been asked in yet.

    A region is an 8-connected component of ``free`` with at least ``min_region`` pixels; its
    deepest pixel is the one farthest from every non-free pixel and from the frame (the
    first in row-major order on ties), where a point is least likely to fall on a region's
    border. Used twice by the automatic mode (docs/design.md section 8): for the regions that
    :func:`extra_view_points`'s thinned grid misses, and after each generator round for the
    regions that no answer explains (e.g. a hidden object beside another hidden object that a
    grid point found, in one uncovered strip).

    Parameters
    ----------
    free : (U, V) bool array
        Pixels still to explain.
    min_region : int
        Smallest region that gets a point (pixels; values below 1 count as 1).
    asked : (P, 2) float array
        ``(x, y)`` pixel positions asked already; a region holding one of them gets no point.

    Returns
    -------
    (R, 2) float64 array
        ``(x, y)`` of each region's point, at its pixel's centre, in label order (row-major
        order of the regions' first pixels); ``(0, 2)`` when no region qualifies.

    Raises
    ------
    ValueError
        For a ``free`` that is not 2-D (the caller's code is at fault).

    Examples
    --------
    Two free squares; a point was asked in the left one already:

    >>> import numpy as np
    >>> free = np.zeros((6, 12), dtype=bool)
    >>> free[1:4, 1:4] = free[1:4, 7:10] = True
    >>> unasked_region_points(free, 4, np.array([[1.5, 1.5]])).tolist()
    [[8.5, 2.5]]
    """
    from scipy import ndimage

    free = np.asarray(free, dtype=bool)
    if free.ndim != 2:
        raise ValueError(f"free must be (U, V), got shape {free.shape}")
    none = np.zeros((0, 2), dtype=np.float64)
    regions, count = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        return none
    sizes = np.bincount(regions.ravel(), minlength=count + 1)
    asked = np.asarray(asked, dtype=np.float64).reshape(-1, 2)
    height, width = free.shape
    rows = np.clip(np.floor(asked[:, 1]).astype(np.int64), 0, height - 1)
    cols = np.clip(np.floor(asked[:, 0]).astype(np.int64), 0, width - 1)
    hit = np.zeros(count + 1, dtype=bool)
    hit[regions[rows, cols]] = True
    wanted = np.flatnonzero((sizes >= max(int(min_region), 1)) & ~hit)
    wanted = wanted[wanted > 0]
    if len(wanted) == 0:
        return none
    depth = ndimage.distance_transform_edt(np.pad(free, 1))[1:-1, 1:-1]
    deepest = np.asarray(ndimage.maximum_position(depth, regions, wanted), dtype=np.float64)
    return deepest.reshape(-1, 2)[:, ::-1] + 0.5  # (row, col) -> (x, y) at the pixel centre


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

    Raises
    ------
    ValueError
        When ``masks`` is not ``(M, U, V)`` with ``covered`` of shape ``(U, V)`` (the caller's
        code is at fault).
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

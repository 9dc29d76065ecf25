"""Visibility of the synthetic scene's patches: a per-sample z-buffer in any view.

Each sample position ``(u', v')`` of the view at offset ``(ds, dt)`` is mapped to every patch's
local coordinates and disparity by the patch's affine view maps
(:meth:`lfsam.synth.spec.PlanarObject.view_maps`); among the patches whose outline contains the
sample, the one with the largest disparity (the closest, docs/design.md section 1) wins. Ties keep
the earlier patch.

Samples are given either as a regular grid, ``us`` of shape ``(rows, 1)`` and ``vs`` of shape
``(1, cols)`` (then each patch is evaluated on its bounding box only, and the affine maps are
evaluated by broadcasting), or as two arrays of arbitrary points of equal shape.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from lfsam.synth.shapes import inside
from lfsam.synth.spec import PlanarObject

__all__ = ["is_grid", "local_coordinates", "region", "zbuffer"]


def is_grid(us: torch.Tensor, vs: torch.Tensor) -> bool:
    """Whether ``(us, vs)`` describe a regular grid: ``(rows, 1)`` and ``(1, cols)``."""
    return us.ndim == 2 and vs.ndim == 2 and us.shape[1] == 1 and vs.shape[0] == 1


def region(obj: PlanarObject, ds: float, dt: float, us: torch.Tensor, vs: torch.Tensor):
    """Slices of a regular sample grid covering the patch's bounding box in the view.

    Returns
    -------
    rows, cols : slice
        Index ``us[rows]`` and ``vs[:, cols]``; the whole grid for unbounded patches.
    """
    box = obj.view_bbox(ds, dt)
    if box is None:
        return slice(None), slice(None)
    row_values, col_values = us[:, 0], vs[0, :]

    def position(values: torch.Tensor, value: float, right: bool = False) -> int:
        target = torch.tensor(value, dtype=values.dtype, device=values.device)
        return int(torch.searchsorted(values, target, right=right))

    r0, r1 = position(row_values, box[0] - 1.0), position(row_values, box[1] + 1.0, True)
    c0, c1 = position(col_values, box[2] - 1.0), position(col_values, box[3] + 1.0, True)
    return slice(r0, max(r0, r1)), slice(c0, max(c0, c1))


def local_coordinates(
    obj: PlanarObject, ds: float, dt: float, u: torch.Tensor, v: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The patch's local ``(y, x)`` and disparity at view samples ``(u, v)`` (broadcast)."""
    local, disparity = obj.view_maps(ds, dt)
    y = (local[0, 0] * u + local[0, 2]) + local[0, 1] * v
    x = (local[1, 0] * u + local[1, 2]) + local[1, 1] * v
    d = (disparity[0] * u + disparity[2]) + disparity[1] * v
    return y, x, d


def zbuffer(
    objects: Sequence[PlanarObject],
    ds: float,
    dt: float,
    us: torch.Tensor,
    vs: torch.Tensor,
    with_coverage: bool = False,
) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor] | None]:
    """Which patch is visible at each sample of the view at offset ``(ds, dt)``.

    Parameters
    ----------
    objects : sequence of PlanarObject
        The patches, background first.
    ds, dt : float
        View offset from the center view.
    us, vs : Tensor
        Sample rows and columns: a regular grid ``(rows, 1)``, ``(1, cols)`` or two arrays of
        points of equal shape. Their dtype is the working precision.
    with_coverage : bool
        Also return, for each patch after the first, where its outline covers the samples
        (ignoring occlusion).

    Returns
    -------
    winner : Tensor of int64
        Index into ``objects`` of the visible patch (-1 where none covers the sample).
    disparity : Tensor
        Disparity of the visible patch (-inf where none).
    coverage : list of Tensor of bool, or None
    """
    grid = is_grid(us, vs)
    shape = torch.broadcast_shapes(us.shape, vs.shape)
    winner = torch.full(shape, -1, dtype=torch.int64, device=us.device)
    best = torch.full(shape, float("-inf"), dtype=us.dtype, device=us.device)
    coverage: list[torch.Tensor] | None = [] if with_coverage else None
    for index, obj in enumerate(objects):
        if grid:
            rows, cols = region(obj, ds, dt, us, vs)
            box: tuple = (rows, cols)
            u, v = us[rows], vs[:, cols]
        else:
            box = (Ellipsis,)
            u, v = us, vs
        y, x, d = local_coordinates(obj, ds, dt, u, v)
        covered = inside(obj.shape, x, y, obj.vertices, obj.corner)
        covered = covered.expand(best[box].shape)
        if coverage is not None and index > 0:
            full = torch.zeros(shape, dtype=torch.bool, device=us.device)
            full[box] = covered
            coverage.append(full)
        take = covered & (d > best[box])
        best[box] = torch.where(take, d, best[box])
        winner[box] = torch.where(take, torch.full_like(winner[box], index), winner[box])
    return winner, best, coverage

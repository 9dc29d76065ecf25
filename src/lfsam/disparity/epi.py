"""Epipolar-plane-image (EPI) stacks through a reference view, ready for orientation analysis.

A view's disparity is measured on two stacks of views (Wanner & Goldluecke, "Globally consistent
depth labeling of 4D light fields", CVPR 2012, section 3; paper section 3.2). For the reference
view ``(s_r, t_r)`` (the center ``(S // 2, T // 2)`` by default, any view for prompts given in
another view, docs/design.md section 8) the *horizontal* stack is its row of views ``L[s_r, t]``
(its EPIs are the slices ``(t, v)`` at fixed pixel row ``u``), the *vertical* stack is its column
``L[s, t_r]`` (EPIs ``(s, u)``). Both are returned in one layout, ``[N, rows, cols]`` with the
shifting pixel axis last: the vertical stack is transposed so that its pixel rows become the last
axis. A scene point with disparity ``d`` at reference pixel ``x`` (along the last axis) is then
seen in the stack's view ``n`` at ``x - d * (n - n_r)`` (docs/design.md section 1), the same
formula for both directions.

Partial grids (``LightField.present``): absent views stay in the stack as empty slots (so that the
stack index is still the view index and view steps stay regular) and are flagged in
:attr:`EpiStack.present`; the stack is cropped to the span of the present views. A direction needs
at least three present views; a reference view with fewer than three present views in both its row
and its column has no usable EPI and raises :class:`~lfsam.errors.LfsamError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = [
    "MIN_VIEWS",
    "EpiStack",
    "as_views",
    "checked_reference",
    "epi_stacks",
    "grid_present",
    "resolve_device",
    "resolve_view",
]

#: Fewest views in a direction for its EPIs to be usable (a derivative across views needs 3).
MIN_VIEWS = 3

# ITU-R BT.601 luma weights, as in skimage.color.rgb2gray's older default and OpenCV.
_LUMA = (0.299, 0.587, 0.114)


@dataclass
class EpiStack:
    """One direction's stack of views through the reference view.

    Attributes
    ----------
    direction : {"horizontal", "vertical"}
        ``"horizontal"``: the reference view's row of views, shifting along pixel columns ``v``.
        ``"vertical"``: its column of views, transposed so that pixel rows ``u`` are last.
    images : torch.Tensor, shape (N, C, rows, cols), float32 in [0, 1]
        The views (``C`` = 1 for gray, 3 for RGB); the shifting pixel axis is last. Absent views
        are zeros.
    center : int
        Index of the reference view in the stack (the center view by default).
    present : torch.Tensor, shape (N,), bool, optional
        Which slots hold a view (absent views of a partial grid do not); default all.
    """

    direction: str
    images: torch.Tensor
    center: int
    present: torch.Tensor | None = None

    def __post_init__(self) -> None:
        if self.present is None:
            self.present = torch.ones(
                self.images.shape[0], dtype=torch.bool, device=self.images.device
            )

    @property
    def offsets(self) -> torch.Tensor:
        """View offsets ``n - center`` (float32, on the stack's device)."""
        count = self.images.shape[0]
        return torch.arange(count, device=self.images.device, dtype=torch.float32) - self.center

    def to_center_layout(self, image: torch.Tensor) -> torch.Tensor:
        """Bring a ``(rows, cols)`` map of this stack back to the reference view's ``(U, V)``."""
        return image.transpose(-1, -2) if self.direction == "vertical" else image


def as_views(views: LightField | np.ndarray) -> np.ndarray:
    """The ``[S, T, U, V, 3]`` uint8 views of a light field or array (checked).

    Raises
    ------
    LfsamError
        If ``views`` is not a light field or an array of shape ``(S, T, U, V, 3)``.
    """
    if isinstance(views, LightField):
        return views.views
    array = np.asarray(views)
    if array.ndim != 5 or array.shape[-1] != 3:
        raise LfsamError(
            f"views must be a LightField or an array of shape (S, T, U, V, 3), got {array.shape}; "
            "stack the views as [view row, view column, pixel row, pixel column, RGB]"
        )
    if array.dtype != np.uint8:
        array = LightField(array).views  # same conversion rules as the data model
    return array


def grid_present(views: LightField | np.ndarray) -> np.ndarray:
    """The ``(S, T)`` bool mask of the views that exist (all of them for a plain array)."""
    if isinstance(views, LightField):
        return np.asarray(views.present, dtype=bool)
    return np.ones(np.shape(views)[:2], dtype=bool)


def checked_reference(
    views: LightField | np.ndarray, view: tuple[int, int] | None
) -> tuple[np.ndarray, np.ndarray, tuple[int, int], list[str]]:
    """The views, their ``present`` mask, the reference view and its usable EPI directions,
    checked the same way for every estimator (docs/design.md section 3.2).

    Raises
    ------
    LfsamError
        If the view lies outside the grid, is absent, or neither its row nor its column has
        :data:`MIN_VIEWS` present views.
    """
    array = as_views(views)
    s_count, t_count = array.shape[:2]
    present = grid_present(views)
    s_r, t_r = resolve_view((s_count, t_count), view)
    if not present[s_r, t_r]:
        raise LfsamError(
            f"view ({s_r}, {t_r}) is absent from this partial grid; choose a view that exists"
        )
    directions = usable_directions((s_count, t_count), (s_r, t_r), present)
    if not directions:
        where = "" if view is None else f" through view ({s_r}, {t_r})"
        raise LfsamError(
            f"grid {s_count}x{t_count}: need at least {MIN_VIEWS} views in a row or column{where} "
            "to estimate disparity; give a disparity map instead (--disparity gt or a .npy file)"
        )
    return array, present, (s_r, t_r), directions


def resolve_view(
    grid_shape: tuple[int, int], view: tuple[int, int] | None
) -> tuple[int, int]:
    """The reference view ``(s, t)`` (0-based view row and column; None = the center), checked.

    Raises
    ------
    LfsamError
        If the view lies outside the grid.
    """
    s_count, t_count = grid_shape
    if view is None:
        return s_count // 2, t_count // 2
    try:
        s, t = (int(i) for i in view)
    except (TypeError, ValueError):
        raise LfsamError(
            f"view must be a pair (s, t) of view row and column, got {view!r}"
        ) from None
    if not (0 <= s < s_count and 0 <= t < t_count):
        raise LfsamError(
            f"view ({s}, {t}) is outside the {s_count}x{t_count} grid; give 0 <= s < {s_count} "
            f"and 0 <= t < {t_count} (0-based view row, column)"
        )
    return s, t


def usable_directions(
    grid_shape: tuple[int, int],
    view: tuple[int, int] | None = None,
    present: np.ndarray | None = None,
) -> list[str]:
    """Directions with at least :data:`MIN_VIEWS` present views through ``view`` (default: the
    center) of a grid of ``(S, T)`` views."""
    s_ref, t_ref = resolve_view(grid_shape, view)
    if present is None:
        present = np.ones(grid_shape, dtype=bool)
    directions = []
    if int(present[s_ref].sum()) >= MIN_VIEWS:
        directions.append("horizontal")
    if int(present[:, t_ref].sum()) >= MIN_VIEWS:
        directions.append("vertical")
    return directions


def epi_stacks(
    views: LightField | np.ndarray,
    device: str | torch.device | None = None,
    color: bool = False,
    view: tuple[int, int] | None = None,
) -> list[EpiStack]:
    """The usable EPI stacks through the reference view ``view``, on ``device``.

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field (a LightField's ``present`` mask marks the views that exist).
    device : str or torch.device, optional
        Where to put the stacks; default ``auto`` (:func:`lfsam.devices.resolve_device`).
    color : bool
        Keep the three colour channels (``C`` = 3) instead of converting to gray (``C`` = 1).
    view : (s, t), optional
        The reference view (0-based view row and column); default the center view.

    Returns
    -------
    stacks : list of EpiStack
        ``horizontal`` (if the view's row has >= 3 present views) then ``vertical`` (if its
        column has), each cropped to the span of its present views.

    Raises
    ------
    LfsamError
        If the view lies outside the grid, is absent, or neither direction has three present
        views.
    """
    array, present, (s_c, t_c), directions = checked_reference(views, view)
    dev = resolve_device(device)
    stacks = []
    for direction in directions:
        line = present[s_c] if direction == "horizontal" else present[:, t_c]
        first, last = (int(i) for i in np.flatnonzero(line)[[0, -1]])
        if direction == "horizontal":
            raw = array[s_c, first : last + 1]  # (N, U, V, 3)
        else:
            raw = array[first : last + 1, t_c]
        images = torch.from_numpy(np.ascontiguousarray(raw)).to(dev).float().div_(255.0)
        images = images.permute(0, 3, 1, 2)  # (N, 3, U, V)
        if not color:
            weights = torch.tensor(_LUMA, device=dev).view(1, 3, 1, 1)
            images = (images * weights).sum(dim=1, keepdim=True)
        if direction == "vertical":
            images = images.transpose(-1, -2)
        center = (t_c if direction == "horizontal" else s_c) - first
        mask = torch.from_numpy(np.ascontiguousarray(line[first : last + 1])).to(dev)
        stacks.append(EpiStack(direction, images.contiguous(), center, mask))
    return stacks

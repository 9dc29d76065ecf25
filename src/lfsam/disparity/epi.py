"""Epipolar-plane-image (EPI) stacks through the center view, ready for orientation analysis.

The center view's disparity is measured on two stacks of views (Wanner & Goldluecke, "Globally
consistent depth labeling of 4D light fields", CVPR 2012, section 3; paper section 3.2): the
*horizontal* stack is the center row of views ``L[s_c, t]`` (its EPIs are the slices ``(t, v)`` at
fixed pixel row ``u``), the *vertical* stack is the center column ``L[s, t_c]`` (EPIs ``(s, u)``).
Both are returned in one layout, ``[N, rows, cols]`` with the shifting pixel axis last: the
vertical stack is transposed so that its pixel rows become the last axis. A scene point with
disparity ``d`` at center pixel ``x`` (along the last axis) is then seen in the stack's view ``n``
at ``x - d * (n - n_c)`` (docs/design.md section 1), the same formula for both directions.

A direction needs at least three views; a grid with fewer than three views in both directions has
no usable EPI and raises :class:`~lfsam.errors.LfsamError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["MIN_VIEWS", "EpiStack", "as_views", "epi_stacks", "resolve_device"]

#: Fewest views in a direction for its EPIs to be usable (a derivative across views needs 3).
MIN_VIEWS = 3

# ITU-R BT.601 luma weights, as in skimage.color.rgb2gray's older default and OpenCV.
_LUMA = (0.299, 0.587, 0.114)


@dataclass
class EpiStack:
    """One direction's stack of views through the center view.

    Attributes
    ----------
    direction : {"horizontal", "vertical"}
        ``"horizontal"``: the center row of views, shifting along pixel columns ``v``.
        ``"vertical"``: the center column of views, transposed so that pixel rows ``u`` are last.
    images : torch.Tensor, shape (N, C, rows, cols), float32 in [0, 1]
        The views (``C`` = 1 for gray, 3 for RGB); the shifting pixel axis is last.
    center : int
        Index of the center view in the stack.
    """

    direction: str
    images: torch.Tensor
    center: int

    @property
    def offsets(self) -> torch.Tensor:
        """View offsets ``n - center`` (float32, on the stack's device)."""
        count = self.images.shape[0]
        return torch.arange(count, device=self.images.device, dtype=torch.float32) - self.center

    def to_center_layout(self, image: torch.Tensor) -> torch.Tensor:
        """Bring a ``(rows, cols)`` map of this stack back to the center view's ``(U, V)``."""
        return image.transpose(-1, -2) if self.direction == "vertical" else image


def resolve_device(device: str | torch.device | None) -> torch.device:
    """``device`` as a torch device; ``None`` picks CUDA when present, else the CPU."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(device)


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


def usable_directions(grid_shape: tuple[int, int]) -> list[str]:
    """Directions with at least :data:`MIN_VIEWS` views, for a grid of ``(S, T)`` views."""
    s_count, t_count = grid_shape
    directions = []
    if t_count >= MIN_VIEWS:
        directions.append("horizontal")
    if s_count >= MIN_VIEWS:
        directions.append("vertical")
    return directions


def epi_stacks(
    views: LightField | np.ndarray,
    device: str | torch.device | None = None,
    color: bool = False,
) -> list[EpiStack]:
    """The usable EPI stacks through the center view, on ``device``.

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field.
    device : str or torch.device, optional
        Where to put the stacks; default CUDA when present, else the CPU.
    color : bool
        Keep the three colour channels (``C`` = 3) instead of converting to gray (``C`` = 1).

    Returns
    -------
    stacks : list of EpiStack
        ``horizontal`` (if the grid has >= 3 view columns) then ``vertical`` (if >= 3 view rows).

    Raises
    ------
    LfsamError
        If neither direction has three views.
    """
    array = as_views(views)
    s_count, t_count = array.shape[:2]
    directions = usable_directions((s_count, t_count))
    if not directions:
        raise LfsamError(
            f"grid {s_count}x{t_count}: need at least {MIN_VIEWS} views in a row or column to "
            "estimate disparity; give a disparity map instead (--disparity gt or a .npy file)"
        )
    dev = resolve_device(device)
    s_c, t_c = s_count // 2, t_count // 2
    stacks = []
    for direction in directions:
        raw = array[s_c] if direction == "horizontal" else array[:, t_c]  # (N, U, V, 3)
        images = torch.from_numpy(np.ascontiguousarray(raw)).to(dev).float().div_(255.0)
        images = images.permute(0, 3, 1, 2)  # (N, 3, U, V)
        if not color:
            weights = torch.tensor(_LUMA, device=dev).view(1, 3, 1, 1)
            images = (images * weights).sum(dim=1, keepdim=True)
        if direction == "vertical":
            images = images.transpose(-1, -2)
        center = t_c if direction == "horizontal" else s_c
        stacks.append(EpiStack(direction, images.contiguous(), center))
    return stacks

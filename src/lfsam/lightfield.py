"""The light-field data model: views on a grid, with optional ground truth.

A light field is ``L[s, t, u, v, c]`` (docs/design.md section 1): ``s`` the view row, ``t`` the view
column, ``u`` the pixel row, ``v`` the pixel column, ``c`` RGB, stored as uint8. Ground truth, when
present, is a disparity ``D[s, t, u, v]`` (float32, in the convention of :mod:`lfsam.geometry`) and
labels ``G[s, t, u, v]`` (int32, 0 = no label); either may be given for the center view only, as
``[U, V]``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lfsam.errors import LfsamError

__all__ = ["LightField", "snake_order"]


def snake_order(grid_shape: tuple[int, int]) -> list[tuple[int, int]]:
    """Views in snake (lawnmower) order: row 0 left to right, row 1 right to left, ...

    This is the frame order of the SAM 2 video baseline (paper section 4; docs/design.md section 4):
    consecutive frames are always neighbouring views.

    Parameters
    ----------
    grid_shape : (S, T)
        Number of view rows and columns.

    Returns
    -------
    order : list of (s, t)
        Every view exactly once.

    Examples
    --------
    >>> snake_order((2, 3))
    [(0, 0), (0, 1), (0, 2), (1, 2), (1, 1), (1, 0)]
    """
    s_count, t_count = grid_shape
    order = []
    for s in range(s_count):
        cols = range(t_count) if s % 2 == 0 else range(t_count - 1, -1, -1)
        order.extend((s, t) for t in cols)
    return order


@dataclass
class LightField:
    """A light field ``views[s, t, u, v, c]`` with optional ground truth.

    Parameters
    ----------
    views : ndarray, shape (S, T, U, V, 3), uint8
        The sub-aperture images.
    disparity : ndarray, shape (S, T, U, V) or (U, V), float32, optional
        Ground-truth disparity of every view (or of the center view only), in the convention of
        :mod:`lfsam.geometry`.
    labels : ndarray, shape (S, T, U, V) or (U, V), int32, optional
        Ground-truth instance or semantic labels (0 = no label), for every view or the center only.
    meta : dict
        Where the light field came from: ``source`` (path), ``format`` (reader name) and any
        reader-specific notes (e.g. the orientation a reader detected).
    present : ndarray, shape (S, T), bool, optional
        Which views exist (partial grids such as the HCI "star" subsets,
        docs/design.md section 8). Absent views hold zeros and are never used as data;
        default: all present.

    Raises
    ------
    LfsamError
        If an array has the wrong shape or dtype.

    Examples
    --------
    >>> import numpy as np
    >>> lf = LightField(np.zeros((3, 5, 4, 6, 3), dtype=np.uint8))
    >>> lf.grid_shape, lf.view_shape, lf.center
    ((3, 5), (4, 6), (1, 2))
    >>> lf.center_view.shape
    (4, 6, 3)
    """

    views: np.ndarray
    disparity: np.ndarray | None = None
    labels: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    present: np.ndarray | None = None

    def __post_init__(self) -> None:
        views = np.asarray(self.views)
        if views.ndim != 5 or views.shape[-1] != 3:
            raise LfsamError(
                f"light-field views must have shape (S, T, U, V, 3), got {views.shape}; "
                "stack the views as [view row, view column, pixel row, pixel column, RGB]"
            )
        if min(views.shape[:4]) < 1:
            raise LfsamError(f"light field has an empty dimension: shape {views.shape}")
        if views.dtype != np.uint8:
            views = _to_uint8(views)
        self.views = np.ascontiguousarray(views)
        if self.present is None:
            self.present = np.ones(views.shape[:2], dtype=bool)
        present = np.asarray(self.present)
        if present.shape != views.shape[:2]:
            raise LfsamError(
                f"present must have the grid's shape {views.shape[:2]}, got {present.shape}"
            )
        self.present = present.astype(bool)
        if not self.present[self.center]:
            raise LfsamError(
                f"the center view {self.center} is absent; lfsam needs the center view"
            )
        if self.disparity is not None:
            self.disparity = self._check_gt(self.disparity, "disparity").astype(np.float32)
        if self.labels is not None:
            labels = self._check_gt(self.labels, "labels")
            if not np.issubdtype(labels.dtype, np.integer):
                if not np.all(np.mod(labels, 1) == 0):
                    raise LfsamError("labels must be integers (0 = no label)")
            if labels.size and labels.min() < 0:
                raise LfsamError("labels must be >= 0 (0 = no label)")
            self.labels = labels.astype(np.int32)

    def _check_gt(self, array: np.ndarray, name: str) -> np.ndarray:
        array = np.asarray(array)
        full = self.views.shape[:4]
        if array.shape not in (full, full[2:]):
            raise LfsamError(
                f"{name} must have shape {full} (every view) or {full[2:]} (center view only), "
                f"got {array.shape}"
            )
        return array

    # --- shape --------------------------------------------------------------------------------
    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(S, T)``: number of view rows and view columns."""
        return self.views.shape[0], self.views.shape[1]

    @property
    def view_shape(self) -> tuple[int, int]:
        """``(U, V)``: pixel rows and columns of each view."""
        return self.views.shape[2], self.views.shape[3]

    @property
    def num_views(self) -> int:
        """``S * T``."""
        return self.grid_shape[0] * self.grid_shape[1]

    @property
    def center(self) -> tuple[int, int]:
        """The reference view ``(S // 2, T // 2)`` (docs/design.md section 1)."""
        return self.grid_shape[0] // 2, self.grid_shape[1] // 2

    @property
    def center_view(self) -> np.ndarray:
        """The reference view's image, ``(U, V, 3)`` uint8."""
        return self.views[self.center]

    @property
    def is_complete(self) -> bool:
        """Whether every view of the grid is present."""
        return bool(self.present.all())

    @property
    def num_present(self) -> int:
        """Number of views present."""
        return int(self.present.sum())

    # --- ground truth -------------------------------------------------------------------------
    @property
    def has_full_disparity(self) -> bool:
        """Whether ground-truth disparity is given for every view."""
        return self.disparity is not None and self.disparity.ndim == 4

    @property
    def has_full_labels(self) -> bool:
        """Whether ground-truth labels are given for every view."""
        return self.labels is not None and self.labels.ndim == 4

    @property
    def center_disparity(self) -> np.ndarray | None:
        """Ground-truth disparity of the center view ``(U, V)``, or None."""
        if self.disparity is None:
            return None
        return self.disparity[self.center] if self.disparity.ndim == 4 else self.disparity

    @property
    def center_labels(self) -> np.ndarray | None:
        """Ground-truth labels of the center view ``(U, V)``, or None."""
        if self.labels is None:
            return None
        return self.labels[self.center] if self.labels.ndim == 4 else self.labels

    def view_labels(self, s: int, t: int) -> np.ndarray | None:
        """Ground-truth labels of view ``(s, t)``; None unless labels exist for that view."""
        if self.labels is None:
            return None
        if self.labels.ndim == 4:
            return self.labels[s, t]
        return self.labels if (s, t) == self.center else None

    # --- iteration ----------------------------------------------------------------------------
    def view_indices(self, present_only: bool = False) -> Iterator[tuple[int, int]]:
        """All ``(s, t)`` in row-major order (only the views present with ``present_only``)."""
        s_count, t_count = self.grid_shape
        for s in range(s_count):
            for t in range(t_count):
                if not present_only or self.present[s, t]:
                    yield s, t

    def snake_order(self) -> list[tuple[int, int]]:
        """Views in snake order; see :func:`snake_order`."""
        return snake_order(self.grid_shape)

    def describe(self) -> dict[str, Any]:
        """A JSON-ready summary: grid, view size, ground truth present, format."""
        disp = self.disparity
        return {
            "grid": list(self.grid_shape),
            "view_size": list(self.view_shape),
            "center": list(self.center),
            "views_present": self.num_present,
            "disparity": None if disp is None else ("all views" if disp.ndim == 4 else "center"),
            "disparity_range": None
            if disp is None
            else [float(np.nanmin(disp)), float(np.nanmax(disp))],
            "labels": None
            if self.labels is None
            else ("all views" if self.labels.ndim == 4 else "center"),
            "num_labels": None
            if self.labels is None
            else int(np.count_nonzero(np.unique(self.labels))),
            **{k: v for k, v in self.meta.items() if isinstance(v, (str, int, float, list))},
        }


def _to_uint8(views: np.ndarray) -> np.ndarray:
    """Convert float views in [0, 1] (or [0, 255]) and 16-bit views to uint8."""
    if views.dtype == np.uint16:
        return (views // 257).astype(np.uint8)
    if np.issubdtype(views.dtype, np.floating):
        finite = views[np.isfinite(views)]
        scale = 255.0 if finite.size == 0 or finite.max() <= 1.0 + 1e-6 else 1.0
        return np.clip(np.rint(np.nan_to_num(views) * scale), 0, 255).astype(np.uint8)
    if np.issubdtype(views.dtype, np.integer):
        if views.min() < 0 or views.max() > 255:
            raise LfsamError(
                f"integer views must lie in 0..255, got {views.min()}..{views.max()}"
            )
        return views.astype(np.uint8)
    raise LfsamError(f"unsupported view dtype {views.dtype}; use uint8 RGB")

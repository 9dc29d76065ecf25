"""The light-field data model: views on a grid, with optional ground truth.

A light field is ``L[s, t, u, v, c]`` (docs/design.md section 1): ``s`` the view row, ``t`` the view
column, ``u`` the pixel row, ``v`` the pixel column, ``c`` RGB, stored as uint8. Ground truth, when
present, is a disparity ``D[s, t, u, v]`` (float32, in the convention of :mod:`lfsam.geometry`) and
labels ``G[s, t, u, v]`` (int32, 0 = no label); either may be given for the center view only, as
``[U, V]``. Labels may carry category names (``categories``, label id -> name, e.g. ``{2: "brick
disc"}``), which the oracle's text answer uses (docs/design.md section 9).

Floating-point views are converted to uint8 by one documented rule (:func:`float_scale`): values
must be finite and within [0, 255] (round-off down to -0.5/255 reads as 0); they are read as
[0, 1] intensities when the 99.9th percentile of the values is at most 2 (so a [0, 1] light field
with a few values pushed slightly above 1 by processing still reads correctly; those few are
clipped to 1), otherwise as [0, 255]. A 0..255 light field whose 99.9th percentile is at most 2
(all but 0.1% of it darker than 2/255) would be misread; give ``value_range=255``
(``--value-range 255``) for it, or ``value_range=1``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lfsam.errors import LfsamError

__all__ = [
    "LightField",
    "categories_from_json",
    "categories_to_json",
    "check_result_shape",
    "float_scale",
    "snake_order",
]

#: Floats are read as [0, 1] when their 99.9th percentile is at most this (see float_scale).
UNIT_RANGE_LIMIT = 2.0
#: The percentile the [0, 1] / [0, 255] rule looks at.
RANGE_PERCENTILE = 99.9
#: Negative values down to this (float round-off; less than half a level even in [0, 1]) read as 0.
NEGATIVE_TOLERANCE = 0.5 / 255


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
        Which views exist (partial grids such as the HCI "star" subsets, docs/design.md
        section 8). Absent views hold zeros and are never used as data; default: all present.
    value_range : {1, 255}, optional
        For floating-point views: whether they are [0, 1] or [0, 255] intensities. None decides
        by the rule of :func:`float_scale` (99.9th percentile <= 2 means [0, 1]). Values must be
        finite and in [0, 255] (in [0, 1] mode, values above 1 are clipped to 1).
    categories : dict of int to str, optional
        The category name of each ground-truth label id (docs/design.md section 9); labels
        without an entry have no category.

    Raises
    ------
    LfsamError
        If an array has the wrong shape or dtype, or float views are non-finite or out of range.

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
    value_range: float | None = None
    categories: dict[int, str] | None = None

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
            views, note = _to_uint8(views, self.value_range)
            if note:
                self.meta = {**self.meta, "value_range": note}
        self.views = np.ascontiguousarray(views)
        if self.present is None:
            self.present = np.ones(views.shape[:2], dtype=bool)
        present = np.asarray(self.present)
        if present.shape != views.shape[:2] or present.dtype.kind not in "biu":
            raise LfsamError(
                f"present must be booleans of the grid's shape {views.shape[:2]}, "
                f"got {present.dtype} {present.shape}"
            )
        self.present = present.astype(bool)
        if not self.present[self.center]:
            raise LfsamError(
                f"the center view {self.center} is absent; lfsam needs the center view"
            )
        if self.disparity is not None:
            disparity = self._check_gt(self.disparity, "disparity")
            if disparity.dtype.kind not in "biuf":
                raise LfsamError(f"disparity must be numbers, got dtype {disparity.dtype}")
            self.disparity = disparity.astype(np.float32)
        if self.labels is not None:
            labels = self._check_gt(self.labels, "labels")
            if labels.dtype.kind not in "biuf":
                raise LfsamError(f"labels must be integers (0 = no label), got {labels.dtype}")
            if not np.issubdtype(labels.dtype, np.integer):
                if not np.all(np.mod(labels, 1) == 0):
                    raise LfsamError("labels must be integers (0 = no label)")
            if labels.size and labels.min() < 0:
                raise LfsamError("labels must be >= 0 (0 = no label)")
            if labels.size and labels.max() > np.iinfo(np.int32).max:
                raise LfsamError(f"labels must be < 2**31, got {labels.max()}")
            self.labels = labels.astype(np.int32)
        if self.categories is not None:
            if self.labels is None:
                raise LfsamError("categories name ground-truth labels, but there are no labels")
            self.categories = categories_from_json(self.categories, "categories")

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
            "categories": None
            if self.categories is None
            else sorted(set(self.categories.values())),
            **{k: v for k, v in self.meta.items() if isinstance(v, (str, int, float, list))},
        }


def categories_from_json(value: Any, where: str) -> dict[int, str]:
    """Category names by label id from JSON (``{"2": "brick disc"}``: keys are label ids >= 1
    as integers or decimal strings, values non-empty names).

    Raises
    ------
    LfsamError
        One line naming ``where`` and the entry at fault.
    """
    if not isinstance(value, dict):
        raise LfsamError(
            f"{where} must map label ids to names, e.g. {{\"2\": \"disc\"}}, got "
            f"{type(value).__name__}"
        )
    out: dict[int, str] = {}
    for key, name in value.items():
        try:
            label = int(key)
        except (TypeError, ValueError):
            label = 0
        if isinstance(key, bool) or label < 1:
            raise LfsamError(f"{where}: key {key!r} is not a label id >= 1")
        if not isinstance(name, str) or not name.split():
            raise LfsamError(f"{where}: label {label} needs a non-empty name, got {name!r}")
        out[label] = " ".join(name.split())
    return dict(sorted(out.items()))


def categories_to_json(categories: dict[int, str]) -> dict[str, str]:
    """Category names with string keys (JSON objects have string keys)."""
    return {str(label): name for label, name in sorted(categories.items())}


def check_result_shape(labels_shape: tuple[int, ...], lf: LightField, where: str) -> None:
    """Check that a result's labels ``(S, T, U, V)`` fit the light field ``lf``.

    Raises
    ------
    LfsamError
        If the grid or the view size differ.
    """
    if tuple(labels_shape) != lf.views.shape[:4]:
        raise LfsamError(
            f"{where} has labels of shape {tuple(labels_shape)} but the light field "
            f"{lf.meta.get('source', '')} has views {lf.views.shape[:4]} (S, T, U, V); "
            "give the light field the result was computed on"
        )


def float_scale(views: np.ndarray, value_range: float | None = None) -> tuple[float, str]:
    """The factor that maps float views to 0..255, and a note saying why.

    The rule (documented in the module docstring and the README): values must be finite and in
    [0, 255]; with ``value_range`` None they are [0, 1] intensities when the 99.9th percentile of
    the values (over an evenly strided sample of at most about 4 million values) is at most 2,
    else [0, 255].

    Parameters
    ----------
    views : ndarray, float
        The views.
    value_range : {1, 255} or None
        Forces the interpretation.

    Returns
    -------
    scale : float
        255.0 for [0, 1] views, 1.0 for [0, 255] views.
    note : str
        For ``meta["value_range"]``.

    Raises
    ------
    LfsamError
        For non-finite values, values outside [0, 255], or a ``value_range`` other than 1 or 255.
    """
    if value_range is not None and value_range not in (1, 255):
        raise LfsamError(f"value range must be 1 or 255, got {value_range!r}")
    bad = views.size - int(np.count_nonzero(np.isfinite(views)))
    if bad:
        raise LfsamError(
            f"{bad} view values are NaN or infinite; fix the light field (views must be finite)"
        )
    low, high = (float(views.min()), float(views.max())) if views.size else (0.0, 0.0)
    if low < -NEGATIVE_TOLERANCE or high > 255:
        raise LfsamError(
            f"float view values span {low:.4g}..{high:.4g}, outside [0, 255]; rescale the "
            "views to [0, 1] or [0, 255]"
        )
    if value_range is not None:
        return (255.0 if value_range == 1 else 1.0), f"[0, {value_range}] (given)"
    flat = views.reshape(-1)
    step = max(1, flat.size // 4_000_000)
    level = float(np.percentile(flat[::step], RANGE_PERCENTILE)) if flat.size else 0.0
    if level <= UNIT_RANGE_LIMIT:
        return 255.0, f"[0, 1] (auto: {RANGE_PERCENTILE}th percentile {level:.4g} <= 2)"
    return 1.0, f"[0, 255] (auto: {RANGE_PERCENTILE}th percentile {level:.4g} > 2)"


def _to_uint8(views: np.ndarray, value_range: float | None = None) -> tuple[np.ndarray, str]:
    """Convert float (see :func:`float_scale`), 16-bit and other integer views to uint8."""
    if views.dtype == np.uint16:
        return (views // 257).astype(np.uint8), ""
    if views.dtype == np.bool_:
        raise LfsamError("views are booleans; give uint8 RGB (or float) views")
    if np.issubdtype(views.dtype, np.floating):
        scale, note = float_scale(views, value_range)
        clipped = int(np.count_nonzero(views > 1.0)) if scale == 255.0 else 0
        if clipped:
            note += f"; {clipped} values above 1 clipped to 1"
        out = np.clip(np.rint(views.astype(np.float32) * scale), 0, 255).astype(np.uint8)
        return out, note
    if np.issubdtype(views.dtype, np.integer):
        if views.size and (views.min() < 0 or views.max() > 255):
            raise LfsamError(
                f"integer views must lie in 0..255, got {views.min()}..{views.max()}"
            )
        return views.astype(np.uint8), ""
    raise LfsamError(f"unsupported view dtype {views.dtype}; use uint8 RGB")

"""A figure of views with label overlays: the whole view grid, or a few chosen views.

Paper section 4.3 (Figure 2) judges a light-field segmentation on border views (top left,
middle, bottom right) next to each other: a consistent segmentation keeps each object's label
and shape from the middle view to the border views.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
from tqdm.auto import tqdm

from lfsam.errors import LfsamError
from lfsam.viz.layout import CAPTION_HEIGHT, _matching_labels, _to_numpy, caption, tile
from lfsam.viz.overlay import overlay_view

__all__ = ["VIEW_SELECTIONS", "grid_layout", "select_views", "view_grid"]

#: Names accepted by :func:`select_views`.
VIEW_SELECTIONS = ("all", "corners", "diagonal")


def select_views(
    grid_shape: tuple[int, int], which: str | Sequence[tuple[int, int]] = "all"
) -> list[tuple[int, int]]:
    """The views a figure shows.

    Parameters
    ----------
    grid_shape : (S, T)
    which : str or sequence of (s, t)
        ``"all"``: every view, row-major; ``"corners"``: top-left, top-right, center,
        bottom-left, bottom-right; ``"diagonal"``: top-left, center, bottom-right (paper
        Figure 2); or an explicit list of views. Repeated views (small grids) are kept once.

    Returns
    -------
    views : list of (s, t)
    """
    s_count, t_count = grid_shape
    center = (s_count // 2, t_count // 2)
    last = (s_count - 1, t_count - 1)
    if isinstance(which, str):
        if which == "all":
            return [(s, t) for s in range(s_count) for t in range(t_count)]
        if which == "corners":
            chosen = [(0, 0), (0, last[1]), center, (last[0], 0), last]
        elif which == "diagonal":
            chosen = [(0, 0), center, last]
        else:
            raise LfsamError(
                f"unknown view selection {which!r}; use one of {', '.join(VIEW_SELECTIONS)}"
            )
    else:
        chosen = [(int(s), int(t)) for s, t in which]
        for s, t in chosen:
            if not (0 <= s < s_count and 0 <= t < t_count):
                raise LfsamError(f"view ({s}, {t}) is outside the {s_count}x{t_count} view grid")
    return list(dict.fromkeys(chosen))


def grid_layout(
    grid_shape: tuple[int, int], which: str | Sequence[tuple[int, int]] = "all"
) -> tuple[int, int, list[tuple[int, int] | None]]:
    """Rows, columns and the view in each cell (row-major) of a :func:`view_grid` figure.

    ``"all"`` keeps the view grid's own ``S x T`` arrangement; any other selection is one row.
    """
    chosen = select_views(grid_shape, which)
    if isinstance(which, str) and which == "all":
        return grid_shape[0], grid_shape[1], list(chosen)
    return 1, len(chosen), list(chosen)


#: Frame colour of marked views (:func:`view_grid`): amber, apart from the label palette's use.
MARK_COLOR = (255, 176, 0)


def frame(image: np.ndarray, color: tuple[int, int, int], width: int | None = None) -> np.ndarray:
    """``image`` with a frame of ``color`` drawn inside its border (a copy); ``width`` defaults
    to 1/40 of the shorter side, at least 2 pixels."""
    out = np.array(image, copy=True)
    width = max(2, min(out.shape[:2]) // 40) if width is None else width
    out[:width], out[-width:], out[:, :width], out[:, -width:] = color, color, color, color
    return out


def view_grid(
    views: ArrayLike,
    labels: ArrayLike | None = None,
    *,
    which: str | Sequence[tuple[int, int]] = "all",
    alpha: float = 0.5,
    boundaries: bool = True,
    masks=None,
    pad: int = 2,
    captions: bool = False,
    background: int | tuple[int, int, int] = 255,
    progress: bool | None = None,
    marked: ArrayLike | None = None,
    mark_color: tuple[int, int, int] = MARK_COLOR,
) -> np.ndarray:
    """A figure of views with their labels overlaid.

    Parameters
    ----------
    views : (S, T, U, V, 3) array_like, uint8
    labels : (S, T, U, V) array_like of int, optional
        Label field (0 = no label); the same id has the same colour in every view.
    which : str or sequence of (s, t)
        Views to show, see :func:`select_views`; ``"all"`` keeps the grid arrangement, other
        selections form one row in the order listed.
    alpha, boundaries
        As in :func:`lfsam.viz.overlay.overlay_labels`.
    masks : object with ``view(s, t) -> (N, U, V) bool``, optional
        E.g. :class:`lfsam.result.PackedMasks`: draw every mask's outline (overlaps visible).
    pad : int
        Background pixels between and around tiles.
    captions : bool
        Put ``(s, t)`` in a strip of ``CAPTION_HEIGHT`` pixels above each tile.
    progress : bool or None
        Show a progress bar (None: only on a terminal).
    marked : (S, T) array_like of bool, optional
        Views framed in ``mark_color`` (and captioned ``(s, t) *``), e.g. the views a sparse run
        refined (a result's ``meta["refined_views"]``, docs/design.md section 3.7).
    mark_color : (r, g, b)
        Colour of the frames of ``marked`` views.

    Returns
    -------
    figure : ndarray, uint8
        Shape ``(R * (U + c) + (R + 1) * pad, C * V + (C + 1) * pad, 3)`` where ``(R, C)`` is
        :func:`grid_layout` and ``c = CAPTION_HEIGHT`` with captions, else 0.
    """
    views = _to_numpy(views)
    if views.ndim != 5 or views.shape[-1] != 3:
        raise LfsamError(f"views must have shape (S, T, U, V, 3), got {views.shape}")
    labels = _matching_labels(views, labels)
    marks = None if marked is None else np.asarray(marked, dtype=bool)
    if marks is not None and marks.shape != views.shape[:2]:
        raise LfsamError(f"marked must have shape (S, T) = {views.shape[:2]}, got {marks.shape}")
    rows, cols, cells = grid_layout(views.shape[:2], which)
    tiles: list[np.ndarray | None] = []
    bar = tqdm(cells, desc="views", unit="view", disable=None if progress is None else not progress)
    for cell in bar:
        if cell is None:
            tiles.append(None)
            continue
        s, t = cell
        image = overlay_view(views, labels, masks, s, t, alpha=alpha, boundaries=boundaries)
        is_marked = marks is not None and bool(marks[s, t])
        if is_marked:
            image = frame(image, mark_color)
        if captions:
            text = f"({s}, {t}) *" if is_marked else f"({s}, {t})"
            image = caption(image, text, height=CAPTION_HEIGHT, background=background)
        tiles.append(image)
    return tile(tiles, rows, cols, pad=pad, background=background)

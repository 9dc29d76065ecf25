"""Two segmentations of one light field in one figure (e.g. ours vs the SAM 2 video baseline).

Paper Figure 2 puts our result and the baseline's on the same views. Both panels are drawn with
the one palette of :mod:`lfsam.viz.colors`, so the same label id has the same colour in both.
Two methods number their masks independently, though; :func:`match_labels` renumbers the second
result so that each of its regions takes the id of the first result's region it overlaps most
(an optimal one-to-one assignment), which makes the same object the same colour.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
from numpy.typing import ArrayLike

from lfsam.errors import LfsamError
from lfsam.viz.animation import animation_frames
from lfsam.viz.epi import epi_figure
from lfsam.viz.grid import view_grid
from lfsam.viz.layout import CAPTION_HEIGHT, _to_numpy, caption, hstack, vstack

__all__ = ["compare_epi", "compare_frames", "compare_grid", "match_labels", "side_by_side"]


def side_by_side(
    images: Sequence[np.ndarray],
    names: Sequence[str] | None = None,
    *,
    gap: int = 8,
    direction: str = "horizontal",
    background: int | tuple[int, int, int] = 255,
) -> np.ndarray:
    """Panels next to each other (``"horizontal"``) or one above the other (``"vertical"``).

    Parameters
    ----------
    images : sequence of (h_i, w_i, 3) uint8 arrays
    names : sequence of str, optional
        A caption strip of ``CAPTION_HEIGHT`` pixels above each panel.
    gap : int
        Background pixels between panels.

    Returns
    -------
    figure : ndarray, uint8
        Horizontal: ``(max(h_i) + c, sum(w_i) + gap * (n - 1), 3)``; vertical:
        ``(sum(h_i + c) + gap * (n - 1), max(w_i), 3)``, with ``c = CAPTION_HEIGHT`` when
        ``names`` are given, else 0.

    Raises
    ------
    ValueError
        If ``names`` and ``images`` differ in length (a fault of the calling code).
    LfsamError
        If ``direction`` is neither ``"horizontal"`` nor ``"vertical"``.
    """
    images = list(images)
    if names is not None:
        if len(names) != len(images):
            raise ValueError(f"{len(names)} names for {len(images)} panels")
        images = [
            caption(im, name, height=CAPTION_HEIGHT, background=background)
            for im, name in zip(images, names, strict=True)
        ]
    if direction == "horizontal":
        return hstack(images, gap=gap, background=background)
    if direction == "vertical":
        return vstack(images, gap=gap, background=background)
    raise LfsamError(f"unknown direction {direction!r}; use horizontal or vertical")


def _check_pair(views: np.ndarray, labels_a, labels_b) -> tuple[np.ndarray, np.ndarray]:
    a, b = _to_numpy(labels_a), _to_numpy(labels_b)
    for name, labels in (("first", a), ("second", b)):
        if labels.shape != views.shape[:4]:
            raise LfsamError(
                f"the {name} labels have shape {labels.shape} but the views are "
                f"{views.shape[:4]}; compare results of the same light field"
            )
    return a, b


def _compare_figures(
    render, views, labels_a, labels_b, names, gap: int, direction: str, kwargs: dict
) -> np.ndarray:
    """``render(views, labels, **kwargs)`` for both label fields, placed side by side."""
    views = _to_numpy(views)
    a, b = _check_pair(views, labels_a, labels_b)
    panels = [render(views, lab, **kwargs) for lab in (a, b)]
    background = kwargs.get("background", 255)
    return side_by_side(panels, names, gap=gap, direction=direction, background=background)


def match_labels(reference: ArrayLike, labels: ArrayLike) -> np.ndarray:
    """Renumber ``labels`` so that its regions take the ids of the ``reference`` regions they match.

    Regions are matched one to one by maximising the total overlap in pixels (Hungarian
    algorithm, ``scipy.optimize.linear_sum_assignment``, on the contingency table of the two label
    fields); label 0 stays 0. A region with no overlapping partner keeps a fresh id above every
    reference id, so no two regions merge.

    Parameters
    ----------
    reference, labels : array_like of int, same shape
        Two label fields of the same pixels (e.g. ``(S, T, U, V)``).

    Returns
    -------
    relabeled : ndarray of int32, same shape
    """
    from scipy.optimize import linear_sum_assignment  # only here: a slow import

    ref = _to_numpy(reference).ravel()
    lab = _to_numpy(labels)
    shape = lab.shape
    lab = lab.ravel()
    if ref.shape != lab.shape:
        raise LfsamError(f"cannot match label fields of {shape} and {_to_numpy(reference).shape}")
    ref_ids, ref_inv = np.unique(ref, return_inverse=True)
    lab_ids, lab_inv = np.unique(lab, return_inverse=True)
    table = np.bincount(
        lab_inv.astype(np.int64) * len(ref_ids) + ref_inv, minlength=len(lab_ids) * len(ref_ids)
    ).reshape(len(lab_ids), len(ref_ids))
    table[lab_ids == 0] = 0  # 0 is never matched
    table[:, ref_ids == 0] = 0
    rows, cols = linear_sum_assignment(table, maximize=True)
    new_ids = np.zeros(len(lab_ids), dtype=np.int64)
    matched = table[rows, cols] > 0
    new_ids[rows[matched]] = ref_ids[cols[matched]]
    unmatched = np.flatnonzero((new_ids == 0) & (lab_ids != 0))
    start = max(int(ref_ids.max()) if ref_ids.size else 0, 0) + 1
    new_ids[unmatched] = start + np.arange(len(unmatched))
    return new_ids[lab_inv].reshape(shape).astype(np.int32)


def compare_grid(
    views: ArrayLike,
    labels_a: ArrayLike,
    labels_b: ArrayLike,
    *,
    names: Sequence[str] = ("A", "B"),
    direction: str = "horizontal",
    gap: int = 8,
    **grid_kwargs,
) -> np.ndarray:
    """Two :func:`lfsam.viz.grid.view_grid` figures of the same views, side by side.

    ``grid_kwargs`` go to ``view_grid`` (``which``, ``alpha``, ``pad``, ...). The size follows
    :func:`side_by_side` with two panels of ``view_grid``'s size.
    """
    return _compare_figures(view_grid, views, labels_a, labels_b, names, gap, direction,
                            grid_kwargs)


def compare_epi(
    views: ArrayLike,
    labels_a: ArrayLike,
    labels_b: ArrayLike,
    *,
    names: Sequence[str] = ("A", "B"),
    direction: str = "horizontal",
    gap: int = 8,
    **epi_kwargs,
) -> np.ndarray:
    """Two :func:`lfsam.viz.epi.epi_figure` figures (same row, column and upsampling), side by side.

    The size follows :func:`side_by_side` with two panels of ``epi_figure``'s size.
    """
    return _compare_figures(epi_figure, views, labels_a, labels_b, names, gap, direction,
                            epi_kwargs)


def compare_frames(
    views: ArrayLike,
    labels_a: ArrayLike,
    labels_b: ArrayLike,
    *,
    names: Sequence[str] = ("A", "B"),
    gap: int = 8,
    **frame_kwargs,
) -> Iterator[np.ndarray]:
    """Animation frames of both results side by side, in snake order.

    Yields :func:`side_by_side` of the two :func:`lfsam.viz.animation.animation_frames` of each
    view (``frame_kwargs`` go to ``animation_frames``).
    """
    views = _to_numpy(views)
    a, b = _check_pair(views, labels_a, labels_b)
    for frame_a, frame_b in zip(
        animation_frames(views, a, **frame_kwargs),
        animation_frames(views, b, **frame_kwargs),
        strict=True,
    ):
        yield side_by_side([frame_a, frame_b], names, gap=gap)

"""Prompts and napari layer data, both ways, free of Qt and napari (:mod:`lfsam.viewer.session`'s
counterpart on the layers' side): :func:`prompts_from_layers` turns the points and shapes layers'
data into an object's prompts, :func:`layers_from_prompts` gives them back to the layers,
:func:`select_labels` keeps some objects of a label field, and :class:`PromptHistory` holds the
prompt states for undo and redo.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt

__all__ = ["PromptHistory", "layers_from_prompts", "prompts_from_layers", "select_labels"]


def prompts_from_layers(
    obj_id: int,
    points: np.ndarray,
    positive: np.ndarray,
    boxes: list[np.ndarray],
    grid_shape: tuple[int, int],
    ndim: int = 4,
) -> Any | None:
    """The prompts of one object from the point and box layers' data.

    Parameters
    ----------
    obj_id : int
        Object id (>= 1).
    points : (N, ndim) float ndarray
        Points in layer coordinates ``(s, t, u, v)``: the view, then pixel row and column; a
        video's layers (``ndim`` 5) put the frame first, ``(frame, s, t, u, v)``.
    positive : (N,) bool ndarray
        Whether each point is positive.
    boxes : list of (K, ndim) float ndarrays
        Rectangles' vertices; the last one is the object's box (an object has at most one,
        docs/design.md section 8).
    grid_shape : (S, T)
        The grid, to clip view indices.
    ndim : {4, 5}
        The layers' dimensions: 5 tags each prompt with its frame (docs/design.md section 10).

    Returns
    -------
    ObjectPrompts or None
        None when there is no prompt at all.
    """

    points = np.asarray(points, dtype=float).reshape(-1, ndim)
    frames = np.rint(points[:, 0]).astype(int) if ndim == 5 else [None] * len(points)
    points = points[:, ndim - 4 :]
    positive = np.asarray(positive, dtype=bool).reshape(-1)
    limit = np.array(grid_shape) - 1
    views = np.clip(np.rint(points[:, :2]).astype(int), 0, limit)
    point_prompts = tuple(
        PointPrompt(
            x=float(p[3]), y=float(p[2]), positive=bool(pos), view=(int(v[0]), int(v[1])),
            frame=None if f is None else max(int(f), 0),
        )
        for p, pos, v, f in zip(points, positive, views, frames, strict=True)
    )
    box = None
    if boxes:
        verts = np.asarray(boxes[-1], dtype=float).reshape(-1, ndim)
        frame = max(int(np.rint(verts[0, 0])), 0) if ndim == 5 else None
        verts = verts[:, ndim - 4 :]
        s, t = np.clip(np.rint(verts[0, :2]).astype(int), 0, limit)
        (y0, x0), (y1, x1) = verts[:, 2:].min(0), verts[:, 2:].max(0)
        box = BoxPrompt(float(x0), float(y0), float(x1), float(y1), view=(int(s), int(t)),
                        frame=frame)
    if not point_prompts and box is None:
        return None
    return ObjectPrompts(obj_id, points=point_prompts, box=box)


def layers_from_prompts(
    obj: Any | None, center: tuple[int, int], ndim: int = 4
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Layer data for one object's prompts: the inverse of :func:`prompts_from_layers`.

    Parameters
    ----------
    obj : ObjectPrompts or None
        The object's prompts (None: no prompts).
    center : (s, t)
        The view of prompts without a view tag.
    ndim : {4, 5}
        5: a video's layers, each row starting with the prompt's frame (None reads as 0).

    Returns
    -------
    points : (N, ndim) float ndarray
        ``([frame,] s, t, u, v)`` of each point.
    positive : (N,) bool ndarray
    boxes : list of (4, ndim) float ndarrays
        The box's corners (zero or one rectangle).
    """
    if obj is None:
        return np.zeros((0, ndim)), np.zeros(0, dtype=bool), []

    def lead(prompt: Any) -> tuple:
        view = prompt.view if prompt.view is not None else center
        frame = 0 if prompt.frame is None else int(prompt.frame)
        return (frame, *view) if ndim == 5 else tuple(view)

    points = np.array([(*lead(p), p.y, p.x) for p in obj.points], dtype=float)
    points = points.reshape(-1, ndim)
    positive = np.array([bool(p.positive) for p in obj.points], dtype=bool)
    boxes = []
    if obj.box is not None:
        b, head = obj.box, lead(obj.box)
        corners = [(b.y0, b.x0), (b.y0, b.x1), (b.y1, b.x1), (b.y1, b.x0)]
        boxes.append(np.array([(*head, y, x) for y, x in corners], dtype=float))
    return points, positive, boxes


def select_labels(labels: np.ndarray, ids: set[int] | list[int]) -> np.ndarray:
    """``labels`` where the label is one of ``ids``, 0 elsewhere (for one display layer)."""
    ids = sorted(ids)
    if not ids:
        return np.zeros_like(labels)
    return np.where(np.isin(labels, ids), labels, 0).astype(labels.dtype, copy=False)


class PromptHistory:
    """Undo and redo of the prompt edits of the object being edited.

    Each state is an ``ObjectPrompts`` (or None for no prompts); :meth:`push` records a new state
    after an edit and drops the redo branch.
    """

    def __init__(self) -> None:
        self._states: list[Any | None] = [None]
        self._index = 0

    def reset(self, state: Any | None = None) -> None:
        """Forget the history; ``state`` is the current one."""
        self._states = [state]
        self._index = 0

    @property
    def current(self) -> Any | None:
        """The current state."""
        return self._states[self._index]

    def push(self, state: Any | None) -> bool:
        """Record ``state`` after an edit; returns False if it equals the current state."""
        if state == self.current:
            return False
        del self._states[self._index + 1 :]
        self._states.append(state)
        self._index += 1
        return True

    @property
    def can_undo(self) -> bool:
        """Whether there is an edit to undo."""
        return self._index > 0

    @property
    def can_redo(self) -> bool:
        """Whether there is an undone edit to redo."""
        return self._index < len(self._states) - 1

    def undo(self) -> Any | None:
        """Step back; returns the state to show."""
        if self.can_undo:
            self._index -= 1
        return self.current

    def redo(self) -> Any | None:
        """Step forward; returns the state to show."""
        if self.can_redo:
            self._index += 1
        return self.current

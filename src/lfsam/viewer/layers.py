"""The widget's fixed set of layers (as in micro-sam) and the view/EPI axis orders.

Layers (docs/design.md section 8), all with the light field's ``(s, t, u, v)`` dimensions (a
video's with ``(frame, s, t, u, v)``: prompts carry their frame, and the mask layers are lazy
:class:`lfsam.viewer.video.FrameStore` objects written one frame at a time):

- ``point prompts``: points with a boolean ``positive`` feature (green positive, red negative);
- ``box prompts``: rectangles (the object's box is the last one);
- ``current object``: the mask of the object being edited (label value = object id);
- ``committed objects``: every committed object;
- ``automatic segmentation``: the objects found by "segment everything".

An epipolar-plane image (EPI) is a reorder of the same data's axes (``viewer.dims.order``): the
horizontal EPI through the current pixel row ``u`` of view row ``s`` shows ``(t, v)``; the vertical
EPI through pixel column ``v`` of view column ``t`` shows ``(u, s)``.

The current object's prompts live in the point and box layers; :class:`PromptLayers` converts
them to and from :class:`lfsam.prompts.ObjectPrompts` (through :mod:`lfsam.viewer.session`'s
Qt-free functions) and reports the user's edits. :class:`MaskLayers` paints predictions into the
three mask layers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from lfsam.viewer.prompt_layers import layers_from_prompts, prompts_from_layers, select_labels

__all__ = [
    "AUTO",
    "BOXES",
    "COMMITTED",
    "CURRENT",
    "LAYER_NAMES",
    "MASK_NAMES",
    "ORDERS",
    "POINTS",
    "MaskLayers",
    "PromptLayers",
    "make_layer",
]

POINTS = "point prompts"
BOXES = "box prompts"
CURRENT = "current object"
COMMITTED = "committed objects"
AUTO = "automatic segmentation"

#: Bottom to top.
LAYER_NAMES = (AUTO, COMMITTED, CURRENT, BOXES, POINTS)
#: The mask layers (label = object id).
MASK_NAMES = (AUTO, COMMITTED, CURRENT)

#: ``viewer.dims.order`` of each display: the last two axes are shown.
ORDERS = {
    "views": (0, 1, 2, 3),
    "epi-row": (0, 2, 1, 3),
    "epi-column": (1, 3, 2, 0),
}

POSITIVE_COLOR = "#00ff00"
NEGATIVE_COLOR = "#ff2020"


def make_layer(name: str, shape: tuple[int, ...]) -> Any:
    """A new, empty layer ``name`` (one of :data:`LAYER_NAMES`) for a light field of ``shape``.

    Parameters
    ----------
    name : str
        Which layer.
    shape : (S, T, U, V) or (F, S, T, U, V)
        The light field's dimensions, or a video's (docs/design.md section 10).

    Returns
    -------
    napari.layers.Layer

    Raises
    ------
    ValueError
        For a name not in :data:`LAYER_NAMES` (the caller's code is at fault).
    """
    import pandas as pd
    from napari.layers import Labels, Points, Shapes

    from lfsam.viewer.video import VIDEO_AXES, FrameStore

    ndim = len(shape)
    axis_labels = VIDEO_AXES[-ndim:]
    if name == POINTS:
        layer = Points(
            np.zeros((0, ndim)),
            ndim=ndim,
            name=POINTS,
            features={"positive": pd.Series([], dtype=bool)},
            face_color="positive",
            face_color_cycle={True: POSITIVE_COLOR, False: NEGATIVE_COLOR},
            border_color="white",
            size=max(4, min(shape[-2:]) // 40),
            axis_labels=axis_labels,
            out_of_slice_display=False,
        )
        layer.feature_defaults = {"positive": True}
        return layer
    if name == BOXES:
        return Shapes(
            ndim=ndim,
            name=BOXES,
            face_color="transparent",
            edge_color="#00c8ff",
            edge_width=max(1, min(shape[-2:]) // 120),
            axis_labels=axis_labels,
        )
    if name in (CURRENT, COMMITTED, AUTO):
        opacity = {CURRENT: 0.6, COMMITTED: 0.45, AUTO: 0.35}[name]
        data = FrameStore(shape) if ndim == 5 else np.zeros(shape, dtype=np.int32)
        return Labels(data, name=name, opacity=opacity, axis_labels=axis_labels)
    raise ValueError(f"unknown layer {name!r}")


class PromptLayers:
    """The point and box layers as the current object's prompts.

    Sets the polarity of clicked points (Ctrl-click: the other one), reads the layers as
    prompts, writes prompts into them, and reports the user's edits (not its own writes).

    Parameters
    ----------
    layers : dict
        The fixed layers by name (filled in later is fine: :meth:`attach` once they exist).
    on_edit : callable
        Called after the user added, removed or changed a point or a box.

    Attributes
    ----------
    negative : bool
        Whether plain clicks add negative points.
    """

    def __init__(self, layers: dict[str, Any], on_edit: Callable[[], None]) -> None:
        self.layers = layers
        self.negative = False
        self._on_edit = on_edit
        self._writing = False

    def attach(self) -> None:
        """Listen to the newly made prompt layers; clicks add points from now on."""
        points = self.layers[POINTS]
        points.mouse_drag_callbacks.insert(0, self._on_press)
        points.events.data.connect(self._on_data)
        self.layers[BOXES].events.data.connect(self._on_data)
        points.mode = "add"
        self.set_negative(self.negative)

    def set_negative(self, negative: bool) -> None:
        """Plain clicks add negative points (True) or positive ones."""
        self.negative = negative
        if POINTS in self.layers:
            self.layers[POINTS].feature_defaults = {"positive": not negative}

    def _on_press(self, layer: Any, event: Any) -> None:
        """Before napari adds a clicked point: its polarity."""
        if layer.mode != "add":
            return
        modifiers = getattr(event, "modifiers", ())
        flip = "Control" in modifiers or "Meta" in modifiers  # vispy keys compare to names
        layer.feature_defaults = {"positive": self.negative == flip}

    def _on_data(self, event: Any) -> None:
        action = str(getattr(event, "action", "changed"))
        if not self._writing and action.endswith(("added", "removed", "changed")):
            self._on_edit()

    def read(self, obj_id: int, grid_shape: tuple[int, int]) -> Any | None:
        """Object ``obj_id``'s prompts from the layers (boxes: their rectangles).

        Parameters
        ----------
        obj_id : int
        grid_shape : (S, T)

        Returns
        -------
        ObjectPrompts or None
            None when the layers hold no prompt.
        """

        points = self.layers[POINTS]
        boxes = self.layers[BOXES]
        positive = (
            points.features["positive"].to_numpy(dtype=bool)
            if len(points.data)
            else np.zeros(0, dtype=bool)
        )
        rects = [
            d for d, kind in zip(boxes.data, boxes.shape_type, strict=True) if kind == "rectangle"
        ]
        return prompts_from_layers(obj_id, points.data, positive, rects, grid_shape,
                                   ndim=points.ndim)

    def write(self, obj: Any | None, center: tuple[int, int]) -> None:
        """Show ``obj``'s prompts (None: none) in the layers, replacing theirs.

        Parameters
        ----------
        obj : ObjectPrompts or None
        center : (s, t)
            The view of prompts without a view tag.
        """

        points, positive, boxes = layers_from_prompts(obj, center, self.layers[POINTS].ndim)
        self._writing = True
        try:
            layer = self.layers[POINTS]
            layer.data = points
            layer.features = {"positive": positive}
            if hasattr(layer, "refresh_colors"):
                layer.refresh_colors()
            shapes = self.layers[BOXES]
            shapes.data = []
            if boxes:
                shapes.add_rectangles(boxes)
        finally:
            self._writing = False
        self.set_negative(self.negative)


class MaskLayers:
    """What the mask layers show: the current object, the committed and the automatic ones.

    Parameters
    ----------
    layers : dict
        The fixed layers by name (filled in later is fine: it is read at each call).

    Attributes
    ----------
    prediction : LightFieldPrediction or None
        The last prediction shown (its masks are unpacked lazily, by :meth:`mask_of`).
    """

    def __init__(self, layers: dict[str, Any], frame: Callable[[], int] = lambda: 0) -> None:
        self.layers = layers
        self.prediction: Any = None
        self._frame = frame

    def array(self, name: str) -> np.ndarray:
        """Mask layer ``name``'s labels ``(S, T, U, V)``, writable in place: a video's are
        those of the frame the predictor works on (``frame``)."""
        data = self.layers[name].data
        if hasattr(data, "frame_array"):  # a video's FrameStore
            return data.frame_array(self._frame())
        return data

    def show_labels(self, name: str, labels: np.ndarray) -> None:
        """Replace mask layer ``name``'s labels by ``labels`` ``(S, T, U, V)``."""
        self.array(name)[...] = labels
        self.layers[name].refresh()

    def clear_frame(self, name: str, index: int) -> None:
        """A video: nothing in mask layer ``name`` at frame ``index``."""
        data = self.layers[name].data
        if index in data.written():
            data.frame_array(index)[...] = 0
            self.layers[name].refresh()

    def show_frame(self, index: int, labels: np.ndarray) -> None:
        """A video: frame ``index`` of every object (a tracked frame) in the committed layer;
        the current object's layer is cleared there."""
        self.layers[COMMITTED].data.put(index, labels)
        self.layers[COMMITTED].refresh()
        self.clear_frame(CURRENT, index)

    def show_current(
        self,
        obj_id: int,
        *,
        view: tuple[int, int] | None = None,
        mask: np.ndarray | None = None,
        masks: np.ndarray | None = None,
    ) -> None:
        """The current object's layer: ``mask`` in ``view`` only, ``masks`` in every view, or
        nothing (neither given)."""
        data = self.array(CURRENT)
        data[...] = 0
        if view is not None and mask is not None:
            data[view][mask] = obj_id
        elif masks is not None:
            data[np.asarray(masks, dtype=bool)] = obj_id
        self.layers[CURRENT].refresh()

    def show_prediction(self, prediction: Any, committed: set[int], auto: set[int]) -> None:
        """Show ``prediction``'s ``committed`` and ``auto`` objects (not the current one)."""

        self.prediction = prediction
        labels = np.asarray(prediction.labels)
        self.show_labels(COMMITTED, select_labels(labels, committed))
        self.show_labels(AUTO, select_labels(labels, auto))

    def mask_of(self, obj_id: int) -> np.ndarray | None:
        """Object ``obj_id``'s mask in the last prediction, ``(S, T, U, V)`` bool, or None."""
        if self.prediction is None or obj_id not in self.prediction.masks:
            return None
        return np.asarray(self.prediction.masks[obj_id], dtype=bool)

    def composite(self) -> np.ndarray:
        """Every object as the mask layers show it, ``(S, T, U, V)`` int32: the current object
        over the committed ones over the automatic ones (a copy)."""
        return self._joined(self.array)

    def composite_at(self, frame: int) -> np.ndarray:
        """:meth:`composite` of a video's frame ``frame``, read without storing anything (any
        thread: the 3D dock's poses read every frame in their own); a single light field's
        :meth:`composite` for any ``frame``."""
        def read(name: str) -> np.ndarray:
            data = self.layers[name].data
            return data[int(frame)] if hasattr(data, "frame_array") else data

        return self._joined(read)

    @staticmethod
    def _joined(read: Callable[[str], np.ndarray]) -> np.ndarray:
        labels = np.array(read(AUTO), dtype=np.int32)
        for name in (COMMITTED, CURRENT):
            layer = np.asarray(read(name))
            labels[layer != 0] = layer[layer != 0]
        return labels

    def shown(self, obj_id: int) -> np.ndarray:
        """Where the committed or automatic layer shows object ``obj_id``, ``(S, T, U, V)``."""
        return (self.array(COMMITTED) == obj_id) | (self.array(AUTO) == obj_id)

    def erase(self, obj_id: int, names: tuple[str, ...] = MASK_NAMES) -> None:
        """Remove object ``obj_id`` from the mask layers ``names``."""
        for name in names:
            data = self.array(name)
            data[data == obj_id] = 0
            self.layers[name].refresh()

    def recommit(self, obj_id: int) -> None:
        """Show object ``obj_id``'s last predicted mask in the committed layer again, where the
        layer shows no other object (it has just stopped being the current object)."""
        mask = self.mask_of(obj_id)
        if mask is not None:
            data = self.array(COMMITTED)
            data[mask & (data == 0)] = obj_id
            self.layers[COMMITTED].refresh()

"""The widget's fixed set of layers (as in micro-sam) and the view/EPI axis orders.

Layers (docs/design.md section 8), all with the light field's ``(s, t, u, v)`` dimensions:

- ``point prompts``: points with a boolean ``positive`` feature (green positive, red negative);
- ``box prompts``: rectangles (the object's box is the last one);
- ``current object``: the mask of the object being edited (label value = object id);
- ``committed objects``: every committed object;
- ``automatic segmentation``: the objects found by "segment everything".

An epipolar-plane image (EPI) is a reorder of the same data's axes (``viewer.dims.order``): the
horizontal EPI through the current pixel row ``u`` of view row ``s`` shows ``(t, v)``; the vertical
EPI through pixel column ``v`` of view column ``t`` shows ``(u, s)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "AUTO",
    "BOXES",
    "COMMITTED",
    "CURRENT",
    "LAYER_NAMES",
    "ORDERS",
    "POINTS",
    "make_layer",
]

POINTS = "point prompts"
BOXES = "box prompts"
CURRENT = "current object"
COMMITTED = "committed objects"
AUTO = "automatic segmentation"

#: Bottom to top.
LAYER_NAMES = (AUTO, COMMITTED, CURRENT, BOXES, POINTS)

#: ``viewer.dims.order`` of each display: the last two axes are shown.
ORDERS = {
    "views": (0, 1, 2, 3),
    "epi-row": (0, 2, 1, 3),
    "epi-column": (1, 3, 2, 0),
}

POSITIVE_COLOR = "#00ff00"
NEGATIVE_COLOR = "#ff2020"


def make_layer(name: str, shape: tuple[int, int, int, int]) -> Any:
    """A new, empty layer ``name`` (one of :data:`LAYER_NAMES`) for a light field of ``shape``.

    Parameters
    ----------
    name : str
        Which layer.
    shape : (S, T, U, V)
        The light field's dimensions.

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

    axis_labels = ("s", "t", "u", "v")
    if name == POINTS:
        layer = Points(
            np.zeros((0, 4)),
            ndim=4,
            name=POINTS,
            features={"positive": pd.Series([], dtype=bool)},
            face_color="positive",
            face_color_cycle={True: POSITIVE_COLOR, False: NEGATIVE_COLOR},
            border_color="white",
            size=max(4, min(shape[2:]) // 40),
            axis_labels=axis_labels,
            out_of_slice_display=False,
        )
        layer.feature_defaults = {"positive": True}
        return layer
    if name == BOXES:
        return Shapes(
            ndim=4,
            name=BOXES,
            face_color="transparent",
            edge_color="#00c8ff",
            edge_width=max(1, min(shape[2:]) // 120),
            axis_labels=axis_labels,
        )
    if name in (CURRENT, COMMITTED, AUTO):
        opacity = {CURRENT: 0.6, COMMITTED: 0.45, AUTO: 0.35}[name]
        return Labels(
            np.zeros(shape, dtype=np.int32), name=name, opacity=opacity, axis_labels=axis_labels
        )
    raise ValueError(f"unknown layer {name!r}")

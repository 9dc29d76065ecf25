"""Which layer is the light field, and keeping the widget's fixed layers in the viewer.

The dock widget (:mod:`lfsam.viewer.widget`) works on one light field shown as an image layer,
with the fixed prompt and mask layers of :mod:`lfsam.viewer.layers` on top (docs/design.md
section 8). This module:

- finds the light field an image layer holds (:func:`lightfield_of`): one read by this plugin
  carries it in its metadata; any ``(S, T, U, V, 3)`` RGB image is one too;
- adds the light field's layers and the fixed layers (:meth:`LayerKeeper.show`);
- finds the result a labels layer holds, to reopen it for correction (:func:`result_to_reopen`);
- offers layers added later to the widget while it has no light field (a light field opened
  with File > Open after the dock), and puts back a fixed layer the user deletes, in its place
  (:class:`LayerKeeper`), until the light field itself is removed or the viewer closes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np
from qtpy.QtCore import QTimer

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.viewer import layers as L
from lfsam.viewer.plugin_io import LIGHTFIELD_KEY, RESULT_KEY, lightfield_layers

__all__ = ["LayerKeeper", "lightfield_of", "result_to_reopen", "video_of"]


def lightfield_of(layer: Any) -> LightField | None:
    """The light field ``layer`` shows, or None if it is not an image layer of one.

    Parameters
    ----------
    layer : napari.layers.Layer

    Returns
    -------
    LightField or None
        The one in the layer's metadata (this plugin's reader puts it there), else one made of
        a ``(S, T, U, V, 3)`` RGB image's data.
    """
    from napari.layers import Image

    if not isinstance(layer, Image):
        return None
    lightfield = layer.metadata.get(LIGHTFIELD_KEY)
    if lightfield is not None:
        return lightfield
    data = layer.data
    if not (layer.rgb and getattr(data, "ndim", 0) == 5 and data.shape[-1] == 3):
        return None
    try:
        return LightField(views=np.asarray(data))
    except LfsamError:
        return None


def video_of(layer: Any) -> Any:
    """The light-field video ``layer`` shows (this plugin's reader keeps it in the metadata),
    or None (docs/design.md section 10)."""
    from napari.layers import Image

    from lfsam.viewer.video import VIDEO_KEY

    return layer.metadata.get(VIDEO_KEY) if isinstance(layer, Image) else None


def result_to_reopen(layer: Any, fixed: Iterable[Any]) -> Any:
    """The result a labels layer shows, to reopen its objects for correction.

    Parameters
    ----------
    layer : napari.layers.Layer or None
        The layer (the one selected in the viewer).
    fixed : iterable of layers
        The widget's own layers, which are not reopened.

    Returns
    -------
    SegmentationResult
        The one read by this plugin (in the layer's metadata, prompts included), else one made
        of the layer's labels (label = object id).

    Raises
    ------
    LfsamError
        If ``layer`` is not a labels layer, or is one of ``fixed``.
    """
    from napari.layers import Labels

    from lfsam.result import SegmentationResult

    if not isinstance(layer, Labels) or any(layer is own for own in fixed):
        raise LfsamError("select a labels layer of this light field (not one of the widget's)")
    result = layer.metadata.get(RESULT_KEY)
    if result is None:
        result = SegmentationResult(labels=np.asarray(layer.data, dtype=np.int32))
    return result


class LayerKeeper:
    """The light field's image layer and the fixed layers, kept in a napari viewer.

    Parameters
    ----------
    viewer : napari.Viewer
    adopt : callable
        Called with each layer inserted into the viewer, other than the keeper's own, while
        there is no light field yet; returns whether it took the layer as its light field.

    Attributes
    ----------
    image_layer : napari.layers.Image or None
        The light field's layer.
    layers : dict
        The fixed layers by name (:data:`lfsam.viewer.layers.LAYER_NAMES`).
    closing : bool
        Set when the light field's layer is removed or the widget closes: deleted layers are no
        longer put back.
    """

    def __init__(self, viewer: Any, adopt: Callable[[Any], bool]) -> None:
        self.viewer = viewer
        self.image_layer: Any = None
        self.layers: dict[str, Any] = {}
        self.closing = False
        self._adopt = adopt
        self._adding = False  # the keeper's own layers are being added
        viewer.layers.events.removed.connect(self._on_removed)
        viewer.layers.events.inserted.connect(self._on_inserted)

    def adopt_existing(self) -> bool:
        """Offer the viewer's layers, bottom first, until one is adopted; whether one was."""
        return any(self._adopt(layer) for layer in list(self.viewer.layers))

    def show(
        self,
        lightfield: Any,
        layer: Any = None,
        keymap: Mapping[str, Callable[[], None]] | None = None,
    ) -> dict[str, Any]:
        """Show ``lightfield`` (as ``layer``, or new layers) and add the fixed layers.

        Parameters
        ----------
        lightfield : LightField or LightFieldVideo
            A video's layers get the frame axis first (docs/design.md section 10).
        layer : napari.layers.Image, optional
            The layer already showing it; default: add the plugin's layers (the views, and the
            ground truth hidden).
        keymap : mapping, optional
            Keys bound on every fixed layer (napari sends a key to the active layer first).

        Returns
        -------
        dict
            :attr:`layers`.
        """
        from lfsam.viewer.video import video_layers

        is_video = not isinstance(lightfield, LightField)
        self._adding = True
        try:
            if layer is None:
                made = video_layers(lightfield) if is_video else lightfield_layers(lightfield)
                for data, kwargs, kind in made:
                    added = getattr(self.viewer, f"add_{kind}")(data, **kwargs)
                    if kind == "image":
                        layer = added
            self.image_layer = layer
            shape = lightfield.shape if is_video else lightfield.views.shape[:4]
            for name in L.LAYER_NAMES:
                fixed = L.make_layer(name, shape)
                self.viewer.layers.append(fixed)
                for key, func in (keymap or {}).items():
                    fixed.bind_key(key, lambda _layer, f=func: f(), overwrite=True)
                self.layers[name] = fixed
        finally:
            self._adding = False
        return self.layers

    @contextmanager
    def aside(self) -> Iterator[None]:
        """Add layers in this block without offering them to the widget (the layers of a
        followed stream, :mod:`lfsam.viewer.follow_dock`, are not its light field)."""
        adding, self._adding = self._adding, True
        try:
            yield
        finally:
            self._adding = adding

    def _on_inserted(self, event: Any) -> None:
        if self.image_layer is None and not self._adding:
            self._adopt(event.value)

    def _on_removed(self, event: Any) -> None:
        layer = event.value
        if layer is self.image_layer:
            self.closing = True  # the light field is gone: stop re-creating layers
        if self.closing or layer not in self.layers.values():
            return
        # a fixed layer was deleted: put it back (after napari has finished removing it)
        index = getattr(event, "index", None)
        QTimer.singleShot(0, lambda: self.restore(layer, index))

    def restore(self, layer: Any, index: int | None = None) -> None:
        """Put the deleted fixed ``layer`` back at ``index`` (default on top)."""
        # not while the viewer closes (it removes every layer, the light field's too)
        layers = self.viewer.layers
        if self.closing or self.image_layer not in layers or layer in layers:
            return
        layers.insert(len(layers) if index is None else min(index, len(layers)), layer)

"""The dock widget: click to segment a light field in napari, correct, commit, save.

A thin Qt layer over :class:`lfsam.viewer.session.ViewerSession` (which drives
:class:`lfsam.predictor.LightFieldPredictor`; docs/design.md section 8). Everything slow (loading
the model, encoding, prediction, automatic segmentation) runs in a napari worker thread with a
progress bar; actions asked for meanwhile are queued, so the interface never blocks. A prediction
shows the prompted view's mask first, then the coarse masks of all views, then the refined ones.

Keys (as in micro-sam): ``S`` segment, ``C`` commit the current object, ``T`` toggle positive /
negative clicks (Ctrl-click adds a point of the other polarity), ``Shift-C`` clear the current
object, ``Ctrl-Z`` / ``Ctrl-Shift-Z`` undo / redo prompt edits.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from qtpy.QtCore import QTimer, Signal
from qtpy.QtWidgets import (
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.references import REFERENCE_MODES
from lfsam.segmenters.registry import ORACLE
from lfsam.viewer import layers as L
from lfsam.viewer.native_libraries import preload_native_libraries
from lfsam.viewer.plugin_io import LIGHTFIELD_KEY, RESULT_KEY, SESSION_KEY, lightfield_layers
from lfsam.viewer.session import (
    DISPARITY_SOURCES,
    ViewerSession,
    layers_from_prompts,
    prompts_from_layers,
    select_labels,
)

__all__ = ["LightFieldWidget"]

_FILE_ITEM = "file…"
#: The weights box: the model hub's trained weights (cached), untrained ones, or a .pt file.
_HUB_WEIGHTS = "trained (hub cache)"
_RANDOM_WEIGHTS = "random (tests only)"


def _choose_item(box: QComboBox, text: str) -> None:
    """Select ``text`` in ``box``, inserting it before the last item ("file…") if it is new."""
    if box.findText(text) < 0:
        box.insertItem(box.count() - 1, text)
    box.setCurrentText(text)


def _notify_error(message: str) -> None:
    from napari.utils.notifications import show_error

    show_error(message)


def _guarded(func: Callable[[], Iterator[tuple]]) -> Callable[[], Iterator[tuple]]:
    """Run ``func`` in the worker; an LfsamError becomes an ("error", ...) item, not a raise."""

    def run() -> Iterator[tuple]:
        try:
            yield from func()
        except LfsamError as exc:
            yield ("error", None, str(exc))

    return run


class LightFieldWidget(QWidget):
    """Segment the light field shown in a napari viewer.

    Parameters
    ----------
    napari_viewer : napari.Viewer
        The viewer (napari passes it when the widget is opened from the Plugins menu).
    lightfield : LightField, optional
        The light field; default: the first image layer that holds one (read by this plugin) or
        any ``(S, T, U, V, 3)`` RGB image layer. Added as a layer if it is not shown yet.
    model : str, optional
        Segmenter (default the package's default SAM 2 model); ``"oracle"`` answers from the
        light field's ground-truth labels.
    disparity : str or path, optional
        ``"estimate"`` (default), ``"gt"`` or a ``.npy`` file.
    cache_dir : path, optional
        Embedding cache of the predictor.
    segmenter_options : dict, optional
        Further keywords of :func:`lfsam.segmenters.load_segmenter` (e.g. ``oracle_options``).
    autoload : bool
        Load the model as soon as a light field is known.
    """

    #: Emitted with every status line the dock shows (``lfsam view`` echoes them on stderr).
    status_changed = Signal(str)

    def __init__(
        self,
        napari_viewer: Any,
        *,
        lightfield: LightField | None = None,
        model: str | None = None,
        disparity: str | os.PathLike | None = None,
        cache_dir: str | os.PathLike | None = None,
        segmenter_options: dict[str, Any] | None = None,
        autoload: bool = True,
    ) -> None:
        super().__init__()
        from lfsam.segmenters import available_models
        from lfsam.segmenters.registry import DEFAULT_MODEL

        preload_native_libraries()  # here, in the main thread, not in the worker (module doc)

        self.viewer = napari_viewer
        self.session: ViewerSession | None = None
        self.image_layer: Any = None
        self.layers: dict[str, Any] = {}
        self.negative = False  # polarity of plain clicks (T toggles)
        self.worker: Any = None
        self._queue: list[Callable[[], None]] = []
        self._segment_pending = False
        self._syncing = False
        self._closing = False
        self.stages: list[str] = []  # stages shown by the last segmentation, in order
        self._prediction: Any = None  # the last LightFieldPrediction (masks unpacked lazily)
        self._options = dict(segmenter_options or {})
        self._cache_dir = cache_dir
        self._autoload = autoload

        # --- controls ---------------------------------------------------------------------
        self.model_box = QComboBox()
        self.model_box.addItems(available_models())
        self.model_box.setCurrentText(model or DEFAULT_MODEL)
        self.weights_box = QComboBox()
        self.weights_box.addItems([_HUB_WEIGHTS, _RANDOM_WEIGHTS, _FILE_ITEM])
        self.weights_box.setToolTip(
            "SAM 2 weights: the model hub's (downloaded once into the cache), untrained ones "
            "of the same architecture, or a checkpoint file (Meta's .pt) of the chosen model"
        )
        if self._options.get("checkpoint"):
            _choose_item(self.weights_box, str(self._options["checkpoint"]))
        elif self._options.get("random_weights"):
            self.weights_box.setCurrentText(_RANDOM_WEIGHTS)
        self.disparity_box = QComboBox()
        self.disparity_box.addItems([*DISPARITY_SOURCES, _FILE_ITEM])
        if disparity is not None:
            _choose_item(self.disparity_box, str(disparity))
        self.references_box = QComboBox()
        self.references_box.addItems(list(REFERENCE_MODES))
        self.references_box.setToolTip(
            "Segment everything from the center view (the paper's setting), or also from the "
            "corner views, the outer ring or every view, to find objects the center cannot see"
        )
        self.load_button = QPushButton("Load model")
        self.polarity_label = QLabel()
        self.segment_button = QPushButton("Segment [S]")
        self.commit_button = QPushButton("Commit [C]")
        self.clear_button = QPushButton("Clear [Shift-C]")
        self.undo_button = QPushButton("Undo [Ctrl-Z]")
        self.redo_button = QPushButton("Redo [Ctrl-Shift-Z]")
        self.toggle_button = QPushButton("Toggle +/- [T]")
        self.everything_button = QPushButton("Segment everything")
        self.objects = QListWidget()
        self.edit_button = QPushButton("Edit selected")
        self.remove_button = QPushButton("Remove selected")
        self.open_labels_button = QPushButton("Reopen selected labels layer")
        self.view_buttons = {
            "views": QPushButton("Views"),
            "epi-row": QPushButton("EPI (row)"),
            "epi-column": QPushButton("EPI (column)"),
        }
        self.save_button = QPushButton("Save result…")
        self.export_button = QPushButton("Export…")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.status = QLabel("")
        self.status.setWordWrap(True)

        form = QFormLayout()
        form.addRow("Model", self.model_box)
        form.addRow("Weights", self.weights_box)
        form.addRow("Disparity", self.disparity_box)
        form.addRow("Everything from", self.references_box)
        grid = QGridLayout()
        buttons = [
            self.segment_button, self.commit_button, self.toggle_button, self.clear_button,
            self.undo_button, self.redo_button,
        ]
        for i, button in enumerate(buttons):
            grid.addWidget(button, i // 2, i % 2)
        views = QHBoxLayout()
        for button in self.view_buttons.values():
            views.addWidget(button)
        objects_row = QHBoxLayout()
        objects_row.addWidget(self.edit_button)
        objects_row.addWidget(self.remove_button)
        files_row = QHBoxLayout()
        files_row.addWidget(self.save_button)
        files_row.addWidget(self.export_button)
        layout = QVBoxLayout()
        layout.addLayout(form)
        layout.addWidget(self.load_button)
        layout.addWidget(self.polarity_label)
        layout.addLayout(grid)
        layout.addWidget(self.everything_button)
        layout.addWidget(QLabel("Objects (double-click to edit)"))
        layout.addWidget(self.objects)
        layout.addLayout(objects_row)
        layout.addWidget(self.open_labels_button)
        layout.addLayout(views)
        layout.addLayout(files_row)
        layout.addWidget(self.progress)
        layout.addWidget(self.status)
        layout.addStretch(1)
        self.setLayout(layout)

        self.load_button.clicked.connect(self.load_model)
        self.model_box.currentTextChanged.connect(self._on_model_changed)
        self._on_model_changed(self.model_box.currentText())
        self.weights_box.activated.connect(self._on_weights_activated)
        self.disparity_box.activated.connect(self._on_disparity_activated)
        self.segment_button.clicked.connect(self.segment)
        self.commit_button.clicked.connect(self.commit)
        self.clear_button.clicked.connect(self.clear)
        self.undo_button.clicked.connect(self.undo)
        self.redo_button.clicked.connect(self.redo)
        self.toggle_button.clicked.connect(self.toggle_polarity)
        self.everything_button.clicked.connect(self.segment_everything)
        self.objects.itemDoubleClicked.connect(self._on_object_double_clicked)
        self.edit_button.clicked.connect(self._edit_selected)
        self.remove_button.clicked.connect(self._remove_selected)
        self.open_labels_button.clicked.connect(self._open_selected_labels)
        for name, button in self.view_buttons.items():
            button.clicked.connect(lambda _=False, n=name: self.show_display(n))
        self.save_button.clicked.connect(self._save_dialog)
        self.export_button.clicked.connect(self._export_dialog)
        self.export_button.setEnabled(_export_module() is not None)
        self._update_polarity()

        self.viewer.layers.events.removed.connect(self._on_layer_removed)
        self.viewer.layers.events.inserted.connect(self._on_layer_inserted)
        for key, func in self._keymap().items():
            self.viewer.bind_key(key, lambda _v, f=func: f(), overwrite=True)

        if lightfield is not None:
            self.set_lightfield(lightfield)
        else:
            for layer in list(self.viewer.layers):
                if self._adopt(layer):
                    break

    # --- set-up -------------------------------------------------------------------------------
    def _keymap(self) -> dict[str, Callable[[], None]]:
        return {
            "s": self.segment,
            "c": self.commit,
            "t": self.toggle_polarity,
            "Shift-c": self.clear,
            "Control-z": self.undo,
            "Control-Shift-z": self.redo,
        }

    def _adopt(self, layer: Any) -> bool:
        """Use ``layer`` as the light field if it is one; returns whether it was adopted."""
        from napari.layers import Image

        if self.session is not None or not isinstance(layer, Image):
            return False
        lightfield = layer.metadata.get(LIGHTFIELD_KEY)
        if lightfield is None:
            data = layer.data
            if not (layer.rgb and getattr(data, "ndim", 0) == 5 and data.shape[-1] == 3):
                return False
            try:
                lightfield = LightField(views=np.asarray(data))
            except LfsamError:
                return False
        self.set_lightfield(lightfield, layer)
        return True

    def set_lightfield(self, lightfield: LightField, layer: Any = None) -> None:
        """Show ``lightfield`` (one image layer) and create the prompt and mask layers."""
        self._syncing = True  # the layers added here are not new light fields to adopt
        try:
            if layer is None:
                for data, kwargs, kind in lightfield_layers(lightfield):
                    added = getattr(self.viewer, f"add_{kind}")(data, **kwargs)
                    if kind == "image":
                        layer = added
        finally:
            self._syncing = False
        self.image_layer = layer
        self.session = ViewerSession(
            lightfield,
            model=self.model_box.currentText(),
            disparity=self._disparity_value(),
            cache_dir=self._cache_dir,
            segmenter_options=dict(self._options),
        )
        shape = lightfield.views.shape[:4]
        for name in L.LAYER_NAMES:
            self.layers[name] = self._add_layer(L.make_layer(name, shape))
        self.layers[L.COMMITTED].metadata[SESSION_KEY] = self.session
        points = self.layers[L.POINTS]
        points.mouse_drag_callbacks.insert(0, self._on_points_press)
        points.events.data.connect(self._on_prompts_edited)
        self.layers[L.BOXES].events.data.connect(self._on_prompts_edited)
        center = lightfield.center
        self.viewer.dims.current_step = (*center, *self.viewer.dims.current_step[2:])
        self.viewer.layers.selection.active = points
        points.mode = "add"
        self._update_polarity()
        self._refresh_objects()
        if self._autoload:
            self.load_model()

    def _add_layer(self, layer: Any) -> Any:
        self.viewer.layers.append(layer)
        for key, func in self._keymap().items():
            layer.bind_key(key, lambda _l, f=func: f(), overwrite=True)
        return layer

    def _on_layer_removed(self, event: Any) -> None:
        layer = event.value
        if layer is self.image_layer:
            self._closing = True  # the light field is gone: stop re-creating layers
        if self._closing or layer not in self.layers.values():
            return
        # a fixed layer was deleted: put it back (after napari has finished removing it)
        index = getattr(event, "index", None)
        QTimer.singleShot(0, lambda: self._restore_layer(layer, index))

    def _restore_layer(self, layer: Any, index: int | None = None) -> None:
        # not while the viewer closes (it removes every layer, the light field's too)
        layers = self.viewer.layers
        if self._closing or self.image_layer not in layers or layer in layers:
            return
        layers.insert(len(layers) if index is None else min(index, len(layers)), layer)

    def _on_layer_inserted(self, event: Any) -> None:
        if self.session is None and not self._syncing:
            self._adopt(event.value)

    # --- running work -------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        """Whether a worker is running."""
        return self.worker is not None

    def _when_idle(self, action: Callable[[], None]) -> None:
        """Run ``action`` now, or after the running worker (in order)."""
        if self.busy:
            self._queue.append(action)
        else:
            self._try(action)

    def _try(self, action: Callable[[], None]) -> None:
        try:
            action()
        except LfsamError as exc:
            self._error(str(exc))

    def _set_status(self, text: str) -> None:
        self.status.setText(text)
        if text:
            self.status_changed.emit(text)

    def _error(self, message: str) -> None:
        self._set_status(message)
        _notify_error(message)

    def _start(self, func: Callable[[], Iterator[tuple]], total: int, desc: str) -> None:
        from napari.qt.threading import create_worker

        self.progress.setRange(0, total)
        self.progress.setValue(0)
        self._set_status(desc + "…")
        self.worker = create_worker(
            _guarded(func),
            _progress={"total": total, "desc": desc},
            _connect={
                "yielded": self._on_yielded,
                "finished": self._on_finished,
                "errored": self._on_errored,
            },
            _start_thread=True,
        )

    def _on_yielded(self, item: tuple) -> None:
        kind, obj_id, value = item
        if kind in ("reference", "coarse", "final"):
            self.stages.append(kind)
        self.progress.setValue(min(self.progress.value() + 1, self.progress.maximum()))
        if kind == "error":
            self._error(value)
            self._queue.clear()
            self._segment_pending = False
        elif kind == "loaded":
            device = getattr(self.session.predictor.segmenter, "device", None)
            where = f" on {device}" if device is not None else ""
            self._set_status(f"model {self.session.model} loaded{where}")
        elif kind == "reference":
            view, mask, score = value
            self._show_current(obj_id, view=tuple(view), mask=np.asarray(mask))
            self._set_status(f"object {obj_id}: view {tuple(view)} (score {score:.2f})")
        elif kind == "coarse":
            self._show_current(obj_id, masks=value.masks.get(obj_id))
        elif kind in ("final", "all"):
            self._show_prediction(value)

    def _on_errored(self, exc: Exception) -> None:  # a bug, not a user error: keep its traceback
        self._queue.clear()
        self._segment_pending = False
        self._set_status(f"error: {exc}")

    def _on_finished(self) -> None:
        self.worker = None
        self.progress.setValue(self.progress.maximum())
        self._refresh_objects()
        if not self._closing:
            self._drain()

    def _drain(self) -> None:
        """Run queued actions in order until one starts a worker; then a pending segmentation."""
        while self._queue and not self.busy:
            self._try(self._queue.pop(0))
        if self._segment_pending and not self.busy:
            self._segment_pending = False
            self._try(self._segment_now)

    # --- model --------------------------------------------------------------------------------
    def _disparity_value(self) -> str:
        return self.disparity_box.currentText()

    def _on_model_changed(self, name: str) -> None:
        self.weights_box.setEnabled(name != ORACLE)  # the oracle has no weights
        if self.session is not None and self.session.model != name:
            self.session.model = name
            if self.session.loaded:
                self.load_model()

    def _on_weights_activated(self, _index: int) -> None:
        text = self.weights_box.currentText()
        if text == _FILE_ITEM:
            text = self._pick_file(self.weights_box, "SAM 2 checkpoint (.pt)", "*.pt *.pth")
            if text is None:  # cancelled: show the weights in use again
                self.set_weights(**{k: self._options.get(k) for k in ("checkpoint",
                                                                      "random_weights")})
                return
        self.set_weights(
            checkpoint=None if text in (_HUB_WEIGHTS, _RANDOM_WEIGHTS) else text,
            random_weights=text == _RANDOM_WEIGHTS,
        )

    def set_weights(self, checkpoint: str | None = None, random_weights: bool = False) -> None:
        """Use a checkpoint file, untrained weights or (neither) the hub's; reloads a loaded
        model (the CLI's ``--checkpoint`` and ``--random-weights``)."""
        if checkpoint:
            _choose_item(self.weights_box, str(checkpoint))
        else:
            self.weights_box.setCurrentText(_RANDOM_WEIGHTS if random_weights else _HUB_WEIGHTS)
        weights = {"checkpoint": checkpoint or None, "random_weights": bool(random_weights)}
        changed = any(self._options.get(key) != value for key, value in weights.items())
        self._options.update(weights)
        if self.session is not None and changed:
            self.session.segmenter_options = dict(self._options)
            if self.session.loaded and self.session.model != ORACLE:
                self.load_model()

    def _pick_file(self, box: QComboBox, title: str, pattern: str) -> str | None:
        """Ask for a file with a dialog; it becomes the box's chosen item (None: cancelled)."""
        path, _ = QFileDialog.getOpenFileName(self, title, "", pattern)
        if path:
            _choose_item(box, path)
        return path or None

    def _on_disparity_activated(self, _index: int) -> None:
        if self.disparity_box.currentText() == _FILE_ITEM:
            if self._pick_file(self.disparity_box, "Disparity (.npy)", "*.npy") is None:
                if self.session is not None:  # cancelled: show the source in use again
                    _choose_item(self.disparity_box, str(self.session.disparity))
                return
        if self.session is not None and self.session.disparity != self._disparity_value():
            self.session.disparity = self._disparity_value()
            if self.session.loaded:
                self.load_model()

    def load_model(self) -> None:
        """Load the chosen model and disparity source (worker); objects are recomputed."""
        if self.session is None:
            self._error("no light field: open one first (File > Open, or `lfsam view LF`)")
            return

        def job() -> Iterator[tuple]:
            self.session.load()
            yield ("loaded", None, None)
            if self.session.object_ids:
                yield ("all", None, self.session.predict_all())

        self._when_idle(lambda: self._start(job, 2, f"loading {self.session.model}"))

    # --- prompts ------------------------------------------------------------------------------
    def _on_points_press(self, layer: Any, event: Any) -> None:
        """Before napari adds a clicked point: its polarity (Ctrl-click = the other one)."""
        if layer.mode != "add":
            return
        modifiers = getattr(event, "modifiers", ())
        flip = "Control" in modifiers or "Meta" in modifiers  # vispy keys compare to names
        layer.feature_defaults = {"positive": self.negative == flip}

    def toggle_polarity(self) -> None:
        """T: plain clicks add negative points instead of positive ones, or back."""
        self.negative = not self.negative
        self._update_polarity()

    def _update_polarity(self) -> None:
        text = "negative" if self.negative else "positive"
        self.polarity_label.setText(f"Clicks add {text} points (Ctrl-click: the other; T)")
        if L.POINTS in self.layers:
            self.layers[L.POINTS].feature_defaults = {"positive": not self.negative}

    def _layer_prompts(self) -> Any:
        points = self.layers[L.POINTS]
        boxes = self.layers[L.BOXES]
        positive = (
            points.features["positive"].to_numpy(dtype=bool)
            if len(points.data)
            else np.zeros(0, dtype=bool)
        )
        rects = [
            d for d, kind in zip(boxes.data, boxes.shape_type, strict=True) if kind == "rectangle"
        ]
        return prompts_from_layers(
            self.session.current_id,
            points.data,
            positive,
            rects,
            self.session.lightfield.grid_shape,
        )

    def _on_prompts_edited(self, event: Any) -> None:
        action = str(getattr(event, "action", "changed"))
        if self._syncing or self.session is None or not action.endswith(("added", "removed",
                                                                          "changed")):
            return
        if self.session.history.push(self._layer_prompts()):
            self.segment()

    def _set_layer_prompts(self, obj: Any) -> None:
        points, positive, boxes = layers_from_prompts(obj, self.session.lightfield.center)
        self._syncing = True
        try:
            layer = self.layers[L.POINTS]
            layer.data = points
            layer.features = {"positive": positive}
            layer.refresh_colors() if hasattr(layer, "refresh_colors") else None
            shapes = self.layers[L.BOXES]
            shapes.data = []
            if boxes:
                shapes.add_rectangles(boxes)
        finally:
            self._syncing = False
        self._update_polarity()

    def undo(self) -> None:
        """Ctrl-Z: undo the last prompt edit of the current object."""
        self._when_idle(lambda: self._apply_history(self.session.history.undo()))

    def redo(self) -> None:
        """Ctrl-Shift-Z: redo an undone prompt edit."""
        self._when_idle(lambda: self._apply_history(self.session.history.redo()))

    def _apply_history(self, obj: Any) -> None:
        self._set_layer_prompts(obj)
        self._segment_now()

    # --- actions ------------------------------------------------------------------------------
    def segment(self) -> None:
        """S: segment the current object from its prompts (worker; queued if busy)."""
        if self.session is None:
            return
        if self.busy:
            self._segment_pending = True
        else:
            self._try(self._segment_now)

    def _segment_now(self) -> None:
        if not self.session.loaded:
            self._segment_pending = True
            self.load_model()
            return
        obj_id = self.session.current_id
        self.session.sync_current()
        if obj_id not in self.session.object_ids:  # no prompts left
            self._show_current(obj_id)
            return
        self.stages = []

        def job() -> Iterator[tuple]:
            for stage, value in self.session.segment_current():
                yield (stage, obj_id, value)

        self._start(job, 3, f"segmenting object {obj_id}")

    def commit(self) -> None:
        """C: commit the current object; the next clicks start a new one."""
        self._when_idle(self._commit_now)

    def _commit_now(self) -> None:
        if self.session is None or not self.session.loaded:
            raise LfsamError("nothing to commit: load a model and segment an object first")
        self.session.sync_current()
        self.session.commit()
        self._set_layer_prompts(None)
        self._show_current(self.session.current_id)
        self._start(lambda: iter([("all", None, self.session.predict_all())]), 1, "committing")

    def clear(self) -> None:
        """Shift-C: remove the current object's prompts and mask."""

        def run() -> None:
            if self.session is None:
                return
            if self.session.loaded:
                self.session.clear_current()
            else:
                self.session.history.reset()
            self._set_layer_prompts(None)
            self._show_current(self.session.current_id)
            self._refresh_objects()

        self._when_idle(run)

    def segment_everything(self) -> None:
        """Automatic mode (``predictor.generate``): every object found, in its own layer."""

        def run() -> None:
            if self.session is None:
                return
            if not self.session.loaded:
                self.load_model()
                self._when_idle(run)
                return
            references = self.references_box.currentText()
            self._start(
                lambda: iter([("all", None, self.session.generate(references))]), 1,
                "segmenting everything" + ("" if references == "center" else f" ({references})"),
            )

        self._when_idle(run)

    def edit_object(self, obj_id: int) -> None:
        """Make object ``obj_id`` the one being edited: its prompts go to the prompt layers."""

        def run() -> None:
            previous = self.session.current_id
            obj = self.session.edit(obj_id)
            self._set_layer_prompts(obj)
            mask = self._mask_of(obj_id)
            if mask is None:
                mask = (self.layers[L.COMMITTED].data == obj_id) | (
                    self.layers[L.AUTO].data == obj_id
                )
            for name in (L.COMMITTED, L.AUTO):
                layer = self.layers[name]
                layer.data[layer.data == obj_id] = 0
                if previous in self.session.committed and name == L.COMMITTED:
                    old = self._mask_of(previous)
                    if old is not None:
                        layer.data[old & (layer.data == 0)] = previous
                layer.refresh()
            self._show_current(obj_id, masks=mask)
            self._refresh_objects()

        self._when_idle(run)

    def remove_object(self, obj_id: int) -> None:
        """Delete object ``obj_id`` (prompts and masks)."""

        def run() -> None:
            self.session.remove(obj_id)
            for name in (L.COMMITTED, L.AUTO, L.CURRENT):
                layer = self.layers[name]
                layer.data[layer.data == obj_id] = 0
                layer.refresh()
            if obj_id == self.session.current_id:
                self._set_layer_prompts(None)
            self._refresh_objects()

        self._when_idle(run)

    def open_result(self, result: Any) -> None:
        """Reopen a result's objects (``LightFieldPredictor.load_objects``) for correction."""

        def run() -> None:
            if not self.session.loaded:
                self.load_model()
                self._when_idle(run)
                return
            self.session.open_result(result)
            self._show_labels(L.COMMITTED, np.asarray(result.labels))
            self._start(lambda: iter([("all", None, self.session.predict_all())]), 1, "reopening")

        self._when_idle(run)

    def open_labels(self, labels: np.ndarray) -> None:
        """Reopen a labels array ``(S, T, U, V)`` (label = object id) for correction."""
        from lfsam.result import SegmentationResult

        self.open_result(SegmentationResult(labels=np.asarray(labels, dtype=np.int32)))

    def show_display(self, name: str) -> None:
        """Show the views (``"views"``) or an EPI (``"epi-row"``, ``"epi-column"``)."""
        self.viewer.dims.order = L.ORDERS[name]
        self.viewer.reset_view()

    def save(self, path: str | os.PathLike) -> Path:
        """Write the session as an lfsam result (prompts included)."""
        out = self.session.save(path)
        self._set_status(f"saved {out}")
        return out

    def export(self, out: str | os.PathLike, to: str = "png") -> Any:
        """Export the result into the folder ``out`` through the CLI's code (``lfsam.export``)."""
        module = _export_module()
        if module is None:
            raise LfsamError("export is not available in this version; save the result instead")
        path = module.export_result(self.session.to_result(), out, to=to)
        self._set_status(f"exported {path} ({to})")
        return path

    # --- display ------------------------------------------------------------------------------
    def _show_labels(self, name: str, labels: np.ndarray) -> None:
        layer = self.layers[name]
        layer.data[...] = labels
        layer.refresh()

    def _show_current(
        self,
        obj_id: int,
        *,
        view: tuple[int, int] | None = None,
        mask: np.ndarray | None = None,
        masks: np.ndarray | None = None,
    ) -> None:
        """The current object's layer: one view's mask, all views' masks, or nothing."""
        if obj_id != self.session.current_id:
            return  # the object was committed or left meanwhile
        layer = self.layers[L.CURRENT]
        layer.data[...] = 0
        if view is not None and mask is not None:
            layer.data[view][mask] = obj_id
        elif masks is not None:
            layer.data[np.asarray(masks, dtype=bool)] = obj_id
        layer.refresh()

    def _show_prediction(self, prediction: Any) -> None:
        if prediction is None:
            return
        self._prediction = prediction
        labels = np.asarray(prediction.labels)
        self._show_labels(L.COMMITTED, select_labels(labels, self.session.committed))
        self._show_labels(L.AUTO, select_labels(labels, self.session.auto))
        self._show_current(self.session.current_id, masks=self._mask_of(self.session.current_id))
        self._refresh_objects()
        self._set_status(f"{len(prediction.masks)} object(s) segmented in every view")

    def _mask_of(self, obj_id: int) -> np.ndarray | None:
        """Object ``obj_id``'s mask in the last prediction, ``(S, T, U, V)`` bool, or None."""
        if self._prediction is None or obj_id not in self._prediction.masks:
            return None
        return np.asarray(self._prediction.masks[obj_id], dtype=bool)

    def _refresh_objects(self) -> None:
        self.objects.clear()
        if self.session is None:
            return
        for obj_id in self.session.object_ids:
            if obj_id == self.session.current_id:
                role = "editing"
            elif obj_id in self.session.auto:
                role = "automatic"
            else:
                role = "committed"
            item = QListWidgetItem(f"{obj_id}  ({role})")
            item.setData(256, obj_id)  # Qt.UserRole
            self.objects.addItem(item)

    def _selected_id(self) -> int | None:
        item = self.objects.currentItem()
        return None if item is None else int(item.data(256))

    def _on_object_double_clicked(self, item: QListWidgetItem) -> None:
        self.edit_object(int(item.data(256)))

    def _edit_selected(self) -> None:
        obj_id = self._selected_id()
        if obj_id is not None:
            self.edit_object(obj_id)

    def _remove_selected(self) -> None:
        obj_id = self._selected_id()
        if obj_id is not None:
            self.remove_object(obj_id)

    def _open_selected_labels(self) -> None:
        from napari.layers import Labels

        layer = self.viewer.layers.selection.active
        if not isinstance(layer, Labels) or layer in self.layers.values():
            self._error("select a labels layer of this light field (not one of the widget's)")
            return
        result = layer.metadata.get(RESULT_KEY)
        if result is not None:
            self.open_result(result)
        else:
            self.open_labels(layer.data)

    def _save_dialog(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save lfsam result", "result.npz", "*.npz")
        if path:
            self._when_idle(lambda: self.save(path))

    def _export_dialog(self) -> None:
        from qtpy.QtWidgets import QInputDialog

        module = _export_module()
        if module is None:
            return
        to, ok = QInputDialog.getItem(
            self, "Export", "Format", list(module.EXPORT_FORMATS), 0, False
        )
        if not ok:
            return
        out, _ = QFileDialog.getSaveFileName(self, "Export to a new folder", "export")
        if out:
            self._when_idle(lambda: self.export(out, to))

    def closeEvent(self, event: Any) -> None:
        """Stop reacting to the viewer when the dock widget closes."""
        self._closing = True
        super().closeEvent(event)


def _export_module() -> Any:
    """The CLI's export module (``lfsam export``), or None where this version has none."""
    try:
        import lfsam.export as module
    except ImportError:
        return None
    return module if hasattr(module, "export_result") else None

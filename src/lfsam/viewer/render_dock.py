"""The viewer's "Render" dock: refocus, see through the selected object, take it out.

Beside the lfsam dock (:class:`lfsam.viewer.widget.LightFieldWidget`), a thin layer over
:mod:`lfsam.render` (docs/design.md section 13) on the dock's light field, the masks it shows
(every mask layer, the current object over the committed ones over the automatic ones) and the
session's disparity source (resolved once per light field and source, in the work's thread):

- the **focus slider** spans the scene's disparity range (pixels per view step, the convention
  of ``lfsam disparity``; the center disparity's finite extent, as ``lfsam render``) and
  refocuses (:func:`lfsam.render.refocus`) a moment after it stops moving; with "slider sees
  through" checked it sees through the object of the last "See through selected" instead;
- **Focus on selected** refocuses at the object's median disparity
  (:func:`lfsam.render.object_focus`) and moves the slider there;
- **See through selected** leaves out every ray that hits the object in any view
  (:func:`lfsam.render.see_through`), focused on what lies behind it
  (:func:`lfsam.render.behind_focus`);
- **Remove selected** makes the whole light field without the object
  (:func:`lfsam.render.remove_objects`), shown as a stack of views like the light field's layer;
- **Save…** writes the last output: an image (PNG, ...) or the removed light field in lfsam's
  native format (``.npz`` or a scene folder, with its ``inpainted.npy`` flags), atomically,
  through :mod:`lfsam.render.output` (the code ``lfsam render`` writes with).

The selected object is the one selected in the lfsam dock's object list, else the object being
edited (the "current object" layer). Images go to the layer :data:`IMAGE_LAYER`, removed light
fields to :data:`REMOVED_LAYER`, each replaced in place. Every computation, and every Save, runs
in a thread of its own, never in the GUI thread; the answer reaches the GUI thread through a
queued Qt signal (:mod:`lfsam.viewer.side_dock`). Problems are one line in the dock's
status, never a dialog.

References
----------
docs/design.md section 13 (rendering around objects).
"""

from __future__ import annotations

import contextlib
import os
from functools import partial
from typing import Any

import numpy as np
from qtpy.QtCore import Qt, QTimer, Signal
from qtpy.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer import render_jobs as J
from lfsam.viewer.plugin_io import lightfield_layers
from lfsam.viewer.render_jobs import REMOVED_LAYER, Rendered, RenderOutput
from lfsam.viewer.side_dock import SideDock, no_widget_message, push_button

__all__ = ["IMAGE_LAYER", "REMOVED_LAYER", "RenderDock", "RenderOutput"]

#: The layer of refocused and seen-through images (the removed light field's:
#: :data:`REMOVED_LAYER`, a stack of views).
IMAGE_LAYER = "lfsam render"
#: Positions of the focus slider over the scene's disparity range.
STEPS = 400
#: The slider refocuses this long (ms) after it stops moving.
DEBOUNCE_MS = 150
#: The scene's range is sought when the dock is still shown this long (ms) after it showed.
SHOWN_MS = 500
#: The slider's range until the scene's is known (pixels per view step).
PLACEHOLDER_RANGE = (-2.0, 2.0)
NO_WIDGET = no_widget_message("render")


class RenderDock(SideDock):
    """Refocus, see through or remove the lfsam dock's selected object (module docstring).

    ``napari_viewer`` and ``widget`` as for :class:`lfsam.viewer.side_dock.SideDock` (the
    lfsam dock whose selected object is rendered; default: the one docked in the viewer).

    Attributes
    ----------
    output : RenderOutput or None
        The last output (None before the first); Save writes it.
    scene_range : (float, float) or None
        The scene's disparity range, once known (the slider spans it).
    slider : QSlider
        The focus, :data:`STEPS` positions over the scene's range.
    focus_label, status : QLabel
    focus_button, through_button, remove_button, save_button : QPushButton
    slider_through : QCheckBox
        The slider sees through the object of the last "See through selected".
    """

    no_widget = NO_WIDGET
    thread_name = "lfsam-render"
    _delivered = Signal(object)
    _saved = Signal(object)

    def __init__(self, napari_viewer: Any, widget: Any = None) -> None:
        super().__init__(napari_viewer, widget)
        self.output: RenderOutput | None = None
        self.scene_range: tuple[float, float] | None = None
        self._disparity = J.DisparityCache()
        self._pending = False
        self._through_id: int | None = None

        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, STEPS)
        self.slider.setValue(STEPS // 2)
        self.slider.setToolTip("focus: the disparity (pixels per view step) brought into focus")
        self.focus_label = QLabel()
        self.focus_label.setMinimumWidth(110)
        self.slider_through = QCheckBox("slider sees through")
        self.slider_through.setToolTip("the slider sees through the object of the last "
                                       "'See through selected' instead of refocusing")
        self.slider_through.setEnabled(False)
        self.focus_button = push_button(
            "Focus on selected", "refocus at the selected object's median disparity")
        self.through_button = push_button(
            "See through selected", "leave out every ray that hits the selected object, focused "
            "on what lies behind it")
        self.remove_button = push_button(
            "Remove selected", "the whole light field without the selected object")
        self.save_button = push_button(
            "Save…", "the image (PNG) or the light field without the object (.npz or a folder)")
        self.status = QLabel()
        self.status.setWordWrap(True)

        focus_row = QHBoxLayout()
        focus_row.addWidget(QLabel("Focus"))
        focus_row.addWidget(self.slider, 1)
        focus_row.addWidget(self.focus_label)
        buttons = QHBoxLayout()
        for button in (self.focus_button, self.through_button, self.remove_button):
            buttons.addWidget(button)
        last = QHBoxLayout()
        last.addWidget(self.slider_through)
        last.addStretch(1)
        last.addWidget(self.save_button)
        layout = QVBoxLayout()
        for row in (focus_row, buttons, last):
            layout.addLayout(row)
        layout.addWidget(self.status)
        layout.addStretch(1)
        self.setLayout(layout)

        self._debounce = QTimer(self)
        self._debounce.setSingleShot(True)
        self._debounce.setInterval(DEBOUNCE_MS)
        self._debounce.timeout.connect(lambda: self.render_focus())
        self._shown = QTimer(self)  # showEvent: the scene's range, if still shown by then
        self._shown.setSingleShot(True)
        self._shown.setInterval(SHOWN_MS)
        self._shown.timeout.connect(self._find_range)
        self.slider.valueChanged.connect(self._on_slider)
        self.focus_button.clicked.connect(lambda _=False: self.focus_on_selected())
        self.through_button.clicked.connect(lambda _=False: self.see_through_selected())
        self.remove_button.clicked.connect(lambda _=False: self.remove_selected())
        self.save_button.clicked.connect(lambda _=False: self._ask_save())
        self._delivered.connect(self._on_done)  # queued: emitted in the work's thread
        self._saved.connect(self._on_saved)
        self._show_focus()
        self._set_status("move the focus slider, or select an object in the lfsam dock's list "
                         "and focus on it, see through it or remove it"
                         if self._find_widget() is not None else NO_WIDGET)

    # --- the focus slider -----------------------------------------------------------------------
    @property
    def focus(self) -> float:
        """The slider's focus, pixels per view step."""
        low, high = self.scene_range or PLACEHOLDER_RANGE
        return low + (high - low) * self.slider.value() / STEPS

    def set_focus(self, focus: float) -> None:
        """Move the slider to ``focus`` (clipped to its range); it renders a moment later."""
        low, high = self.scene_range or PLACEHOLDER_RANGE
        share = (focus - low) / (high - low) if high > low else 0.5
        self.slider.setValue(round(min(max(share, 0.0), 1.0) * STEPS))

    def _place_slider(self, focus: float) -> None:
        """The slider at ``focus`` without rendering again."""
        with _signals_blocked(self.slider):
            self.set_focus(focus)
        self._show_focus()

    def _show_focus(self) -> None:
        known = "" if self.scene_range is not None else " (range: at first use)"
        self.focus_label.setText(f"{self.focus:+.2f} px{known}")

    def _on_slider(self, _value: int) -> None:
        self._show_focus()
        self._debounce.start()  # restarted while the slider moves

    # --- the lfsam dock and what it shows -------------------------------------------------------
    def _source(self) -> tuple[Any, LightField, Any]:
        """The lfsam dock, its light field and its disparity source (GUI thread).

        Raises
        ------
        LfsamError
            No lfsam dock or no light field (one line each).
        """
        widget, session = self._session()
        return widget, session.lightfield, session.disparity

    def selected(self) -> tuple[int, np.ndarray]:
        """The selected object's id and its masks in every view, ``(S, T, U, V)`` bool: the
        object selected in the lfsam dock's list, else the one being edited (GUI thread).

        Raises
        ------
        LfsamError
            No lfsam dock, no light field, no object, none selected, or no mask of it.
        """
        widget, _, _ = self._source()
        labels = widget.masks.composite()
        ids = [int(i) for i in np.unique(labels) if i > 0]
        if not ids:
            raise LfsamError("no object yet: click one or Segment everything in the lfsam dock, "
                             "then select it in its object list")
        obj_id = widget.controls.selected_id()
        if obj_id is None:
            editing = np.asarray(widget.masks.array(L.CURRENT))
            current = widget.session.current_id
            if not (editing == current).any():
                raise LfsamError("no object selected: select one in the lfsam dock's object "
                                 f"list (objects with masks: {', '.join(map(str, ids))})")
            obj_id = current
        masks = labels == obj_id
        if not masks.any():
            raise LfsamError(f"object {obj_id} has no mask yet: segment it first (objects with "
                             f"masks: {', '.join(map(str, ids))})")
        return int(obj_id), masks

    # --- the actions ----------------------------------------------------------------------------
    def render_focus(self, block: bool = False, timeout: float = 120.0) -> None:
        """Render at the slider's focus: refocus, or see through the object of the last "See
        through selected" when "slider sees through" is checked. While something runs, the
        latest focus is rendered when it is done. ``block``: wait (``timeout`` seconds at most)
        while Qt processes its events (tests, scripts)."""
        if self._running:
            self._pending = True
            return
        focus = self.focus
        if self.slider_through.isChecked() and self._through_id is not None:
            self._see_through(self._through_id, focus, block, timeout)
            return
        try:
            _, lightfield, spec = self._source()
        except LfsamError as exc:
            self._set_status(str(exc))
            return
        self._start(partial(J.refocus_job, self._disparity, lightfield, spec, focus),
                    self._delivered, f"refocusing at {focus:+.3f} px…", block, timeout)

    def focus_on_selected(self, block: bool = False, timeout: float = 120.0) -> None:
        """Refocus at the selected object's median disparity; the slider moves there."""
        inputs = self._selected_inputs()
        if inputs is None:
            return
        obj_id, masks, lightfield, spec = inputs
        center = masks[lightfield.center]
        self._start(partial(J.refocus_job, self._disparity, lightfield, spec, None,
                            obj_id, center),
                    self._delivered, f"object {obj_id}: focusing on it…", block, timeout)

    def _selected_inputs(self) -> tuple[int, np.ndarray, LightField, Any] | None:
        """The selected object's id and masks, the light field and its disparity source; None
        (said in the status) while something runs or when one is missing."""
        if self._still_running():
            return None
        try:
            obj_id, masks = self.selected()
            _, lightfield, spec = self._source()
        except LfsamError as exc:
            self._set_status(str(exc))
            return None
        return obj_id, masks, lightfield, spec

    def see_through_selected(self, block: bool = False, timeout: float = 120.0) -> None:
        """See through the selected object, focused on what lies behind it; from then on the
        slider sees through it (until "slider sees through" is unchecked)."""
        if self._still_running():
            return
        try:
            obj_id, _ = self.selected()
        except LfsamError as exc:
            self._set_status(str(exc))
            return
        self._see_through(obj_id, None, block, timeout)

    def _see_through(self, obj_id: int, focus: float | None, block: bool, timeout: float) -> None:
        try:
            _, lightfield, spec = self._source()
            labels = self._labels_with(obj_id)
        except LfsamError as exc:
            self.slider_through.setChecked(False)
            self._set_status(str(exc))
            return
        where = "what lies behind it" if focus is None else f"{focus:+.3f} px"
        self._start(partial(J.see_through_job, self._disparity, lightfield, spec, obj_id,
                            labels, focus),
                    self._delivered, f"object {obj_id}: seeing through it at {where}…", block,
                    timeout)

    def _labels_with(self, obj_id: int) -> np.ndarray:
        """Every view's label map (all objects), checked to still hold ``obj_id``."""
        widget, _, _ = self._source()
        labels = np.asarray(widget.masks.composite())
        if not (labels == obj_id).any():
            raise LfsamError(f"object {obj_id} has no mask any more: select another")
        return labels

    def remove_selected(self, block: bool = False, timeout: float = 600.0) -> None:
        """The whole light field without the selected object, shown as a stack of views."""
        inputs = self._selected_inputs()
        if inputs is None:
            return
        obj_id, masks, lightfield, spec = inputs
        self._start(partial(J.remove_job, self._disparity, lightfield, spec, obj_id, masks),
                    self._delivered,
                    f"object {obj_id}: removing it from {lightfield.num_present} views…", block,
                    timeout)

    def save(self, path: str | os.PathLike, block: bool = False, timeout: float = 600.0) -> None:
        """Write the last output to ``path`` (atomically, in a thread of its own): an image
        (``.png``, ...), or the removed light field (``.npz`` or a new scene folder)."""
        if self._still_running():
            return
        output = self.output
        if output is None:
            self._set_status("nothing to save yet: refocus, see through or remove first")
            return
        self._start(partial(J.write_output, output, path), self._saved, f"writing {path}…",
                    block, timeout)

    def _ask_save(self) -> None:
        output = self.output
        if output is None:
            self._set_status("nothing to save yet: refocus, see through or remove first")
            return
        if output.kind == "remove":
            path = C.ask_save_file(self, "Save the light field without the object (.npz, or a "
                                   "new folder)", f"without{output.object_id}.npz")
        else:
            path = C.ask_save_file(self, "Save the rendered image", f"{output.kind}.png",
                                   "Images (*.png *.jpg *.jpeg *.tif *.tiff)")
        if path:
            self.save(path)

    # --- the work, in its own thread (:class:`SideDock`) ----------------------------------------
    def _start(self, work: Any, signal: Any, status: str, block: bool, timeout: float) -> None:
        self._pending = False  # the focus of a slider moved meanwhile is rendered now
        super()._start(work, signal, status, block, timeout)

    def _enable(self, on: bool) -> None:
        for each in (self.focus_button, self.through_button, self.remove_button,
                     self.save_button):
            each.setEnabled(on)

    # --- answers, in the GUI thread -------------------------------------------------------------
    def _on_done(self, answer: Any) -> None:
        self._finish()
        if isinstance(answer, str):
            self._set_status(answer)
        else:
            self._take(answer)
        if self._pending:  # the slider moved meanwhile: its latest focus
            self.render_focus()

    def _take(self, done: Rendered) -> None:
        """Show a job's answer; the slider spans the scene's range and stands at the focus
        used (an answer without output only gives the range: the slider keeps its focus)."""
        output = done.output
        focus = self.focus if output is None or output.focus is None else output.focus
        if done.scene_range is not None:
            self.scene_range = done.scene_range
            focus = min(max(focus, done.scene_range[0]), done.scene_range[1])
        self._place_slider(focus)
        if output is not None:
            self.output = output
            self._show(output)
        self._set_status(J.summary(done))

    def _on_saved(self, answer: Any) -> None:
        self._finish()
        self._set_status(answer)
        if self._pending:
            self.render_focus()

    # --- layers ---------------------------------------------------------------------------------
    def _show(self, output: RenderOutput) -> None:
        """Show ``output`` in its layer (replaced in place), the other kind's layer hidden; the
        active layer stays the one the user works in."""
        if output.kind == "see-through":
            self._through_id = output.object_id
            self.slider_through.setEnabled(True)
            with _signals_blocked(self.slider_through):
                self.slider_through.setChecked(True)
        elif output.object_id is not None:  # "Focus on selected": the slider refocuses
            self.slider_through.setChecked(False)
        if output.kind == "remove":
            data, kwargs, _ = lightfield_layers(output.lightfield, name=REMOVED_LAYER)[0]
            self._put(REMOVED_LAYER, data, kwargs, hide=IMAGE_LAYER)
        else:
            kwargs = {"name": IMAGE_LAYER, "rgb": True, "contrast_limits": (0.0, 255.0)}
            self._put(IMAGE_LAYER, output.image, kwargs, hide=REMOVED_LAYER)

    def _put(self, name: str, data: np.ndarray, kwargs: dict, hide: str) -> None:
        layers = self.viewer.layers
        active = layers.selection.active
        if hide in layers:
            layers[hide].visible = False
        if name in layers and layers[name].data.shape == data.shape:
            layer = layers[name]
            layer.data = data
            layer.metadata.update(kwargs.get("metadata", {}))
            layer.visible = True
            layer.refresh()
            return
        if name in layers:  # another light field's: its shape differs
            layers.remove(name)
        keeper = getattr(self.widget, "keeper", None)
        with keeper.aside() if keeper is not None else contextlib.nullcontext():
            self.viewer.add_image(data, **kwargs)  # not offered to the lfsam dock to adopt
        if active is not None and active in layers:
            layers.selection.active = active

    def showEvent(self, event: Any) -> None:
        """Shown before the scene's disparity range is known: find it for the slider, in the
        work's thread, if the dock is still in front a moment later (``lfsam view`` adds it
        as a tab and brings the lfsam dock to the front)."""
        super().showEvent(event)
        if self.scene_range is None:
            self._shown.start()  # restarted by each show

    def _find_range(self) -> None:
        if self.scene_range is None and not self._running and self.isVisible():
            with contextlib.suppress(LfsamError):
                _, lightfield, spec = self._source()
                self._start(partial(J.range_job, self._disparity, lightfield, spec),
                            self._delivered,
                            "finding the scene's disparity range for the focus slider…",
                            False, 0.0)


@contextlib.contextmanager
def _signals_blocked(widget: QWidget) -> Any:
    blocked = widget.blockSignals(True)
    try:
        yield
    finally:
        widget.blockSignals(blocked)

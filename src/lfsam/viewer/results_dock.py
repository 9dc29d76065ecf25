"""The dock's object list and result files (mixed into
:class:`lfsam.viewer.widget.LightFieldWidget`): an object chosen from the list is edited or
removed; a result or a labels layer is reopened for correction; the session is saved as an lfsam
result or exported through the CLI's code (``lfsam export``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from qtpy.QtWidgets import QListWidgetItem

from lfsam.errors import LfsamError
from lfsam.result import SegmentationResult
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer.adoption import result_to_reopen

__all__ = ["ResultsDock"]


class ResultsDock:
    """The object list and the result files of the dock (mixed into the widget, which provides
    ``session``, ``viewer``, ``controls``, ``layers``, ``masks``, ``work``, ``is_video``,
    ``show_tracked``, ``_set_layer_prompts``, ``_show_current``, ``_refresh_objects``,
    ``_when_loaded``, ``_predict_all`` and ``_set_status``)."""

    session: Any
    viewer: Any
    controls: Any
    work: Any

    def edit_object(self, obj_id: int) -> None:
        """Make object ``obj_id`` the one being edited: its prompts go to the prompt layers."""

        def run() -> None:
            previous = self.session.current_id
            self._set_layer_prompts(self.session.edit(obj_id))
            mask = self.masks.mask_of(obj_id)
            mask = self.masks.shown(obj_id) if mask is None else mask
            self.masks.erase(obj_id, (L.COMMITTED, L.AUTO))
            if previous in self.session.committed:  # the object left was committed
                self.masks.recommit(previous)
            self._show_current(obj_id, masks=mask)
            self._refresh_objects()

        self.work.when_idle(run)

    def remove_object(self, obj_id: int) -> None:
        """Delete object ``obj_id`` (prompts and masks)."""

        def run() -> None:
            self.session.remove(obj_id)
            self.masks.erase(obj_id)
            if obj_id == self.session.current_id:
                self._set_layer_prompts(None)
            self._refresh_objects()

        self.work.when_idle(run)

    def open_result(self, result: Any) -> None:
        """Reopen a result's objects to correct them (a video's result: :meth:`show_tracked`)."""

        def run() -> None:
            self.session.open_result(result)
            self.masks.show_labels(L.COMMITTED, np.asarray(result.labels))
            self._predict_all("reopening")

        then = partial(self.show_tracked, result) if self.is_video else run
        self.work.when_idle(lambda: self._when_loaded(then))

    def open_labels(self, labels: np.ndarray) -> None:
        """Reopen a labels array ``(S, T, U, V)`` (label = object id) for correction."""
        self.open_result(SegmentationResult(labels=np.asarray(labels, dtype=np.int32)))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the session as an lfsam result (prompts included); a video's tracked result
        folder is copied to the folder ``path``."""
        out = self.session.save(path)
        self._set_status(f"saved {out}")
        return out

    def export(self, out: str | os.PathLike, to: str = "png") -> Any:
        """Export the result into the folder ``out`` through the CLI's code (``lfsam.export``)."""
        module = _export_module()
        if module is None:
            raise LfsamError("export is not available in this version; save the result instead")
        if self.is_video:
            path = module.export_video(iter(self.session.to_result()), out, to=to)
        else:
            path = module.export_result(self.session.to_result(), out, to=to)
        self._set_status(f"exported {path} ({to})")
        return path

    def _on_object_double_clicked(self, item: QListWidgetItem) -> None:
        self.edit_object(C.item_id(item))

    def _on_selected(self, action: Callable[[int], None]) -> None:
        obj_id = self.controls.selected_id()
        if obj_id is not None:
            action(obj_id)

    def _open_selected_labels(self) -> None:
        active = self.viewer.layers.selection.active
        self.work.attempt(lambda: self.open_result(result_to_reopen(active, self.layers.values())))

    def _save_dialog(self) -> None:
        if self.is_video:  # a folder, one file per frame (docs/design.md section 10)
            path = C.ask_save_file(self, "Save the video result (a new folder)", "result")
        else:
            path = C.ask_save_file(self, "Save lfsam result", "result.npz", "*.npz")
        if path:  # the place is checked at once, written once the work running is done
            self.work.attempt(lambda: self.session.check_save(path) and self.work.when_idle(
                lambda: self.save(path)))

    def _export_dialog(self) -> None:
        module = _export_module()
        answer = None if module is None else C.ask_export(self, module.EXPORT_FORMATS)
        if answer is not None:
            self.work.when_idle(lambda: self.export(*answer))



def _export_module() -> Any:
    """The CLI's export module (``lfsam export``), or None where this version has none."""
    try:
        import lfsam.export as module
    except ImportError:
        return None
    return module if hasattr(module, "export_result") else None

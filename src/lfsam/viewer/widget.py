"""The dock widget: click to segment a light field in napari, correct, commit, save.

A thin Qt layer over :class:`lfsam.viewer.session.ViewerSession` (which drives
:class:`lfsam.predictor.LightFieldPredictor`; docs/design.md section 8), in the shape of napari
plugins such as micro-sam's. It connects three parts and shows what they produce:

- the dock's controls and layout (:mod:`lfsam.viewer.controls`), its model settings
  (:mod:`lfsam.viewer.model_dock`) and its object list and result files
  (:mod:`lfsam.viewer.results_dock`);
- the light field's layer and the fixed prompt and mask layers (:mod:`lfsam.viewer.adoption`,
  :mod:`lfsam.viewer.layers`);
- the worker (:mod:`lfsam.viewer.worker`): everything slow (loading the model, encoding,
  prediction, automatic segmentation) runs in a napari worker thread with a progress bar and
  yields typed events, on whose type the widget dispatches; actions asked for meanwhile are
  queued, so the interface never blocks. A prediction shows the prompted view's mask first, then
  the coarse masks of all views, then the refined ones.

Keys (as in micro-sam): ``S`` segment, ``C`` commit the current object, ``T`` toggle positive /
negative clicks (Ctrl-click adds a point of the other polarity), ``Shift-C`` clear the current
object, ``Ctrl-Z`` / ``Ctrl-Shift-Z`` undo / redo prompt edits, ``Ctrl-T`` track a video.

A light-field video (docs/design.md section 10) gets a ``frame`` slider before ``s`` and ``t``
(its layers are read lazily, :mod:`lfsam.viewer.video`); a click is tagged with the frame shown
and segments that frame at once (:class:`lfsam.viewer.video_session.VideoSession`); "Track"
runs :func:`lfsam.video.tracking.track.track_video` in the worker and shows each frame as it
finishes.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
from qtpy.QtCore import Signal
from qtpy.QtWidgets import QWidget

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.references import REFERENCE_MODES
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer import worker as W
from lfsam.viewer.adoption import LayerKeeper, lightfield_of, video_of
from lfsam.viewer.follow_dock import FollowController
from lfsam.viewer.model_dock import ModelDock
from lfsam.viewer.native_libraries import preload_native_libraries
from lfsam.viewer.plugin_io import SESSION_KEY
from lfsam.viewer.results_dock import ResultsDock, _export_module
from lfsam.viewer.session import DISPARITY_SOURCES, ViewerSession
from lfsam.viewer.video_dock import VideoDock

__all__ = ["LightFieldWidget"]

#: Keys (napari's names) and the widget's methods they call.
_KEYS = {
    "s": "segment", "c": "commit", "t": "toggle_polarity", "Shift-c": "clear",
    "Control-z": "undo", "Control-Shift-z": "redo", "Control-t": "track",
}


def _notify_error(message: str) -> None:
    from napari.utils.notifications import show_error

    show_error(message)


class LightFieldWidget(ModelDock, ResultsDock, VideoDock, QWidget):
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
    video : LightFieldVideo, optional
        A light-field video instead of ``lightfield`` (docs/design.md section 10).
    consensus : bool
        The "Consensus" box's initial state: the multi-view vote (docs/design.md section 3.9).
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
        text_options: dict[str, Any] | None = None,
        autoload: bool = True,
        refine_views: str | int = "all",
        video: Any = None,
        consensus: bool = False,
    ) -> None:
        super().__init__()
        from lfsam.segmenters import available_models
        from lfsam.segmenters.registry import DEFAULT_MODEL

        preload_native_libraries()  # here, in the main thread, not in the worker (module doc)

        self.viewer = napari_viewer
        self.session: ViewerSession | None = None
        #: Set to stop the running track (:meth:`stop_tracking`); None when not tracking.
        self._stop_track: threading.Event | None = None
        self.stages: list[str] = []  # stages shown by the last segmentation, in order
        self._options = dict(segmenter_options or {})
        self._text_options = dict(text_options or {})
        self._cache_dir = cache_dir
        self._autoload = autoload
        self._refine_views = refine_views

        self.controls = c = C.DockControls(
            models=available_models(),
            model=model or DEFAULT_MODEL,
            disparity_sources=DISPARITY_SOURCES,
            disparity=None if disparity is None else str(disparity),
            reference_modes=list(REFERENCE_MODES),
            checkpoint=self._options.get("checkpoint"),
            random_weights=bool(self._options.get("random_weights")),
            refine_views=refine_views,
            consensus=consensus,
        )
        self.setLayout(c.layout)
        # the controls callers read through the widget
        self.model_box, self.weights_box = c.model_box, c.weights_box
        self.disparity_box, self.references_box = c.disparity_box, c.references_box
        self.objects, self.export_button = c.objects, c.export_button
        self.progress, self.status = c.progress, c.status
        self.work = W.WorkQueue(
            c.progress, deliver=self._on_event, error=self._error, status=self._set_status,
            finished=self._on_work_finished, segment=self._segment_now, parent=self,
        )
        self.follow = FollowController(self)  # a camera's growing frames folder (section 10)
        self._connect_controls()
        self.keeper = LayerKeeper(napari_viewer, adopt=self._adopt)
        self.layers: dict[str, Any] = self.keeper.layers
        self.masks = L.MaskLayers(self.layers, frame=lambda: getattr(self.session, "frame", 0))
        self.prompts = L.PromptLayers(self.layers, on_edit=self._on_prompts_edited)
        for key, func in self._keymap().items():
            self.viewer.bind_key(key, lambda _v, f=func: f(), overwrite=True)
        if video is not None:
            self.set_video(video)
        elif lightfield is not None:
            self.set_lightfield(lightfield)
        else:
            self.keeper.adopt_existing()

    # --- set-up -------------------------------------------------------------------------------
    def _connect_controls(self) -> None:
        c = self.controls
        c.load_button.clicked.connect(self.load_model)
        c.model_box.currentTextChanged.connect(self._on_model_changed)
        self._on_model_changed(c.model_box.currentText())
        c.weights_box.activated.connect(self._on_weights_activated)
        c.disparity_box.activated.connect(self._on_disparity_activated)
        c.refine_box.activated.connect(
            lambda _index: self.set_refine_views(c.refine_box.currentText())
        )
        c.consensus_box.clicked.connect(self.set_consensus)
        for button, action in (
            (c.segment_button, self.segment), (c.commit_button, self.commit),
            (c.clear_button, self.clear), (c.undo_button, self.undo), (c.redo_button, self.redo),
            (c.toggle_button, self.toggle_polarity),
            (c.everything_button, self.segment_everything),
            (c.find_button, self.find),
            (c.edit_button, lambda: self._on_selected(self.edit_object)),
            (c.remove_button, lambda: self._on_selected(self.remove_object)),
            (c.open_labels_button, self._open_selected_labels),
            (c.save_button, self._save_dialog), (c.export_button, self._export_dialog),
            (c.track_button, self.track), (c.stop_track_button, self.stop_tracking),
            (c.follow_button, self.follow.ask), (c.stop_follow_button, self.follow.stop),
        ):
            button.clicked.connect(lambda _=False, a=action: a())
        c.find_edit.returnPressed.connect(lambda: self.find())
        c.objects.itemDoubleClicked.connect(self._on_object_double_clicked)
        for name, button in c.view_buttons.items():
            button.clicked.connect(lambda _=False, n=name: self.show_display(n))
        c.export_button.setEnabled(_export_module() is not None)

    def _keymap(self) -> dict[str, Callable[[], None]]:
        """The dock's keys (bound on the viewer and on each fixed layer)."""
        return {key: getattr(self, name) for key, name in _KEYS.items()}

    def _adopt(self, layer: Any) -> bool:
        """Use ``layer`` as the light field if it is one; returns whether it was adopted."""
        if self.session is not None:
            return False
        video = video_of(layer)
        if video is not None:
            self.set_video(video, layer)
            return True
        lightfield = lightfield_of(layer)
        if lightfield is not None:
            self.set_lightfield(lightfield, layer)
        return lightfield is not None

    def set_lightfield(self, lightfield: LightField, layer: Any = None) -> None:
        """Show ``lightfield`` (one image layer) and create the prompt and mask layers."""
        self._start_session(ViewerSession, lightfield, lightfield, layer)

    def _start_session(self, kind: type, shown: Any, lightfield: LightField, layer: Any,
                       **extra: Any) -> None:
        self.session = kind(
            lightfield,
            model=self.model_box.currentText(),
            disparity=self.disparity_box.currentText(),
            cache_dir=self._cache_dir,
            segmenter_options=dict(self._options),
            text_options=dict(self._text_options),
            refine_views=self._refine_views,
            consensus=self.controls.consensus,
            **extra,
        )
        self.keeper.show(shown, layer, self._keymap())
        self.layers[L.COMMITTED].metadata[SESSION_KEY] = self.session
        lead = (0,) * self._frame_axes  # a video opens on its first frame, the session's
        rest = self.viewer.dims.current_step[self._frame_axes + 2 :]
        self.viewer.dims.current_step = (*lead, *lightfield.center, *rest)
        self.viewer.layers.selection.active = self.layers[L.POINTS]
        self.prompts.attach()
        self._refresh_objects()
        if self._autoload:
            self.load_model()

    @property
    def image_layer(self) -> Any:
        """The light field's image layer (None before there is one)."""
        return self.keeper.image_layer

    # --- running work -------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        """Whether a worker is running."""
        return self.work.busy

    @property
    def worker(self) -> Any:
        """The running napari worker, or None."""
        return self.work.worker

    @property
    def _segment_pending(self) -> bool:
        """Whether a segmentation waits for the running worker."""
        return self.work.segment_pending

    def _set_status(self, text: str) -> None:
        self.status.setText(text)
        if text:
            self.status_changed.emit(text)

    def _error(self, message: str) -> None:
        self._set_status(message)
        _notify_error(message)

    def _on_event(self, event: W.WorkerEvent) -> None:
        """Show what the worker yielded (main thread); partial masks of a left object are not."""
        match event:
            case W.ModelLoaded(model=model, device=device):
                where = f" on {device}" if device is not None else ""
                self._set_status(f"model {model} loaded{where}")
            case W.ReferenceMask(obj_id=obj_id) | W.CoarseMasks(obj_id=obj_id) if (
                obj_id != self.session.current_id
            ):
                return  # the object was committed or left meanwhile
            case W.ReferenceMask(obj_id=obj_id, view=view, mask=mask, score=score):
                self.stages.append(event.stage)
                self._show_current(obj_id, view=view, mask=mask)
                self._set_status(f"object {obj_id}: view {view} (score {score:.2f})")
            case W.CoarseMasks(obj_id=obj_id, prediction=prediction):
                self.stages.append(event.stage)
                self._show_current(obj_id, masks=prediction.masks.get(obj_id))
            case W.FinalMasks(prediction=prediction):
                self.stages.append(event.stage)
                self._show_prediction(prediction)
            case W.TextFound(prediction=prediction, phrase=phrase, finds=finds):
                self._show_prediction(prediction)
                found = sum(find["found"] for find in finds)
                where = ", ".join(f"view {f['view'][0]},{f['view'][1]}" for f in finds)
                self._set_status(
                    f"find {phrase!r}: {found or 'no'} object(s) in {where}"
                    + ("" if found else " (try another phrase or a lower threshold)")
                )
            case W.FrameTracked(index=index, total=total, labels=labels):
                self.masks.show_frame(index, labels)
                found = len(np.unique(labels)) - int((labels == 0).any())
                self._set_status(f"tracking frame {index + 1} of {total}: {found} object(s)")
                if index + 1 < total:
                    self.work.describe(f"tracking frame {index + 2} of {total}")
            case W.TrackStopped(index=index, total=total):
                previous = self.session.tracked
                if previous is not None:
                    self.layers[L.COMMITTED].data.attach_result(previous)
                    self.layers[L.COMMITTED].refresh()
                self._set_status(
                    f"tracking stopped after frame {index + 1} of {total}; nothing of it was "
                    + ("saved (the previous track is shown again)" if previous is not None
                       else "saved: Track again to track the whole video")
                )
            case W.Tracked(result=result):
                self.layers[L.COMMITTED].data.attach_result(result)
                self.layers[L.CURRENT].data.clear()
                for name in (L.COMMITTED, L.CURRENT):
                    self.layers[name].refresh()
                self._set_status(
                    f"tracked {len(result.object_ids)} object(s) through {len(result)} frames "
                    f"into {result.path}; Save copies the result folder"
                )
            case W.AllMasks(prediction=prediction, found=found):
                self._show_prediction(prediction)
                if found is not None:
                    self._set_status(
                        f"segment everything: {found or 'no'} new object(s) found; "
                        f"{len(prediction.masks)} in every view"
                    )

    def _on_work_finished(self) -> None:
        self._stop_track = None
        self.controls.stop_track_button.setEnabled(False)
        self._refresh_objects()
        if not self.keeper.closing:  # the light field's layer is gone, or the dock
            self.work.drain()

    # --- prompts ------------------------------------------------------------------------------
    @property
    def negative(self) -> bool:
        """Whether plain clicks add negative points (T toggles)."""
        return self.prompts.negative

    def toggle_polarity(self) -> None:
        """T: plain clicks add negative points instead of positive ones, or back."""
        self.prompts.set_negative(not self.prompts.negative)
        self.controls.show_polarity(self.prompts.negative)

    def _on_prompts_edited(self) -> None:
        if self.session is not None:
            grid = self.session.lightfield.grid_shape
            if self.session.history.push(self.prompts.read(self.session.current_id, grid)):
                self.segment()

    def _set_layer_prompts(self, obj: Any) -> None:
        self.prompts.write(obj, self.session.lightfield.center)

    def undo(self) -> None:
        """Ctrl-Z: undo the last prompt edit of the current object."""
        self.work.when_idle(lambda: self._apply_history(self.session.history.undo()))

    def redo(self) -> None:
        """Ctrl-Shift-Z: redo an undone prompt edit."""
        self.work.when_idle(lambda: self._apply_history(self.session.history.redo()))

    def _apply_history(self, obj: Any) -> None:
        self._set_layer_prompts(obj)
        self._segment_now()

    # --- actions ------------------------------------------------------------------------------
    def segment(self) -> None:
        """S: segment the current object from its prompts (worker; queued if busy)."""
        if self.session is not None:
            self.work.request_segment()

    def _segment_now(self) -> None:
        if not self.session.loaded:
            self.work.segment_pending = True
            self.load_model()
            return
        obj_id = self.session.current_id
        self.session.sync_current()
        if obj_id not in self.session.object_ids:  # no prompts left
            self._show_current(obj_id)
            return
        self.stages = []
        if self.is_video:
            frame = self.shown_frame()
            if not self.session.has_positive_at(frame):
                self.masks.clear_frame(L.CURRENT, frame)
                self._set_status(
                    f"object {obj_id} has no positive click or box on frame {frame}; its other "
                    "clicks there count when tracking (Track, Ctrl-T)"
                )
                return
            self.work.start(partial(W.video_segment_job, self.session, obj_id, frame), 3,
                            f"segmenting object {obj_id} in frame {frame}")
            return
        self.work.start(partial(W.segment_job, self.session, obj_id), 3,
                        f"segmenting object {obj_id}")

    def _predict_all(self, desc: str) -> None:
        self.work.start(partial(W.predict_all_job, self.session), 1, desc)

    def commit(self) -> None:
        """C: commit the current object; the next clicks start a new one."""
        self.work.when_idle(self._commit_now)

    def _commit_now(self) -> None:
        if self.session is None or not self.session.loaded:
            raise LfsamError("nothing to commit: load a model and segment an object first")
        self.session.sync_current()
        self.session.commit()
        self._set_layer_prompts(None)
        self._show_current(self.session.current_id)
        self._predict_all("committing")

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

        self.work.when_idle(run)

    def _when_loaded(self, run: Callable[[], None]) -> None:
        """Run ``run`` once the model is loaded (loading it first if need be)."""
        if self.session.loaded:
            run()
        else:
            self.load_model()
            self.work.when_idle(lambda: self._when_loaded(run))

    def segment_everything(self) -> None:
        """Automatic mode (``predictor.generate``): every object found, in its own layer."""

        def run() -> None:
            references = self.references_box.currentText()
            desc = "segmenting everything" + ("" if references == "center" else f" ({references})")
            self.work.start(partial(W.generate_job, self.session, references), 1, desc)

        if self.session is not None:
            self.work.when_idle(lambda: self._when_loaded(run))

    def shown_view(self) -> tuple[int, int]:
        """The view on the sliders (view row, view column)."""
        first = self._frame_axes
        s, t = (int(x) for x in self.viewer.dims.current_step[first : first + 2])
        grid = self.session.lightfield.grid_shape
        return min(max(s, 0), grid[0] - 1), min(max(t, 0), grid[1] - 1)

    def find(self, phrase: str | None = None, view: tuple[int, int] | None = None) -> None:
        """Text prompt (the "Find" field): every instance of ``phrase`` (default: the field's
        text) in ``view`` (default: the view shown) becomes an object, in the worker thread
        (docs/design.md section 9)."""
        phrase = self.controls.find_edit.text() if phrase is None else phrase
        if not phrase.split():
            self._set_status("type a phrase to find, e.g. red cup")
            return

        def run() -> None:
            where = self.shown_view() if view is None else view
            desc = f"finding {phrase.strip()!r}"
            self.work.start(partial(W.find_job, self.session, phrase, where), 1, desc)

        if self.session is not None:
            self.work.when_idle(lambda: self._when_loaded(run))

    def show_display(self, name: str) -> None:
        """Show the views (``"views"``) or an EPI (``"epi-row"``, ``"epi-column"``)."""
        order = L.ORDERS[name]
        if self.is_video:  # the frame axis stays first (a slider)
            order = (0, *(axis + 1 for axis in order))
        self.viewer.dims.order = order
        self.viewer.reset_view()

    # --- display ------------------------------------------------------------------------------
    @property
    def _prediction(self) -> Any:
        """The last LightFieldPrediction shown (or None)."""
        return self.masks.prediction

    def _show_current(self, obj_id: int, **shown: Any) -> None:
        """The current object's layer (:meth:`MaskLayers.show_current`), if ``obj_id`` still is
        the current object."""
        if obj_id == self.session.current_id:  # else it was committed or left meanwhile
            self.masks.show_current(obj_id, **shown)

    def _show_prediction(self, prediction: Any) -> None:
        if prediction is None:
            return
        session = self.session
        self.masks.show_prediction(prediction, session.committed, session.auto)
        self._show_current(session.current_id, masks=self.masks.mask_of(session.current_id))
        self._refresh_objects()
        refined = session.refined_summary()
        where = f" of frame {session.frame}" if self.is_video else ""
        self._set_status(
            f"{len(prediction.masks)} object(s) segmented in every view{where}"
            + ("" if refined is None else f"; {refined}, the others filled from them")
        )

    def _refresh_objects(self) -> None:
        if self.session is not None:
            session = self.session
            self.controls.show_objects(session.object_ids, session.current_id, session.auto)

    def closeEvent(self, event: Any) -> None:
        """Stop reacting to the viewer when the dock widget closes."""
        self.keeper.closing = True
        self.follow.stop()
        super().closeEvent(event)

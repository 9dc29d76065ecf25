"""The dock's model settings (mixed into :class:`lfsam.viewer.widget.LightFieldWidget`): the
model, its weights (a checkpoint, untrained or the hub's), the disparity source, the views refined
(docs/design.md section 3.7) and the multi-view consensus (section 3.9); a change reloads a loaded
model or refines the objects again in the worker.
"""

from __future__ import annotations

from functools import partial
from typing import Any

from lfsam.segmenters.registry import ORACLE
from lfsam.viewer import worker as W

__all__ = ["ModelDock"]


class ModelDock:
    """The model settings of the dock (mixed into the widget, which provides ``session``,
    ``controls``, ``work``, ``weights_box``, ``_options``, ``_refine_views``, ``_error`` and
    ``_predict_all``)."""

    session: Any
    controls: Any
    work: Any

    def _on_model_changed(self, name: str) -> None:
        self.weights_box.setEnabled(name != ORACLE)  # the oracle has no weights
        if self.session is not None and self.session.model != name:
            self.session.model = name
            self._reload()

    def _on_weights_activated(self, _index: int) -> None:
        in_use = (self._options.get("checkpoint"), bool(self._options.get("random_weights")))
        chosen = self.controls.pick_weights(self, in_use)
        if chosen is not None:
            self.set_weights(*chosen)

    def set_weights(self, checkpoint: str | None = None, random_weights: bool = False) -> None:
        """Use a checkpoint file, untrained weights or (neither) the hub's; reloads a loaded
        model (the CLI's ``--checkpoint`` and ``--random-weights``)."""
        self.controls.show_weights(checkpoint, random_weights)
        weights = {"checkpoint": checkpoint or None, "random_weights": bool(random_weights)}
        changed = any(self._options.get(key) != value for key, value in weights.items())
        self._options.update(weights)
        if self.session is not None and changed:
            self.session.segmenter_options = dict(self._options)
            if self.session.model != ORACLE:  # the oracle has no weights
                self._reload()

    def _on_disparity_activated(self, _index: int) -> None:
        in_use = None if self.session is None else str(self.session.disparity)
        source = self.controls.pick_disparity(self, in_use)
        if source is not None and self.session is not None and source != in_use:
            self.session.disparity = source
            self._reload()

    def set_refine_views(self, setting: str | int) -> None:
        """Refine ``"all"`` views, ``"sparse"`` or N (docs/design.md section 3.7). The objects
        are refined again in a worker: ``"all"`` after a sparse pass encodes and refines only
        the remaining views (their masks replace the filled ones as it finishes)."""
        from lfsam.pipeline.sparse import check_refine_views

        setting = check_refine_views(setting)
        self._refine_views = setting
        self.controls.show_refine_views(setting)
        session = self.session
        if session is None or session.refine_views == setting:
            return
        session.set_refine_views(setting)
        if session.loaded and session.object_ids:
            self.work.when_idle(lambda: self._predict_all(f"refining {setting} views"))

    def set_consensus(self, on: bool) -> None:
        """Turn the multi-view consensus on or off (docs/design.md section 3.9) once the worker
        is idle; the objects are then refined again in it (``ViewerSession.set_consensus``)."""
        self.controls.show_consensus(on)

        def run() -> None:
            if self.session is not None and self.session.set_consensus(on):
                self._predict_all(f"refining {'with' if on else 'without'} consensus")

        self.work.when_idle(run)

    def _reload(self) -> None:
        """Load the model again if it is loaded (its name, weights or disparity changed)."""
        if self.session.loaded:
            self.load_model()

    def load_model(self) -> None:
        """Load the chosen model and disparity source (worker); objects are recomputed."""
        if self.session is None:
            self._error("no light field: open one first (File > Open, or `lfsam view LF`)")
            return
        job = partial(W.load_job, self.session)
        self.work.when_idle(lambda: self.work.start(job, 2, f"loading {self.session.model}"))


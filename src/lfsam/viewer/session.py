"""The state behind the viewer's widget, free of Qt and napari: objects, prompts, undo, results.

The widget (:mod:`lfsam.viewer.widget`) is a thin layer over this module: it turns napari layer
data into prompts and back (:mod:`lfsam.viewer.prompt_layers`), and runs
the slow calls of a :class:`ViewerSession` (loading the model, the coarse-to-fine prediction,
automatic segmentation) in a worker thread. All segmentation is done by
:class:`lfsam.predictor.LightFieldPredictor` (docs/design.md section 8); this module only keeps
track of which object is being edited, which are committed and which came from the automatic
mode, and of the prompt history for undo and redo.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import check_output_path, check_writable
from lfsam.generator import LightFieldMaskGenerator
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.sparse import check_refine_views
from lfsam.predictor import LightFieldPredictor
from lfsam.prompts import TextPrompt
from lfsam.result import SegmentationResult, save_result
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.registry import ORACLE
from lfsam.segmenters.text import (
    DEFAULT_TEXT_MODEL,
    TEXT_ORACLE,
    TextDetector,
    load_text_detector,
)
from lfsam.text_search import TextFind, find_text
from lfsam.viewer.native_libraries import preload_native_libraries
from lfsam.viewer.prompt_layers import PromptHistory

__all__ = [
    "DISPARITY_SOURCES",
    "SAM2_ONLY_OPTIONS",
    "ViewerSession",
]

#: Keywords of :func:`lfsam.segmenters.load_segmenter` that only a SAM 2 model takes.
SAM2_ONLY_OPTIONS = ("checkpoint", "random_weights", "amg_options", "precision")

#: Disparity sources the widget offers besides a file (``set_lightfield(disparity=...)``).
DISPARITY_SOURCES = ("estimate", "gt")


@dataclass
class ViewerSession:
    """One annotation session on one light field.

    Parameters
    ----------
    lightfield : LightField
        The light field shown.
    model : str
        Segmenter name (:func:`lfsam.segmenters.available_models`).
    disparity : str or path or ndarray
        ``"estimate"``, ``"gt"``, a ``.npy`` path or a ``(U, V)`` array
        (``LightFieldPredictor.set_lightfield``).
    cache_dir : path, optional
        Embedding cache of the predictor (docs/design.md section 8).
    segmenter_options : dict
        Further keywords of :func:`lfsam.segmenters.load_segmenter` (e.g. ``oracle_options``).
    refine_views : str or int
        Which views SAM 2 refines (docs/design.md section 3.7): ``"all"``, ``"sparse"`` or N.
    consensus : bool
        The multi-view consensus after refinement (docs/design.md section 3.9).
    text_options : dict
        The text detector of :meth:`find` (docs/design.md section 9): ``text_model`` (default
        the oracle with the oracle segmenter, else ``sam3``), ``text_checkpoint``,
        ``text_threshold``.
    """

    lightfield: LightField
    model: str = "sam2.1-hiera-small"
    disparity: Any = "estimate"
    cache_dir: str | os.PathLike | None = None
    segmenter_options: dict[str, Any] = field(default_factory=dict)
    text_options: dict[str, Any] = field(default_factory=dict)
    refine_views: str | int = "all"
    consensus: bool = False
    predictor: Any = None
    current_id: int = 1
    committed: set[int] = field(default_factory=set)
    auto: set[int] = field(default_factory=set)
    history: PromptHistory = field(default_factory=PromptHistory)
    _given: tuple | None = field(default=None, repr=False)  # (id, view, mask) being edited
    _detector: tuple[str, TextDetector] | None = field(default=None, repr=False)

    # --- model --------------------------------------------------------------------------------
    @property
    def loaded(self) -> bool:
        """Whether the predictor is built (the segmenter is loaded)."""
        return self.predictor is not None

    def load(self) -> None:
        """Build the segmenter and the predictor (slow: run it in a worker thread).

        Objects of a previous predictor (another model or disparity source) are carried over.

        Raises
        ------
        LfsamError
            Unknown model, weights missing offline, oracle without labels, bad disparity.
        """

        preload_native_libraries()  # a no-op when the widget did it in the main thread
        predictor = self._new_predictor(self.lightfield)
        old = self.predictor
        if old is not None and old.object_ids:
            if set(old.objects) == set(old.object_ids):  # every object has prompts
                for obj in old.objects.values():
                    predictor.set_object(obj)
            else:  # automatic or imported objects are carried by their masks
                predictor.open_result(old.to_result())
        self.predictor = predictor

    def segmenter_keywords(self) -> dict[str, Any]:
        """The keywords of :func:`lfsam.segmenters.load_segmenter` for :attr:`model` (the
        options of the other kind of segmenter stay for when the model box switches back)."""
        options = dict(self.segmenter_options)
        dropped = SAM2_ONLY_OPTIONS if self.model == ORACLE else ("oracle_options",)
        for key in dropped:
            options.pop(key, None)
        return options

    def _new_predictor(self, lightfield: LightField, segmenter: Any = None) -> Any:
        """A predictor on ``lightfield`` with ``segmenter`` (default: a new one of
        :attr:`model`), its disparity set (slow: worker thread)."""
        if segmenter is None:
            segmenter = load_segmenter(self.model, lightfield=lightfield,
                                       **self.segmenter_keywords())
        predictor = LightFieldPredictor(segmenter, self.pipeline_config(), cache_dir=self.cache_dir)
        predictor.set_lightfield(lightfield, disparity=self.disparity)
        return predictor

    def set_refine_views(self, setting: str | int) -> None:
        """Refine ``"all"`` views, ``"sparse"`` or N from now on; a loaded predictor refines
        its objects again at the next prediction (``LightFieldPredictor.set_refine_views``:
        after a sparse pass, ``"all"`` encodes and refines only the remaining views)."""
        self.refine_views = check_refine_views(setting)
        if self.predictor is not None:
            self.predictor.set_refine_views(self.refine_views)

    def pipeline_config(self) -> PipelineConfig:
        """The pipeline settings of every predictor, track and stream of this session: the
        refined views (docs/design.md section 3.7) and the consensus (section 3.9)."""
        return PipelineConfig(refine_views=self.refine_views, consensus=self.consensus)

    def set_consensus(self, on: bool) -> bool:
        """Turn the multi-view consensus (docs/design.md section 3.9) on or off from now on; a
        loaded predictor refines its objects again at the next prediction
        (``LightFieldPredictor.set_consensus``).

        Returns
        -------
        bool
            Whether the setting changed while a model with objects is loaded, i.e. whether the
            objects should be predicted again to show it.
        """
        on = bool(on)
        changed, self.consensus = on != self.consensus, on
        if self.predictor is not None:
            self.predictor.set_consensus(on)
        return changed and self.loaded and bool(self.object_ids)

    def refined_summary(self) -> str | None:
        """E.g. ``"13 of 81 views refined (sparse)"``; None when every view is refined."""
        if self.predictor is None or self.refine_views == "all":
            return None
        flags = self.predictor.refined_views
        present = int(np.count_nonzero(self.lightfield.present))
        return f"{int(flags.sum())} of {present} views refined ({self.refine_views})"

    def _require(self) -> Any:
        if self.predictor is None:
            raise LfsamError("no model is loaded yet; pick a model and press Load")
        return self.predictor

    # --- objects ------------------------------------------------------------------------------
    @property
    def object_ids(self) -> list[int]:
        """Ids of every object the predictor holds (prompted, automatic, imported), sorted."""
        return list(self.predictor.object_ids) if self.predictor is not None else []

    def next_id(self) -> int:
        """A fresh object id: one more than any id in use."""
        used = {*self.object_ids, *self.committed, *self.auto, self.current_id}
        return max(used) + 1

    def sync_current(self) -> Any | None:
        """Give the predictor the current object's prompts as the history has them.

        An automatic or imported object being edited (no prompts) keeps its mask until it is
        given prompts, and gets its mask back when every prompt edit is undone.

        Returns
        -------
        ObjectPrompts or None
            The current prompts.
        """
        pred = self._require()
        obj = self.history.current
        obj_id = self.current_id
        if obj is not None:
            if pred.objects.get(obj_id) != obj:
                pred.set_object(obj)
        elif self._given is not None and self._given[0] == obj_id:
            if obj_id in pred.objects:  # prompted meanwhile: back to the given mask
                pred.add_mask(obj_id, self._given[2], view=self._given[1])
        elif obj_id in pred.object_ids:
            pred.remove_object(obj_id)
        return obj

    def current_prompts(self) -> Any | None:
        """The current object's prompts, or None."""
        if self.predictor is None:
            return None
        return self.predictor.objects.get(self.current_id)

    def segment_current(self) -> Iterator[tuple[str, Any]]:
        """Segment the current object, coarse to fine (run it in a worker thread).

        Yields
        ------
        ("reference", (view, mask, score))
            The mask in the view the object is prompted in (``predict_reference``).
        ("coarse", LightFieldPrediction)
            Every view, propagated and occluded, not refined (``predict_coarse``).
        ("final", LightFieldPrediction)
            Every object, refined (``predict``; unchanged objects are reused).
        """
        pred = self._require()
        obj_id = self.current_id
        if obj_id not in pred.object_ids:
            return
        yield "reference", pred.predict_reference(obj_id)
        yield "coarse", pred.predict_coarse([obj_id])
        yield "final", pred.predict()

    def predict_all(self) -> Any:
        """Every object's masks (unchanged objects are reused; worker thread)."""
        return self._require().predict()

    def commit(self) -> int:
        """Commit the current object; returns its id. A new current id is chosen."""
        obj_id = self.current_id
        if obj_id not in self.object_ids:
            raise LfsamError("nothing to commit: add a point or a box to the object first")
        self.committed.add(obj_id)
        self.auto.discard(obj_id)
        self.current_id = self.next_id()
        self.history.reset()
        self._given = None
        return obj_id

    def edit(self, obj_id: int) -> Any | None:
        """Make object ``obj_id`` the one being edited; returns its prompts.

        The object being edited before, if it has prompts, is committed first.
        """
        pred = self._require()
        if obj_id not in pred.object_ids:
            raise LfsamError(f"there is no object {obj_id}; pick one from the list")
        if self.current_id != obj_id and self.current_id in pred.object_ids:
            self.committed.add(self.current_id)
        self.committed.discard(obj_id)
        self.auto.discard(obj_id)
        self.current_id = obj_id
        obj = pred.objects.get(obj_id)  # None for an automatic or imported object
        self._given = None
        if obj is None:
            view, mask, _ = pred.predict_reference(obj_id)
            self._given = (obj_id, tuple(view), np.asarray(mask, dtype=bool))
        self.history.reset(obj)
        return obj

    def remove(self, obj_id: int) -> None:
        """Delete object ``obj_id`` (its prompts and masks)."""
        pred = self._require()
        if obj_id in pred.object_ids:
            pred.remove_object(obj_id)
        self.committed.discard(obj_id)
        self.auto.discard(obj_id)
        if obj_id == self.current_id:
            self.history.reset()

    def clear_current(self) -> None:
        """Remove the current object's prompts (Shift-C); the id stays."""
        if self.predictor is not None and self.current_id in self.predictor.object_ids:
            self.predictor.remove_object(self.current_id)
        self.history.reset()

    def generate(self, references: str = "center") -> Any:
        """Automatic mode: add every object found, then predict (worker thread).

        ``references`` is :class:`lfsam.generator.LightFieldMaskGenerator`'s: ``center`` (the
        paper's setting), or also ``corners``, ``ring`` or ``all`` to find objects the center
        view cannot see (docs/design.md section 8).
        """
        pred = self._require()
        ids = LightFieldMaskGenerator(pred, references).generate()
        self.auto.update(int(i) for i in ids)
        if self.current_id in self.auto:
            self.current_id = self.next_id()
        return pred.predict()

    def text_detector(self) -> TextDetector:
        """The text detector of :attr:`text_options`, built once per detector name (slow for
        SAM 3: call it in the worker thread)."""
        name = self.text_options.get("text_model") or (
            TEXT_ORACLE if self.model == ORACLE else DEFAULT_TEXT_MODEL
        )
        if self._detector is None or self._detector[0] != name:
            detector = load_text_detector(
                name,
                checkpoint=self.text_options.get("text_checkpoint"),
                random_weights=bool(self.segmenter_options.get("random_weights")),
                device=self.segmenter_options.get("device"),
                lightfield=self.lightfield,
            )
            self._detector = (name, detector)
        return self._detector[1]

    def find(
        self, phrase: str, view: tuple[int, int] | None = None
    ) -> tuple[Any, list[TextFind]]:
        """Text prompt: every instance of ``phrase`` in ``view`` (None = center) becomes an
        object with the phrase as its category, then every object is predicted (worker
        thread; docs/design.md section 9).

        Returns
        -------
        prediction : LightFieldPrediction
        finds : list of TextFind
            What the phrase found (:func:`lfsam.text_search.find_text`).
        """
        pred = self._require()
        finds = find_text(
            pred, self.text_detector(), [TextPrompt(phrase, view)],
            threshold=self.text_options.get("text_threshold"),
        )
        self.auto.update(i for find in finds for i in find.ids)
        if self.current_id in self.auto:
            self.current_id = self.next_id()
        return pred.predict(), finds

    def open_result(self, result: Any) -> list[int]:
        """Reopen a result's objects for editing (``LightFieldPredictor.open_result``).

        Prompted objects come back with their prompts, the others (automatic, imported) with
        their reference-view masks; all are committed.

        Returns
        -------
        ids : list of int
            The objects added.
        """
        pred = self._require()
        before = set(pred.object_ids)
        pred.open_result(result)
        ids = sorted(set(pred.object_ids) - before)
        if not ids:
            raise LfsamError(
                "this result has no objects to reopen; open a result saved by lfsam or a "
                "labels layer with objects"
            )
        self.committed.update(ids)
        self.current_id = self.next_id()
        return ids

    def open_labels(self, labels: np.ndarray) -> list[int]:
        """Reopen a labels array ``(S, T, U, V)`` (label value = object id) for editing.

        Each label becomes an object given by its mask in the view where it is largest.
        """

        labels = np.asarray(labels)
        if labels.shape != self.lightfield.views.shape[:4]:
            raise LfsamError(
                f"labels of shape {labels.shape} do not fit the light field "
                f"{self.lightfield.views.shape[:4]}; open labels of the same light field"
            )
        labels = labels.astype(np.int32)
        ids = [int(i) for i in np.unique(labels) if i > 0]
        if not ids:
            raise LfsamError("this labels layer is empty; paint or segment an object first")
        s_count, t_count = labels.shape[:2]
        flat = labels.reshape(s_count * t_count, -1)
        areas = np.stack([np.bincount(row, minlength=ids[-1] + 1) for row in flat])
        best = areas[:, ids].argmax(axis=0)
        objects = [
            {"id": i, "reference_view": [int(b // t_count), int(b % t_count)], "mask": "given"}
            for i, b in zip(ids, best, strict=True)
        ]
        meta = {"object_ids": ids, "objects": objects}
        return self.open_result(SegmentationResult(labels=labels, meta=meta))

    # --- output -------------------------------------------------------------------------------
    def to_result(self) -> Any:
        """The session as a normal lfsam result, prompts included (``predictor.to_result``)."""
        pred = self._require()
        if not pred.object_ids:
            raise LfsamError("nothing to save: segment at least one object first")
        return pred.to_result()

    def check_save(self, path: str | os.PathLike) -> Path:
        """Check that Save can write ``path`` (its folder exists and takes files), before any
        work; raises :class:`LfsamError` in one line otherwise."""
        check_output_path(path)
        return check_writable(path, folder=False, option="the file to save")

    def save(self, path: str | os.PathLike) -> Path:
        """Write the result to ``path`` (``.npz``, atomic; checked first)."""
        self.check_save(path)
        return save_result(self.to_result(), path)

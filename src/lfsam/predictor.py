"""Interactive light-field segmentation: :class:`LightFieldPredictor`.

The life cycle follows Meta's ``SAM2ImagePredictor`` and video predictor: :meth:`set_lightfield`
once, then :meth:`~LightFieldPredictor.add_prompts` per object id (points positive or negative,
at most one box, each in any view), then :meth:`~LightFieldPredictor.predict`. Each object runs
the paper's four steps (section 3) from its own *reference view* (docs/design.md section 8):

1. initial segmentation of the reference view from the object's prompts (clicks given in other
   views are carried there by their own view's disparity);
2. disparity propagation of that mask into every view with the reference view's disparity;
3. occluding (semantic with SAM 2's features, and/or geometric);
4. refinement: SAM 2 re-prompted in every view with a box and a point from the surviving
   pixels, plus the user's own clicks carried into that view (a click that lands outside the
   view or behind a closer surface is dropped there).

Coarse to fine, each stage callable on its own: :meth:`predict_reference` (the clicked view),
:meth:`predict_coarse` (steps 1-3 in all views), :meth:`predict` (all four steps). Changing one
object recomputes that object only; every other object's masks are kept as they were. Overlaps
between objects keep the pipeline's paint order (larger reference-view masks first, smaller on
top; docs/design.md section 3.6), and an object's label value is its id.

A facade: objects and clicks live in :mod:`lfsam.pipeline.objects`, the streaming of views,
which views are refined and the run's metadata in :mod:`lfsam.pipeline.engine`, results in
:mod:`lfsam.result_objects`; the automatic mode and text prompts wrap it from outside
(:class:`lfsam.generator.LightFieldMaskGenerator`, :mod:`lfsam.text_search`), light-field video
too (:mod:`lfsam.video.tracking.track`); batch: :func:`lfsam.segment`.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.engine import StreamingEngine
from lfsam.pipeline.objects import ObjectTable, TrackedObject, View
from lfsam.prediction import LightFieldPrediction
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt, validate_objects
from lfsam.result import SegmentationResult
from lfsam.result_objects import GivenMask, build_result, result_objects
from lfsam.segmenters.base import Segmenter, ViewEmbedding
from lfsam.timing import StageTimer
from lfsam.version import __version__

__all__ = ["LightFieldPrediction", "LightFieldPredictor", "View"]


class LightFieldPredictor:
    """Prompt objects in any view of a light field; get view-consistent 4D masks.

    Parameters
    ----------
    segmenter : Segmenter
        SAM 2 or the oracle (:func:`lfsam.segmenters.load_segmenter`), configured when built
        (the predictor never changes it).
    config : PipelineConfig, optional
        Switches and thresholds (default: the paper's full method).
    cache_dir : path, optional
        On-disk embedding cache (keyed by view content, model and weights).
    memory_budget_mb : float
        In-memory embedding budget (least recently used views dropped beyond it).
    progress : bool
        Progress bars over views.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> from lfsam.segmenters import load_segmenter
    >>> lf = generate_scene(grid=(3, 3), size=(48, 64), seed=0)
    >>> predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf))
    >>> predictor.set_lightfield(lf, disparity="gt")
    >>> predictor.add_prompts(1, points=[(32, 24)], labels=[1])
    ObjectPrompts(obj_id=1, points=(PointPrompt(x=32.0, y=24.0,
                  positive=True, view=(1, 1)...),), box=None)
    >>> prediction = predictor.predict()
    >>> prediction.labels.shape
    (3, 3, 48, 64)
    """

    def __init__(
        self,
        segmenter: Segmenter,
        config: PipelineConfig | None = None,
        *,
        cache_dir: Any = None,
        memory_budget_mb: float = 2048.0,
        progress: bool = False,
    ) -> None:
        self.segmenter = segmenter
        self.config = config or PipelineConfig()
        self.cache_dir = cache_dir
        self.memory_budget_mb = memory_budget_mb
        self.progress = progress
        self.device = segmenter.device
        self.seconds = 0.0
        self.lightfield: LightField | None = None
        self._engine: StreamingEngine | None = None
        self._table = ObjectTable()
        self._labels_cache: dict[str, np.ndarray] = {}

    # --- light field -------------------------------------------------------------------------
    def set_lightfield(self, lightfield: LightField, disparity: Any = "estimate") -> None:
        """Take a light field and where its disparity comes from; forget every object.

        Parameters
        ----------
        lightfield : LightField
        disparity : {"estimate", "gt"}, path to a .npy, or ndarray
            Resolved lazily, once per reference view (docs/design.md section 8): the view of
            each object's prompts. A ``(U, V)`` array is the center view's disparity; an
            ``(S, T, U, V)`` array gives every view's.
        """
        self.lightfield = lightfield
        self._engine = StreamingEngine(
            self.segmenter, self.config, lightfield, disparity, cache_dir=self.cache_dir,
            memory_budget_mb=self.memory_budget_mb, progress=self.progress,
        )
        self._table = ObjectTable()
        self._labels_cache = {}

    def set_refine_views(self, setting: str | int) -> None:
        """Refine ``"all"`` views, ``"sparse"`` or N of them from now on (docs/design.md
        section 3.7), e.g. ``"all"`` to finish the views a sparse pass filled."""
        self._refine_again(refine_views=setting)

    def set_consensus(self, on: bool) -> None:
        """The multi-view consensus on or off from now on (docs/design.md section 3.9)."""
        self._refine_again(consensus=bool(on))

    def _refine_again(self, **changes: Any) -> None:
        """Change settings of refinement only: objects refined under other settings are
        refined again at the next :meth:`predict` (step-1 and coarse masks and the embeddings
        stay)."""
        config = replace(self.config, **changes)
        if config != self.config:
            self.config = config
            if self._engine is not None:
                self._engine.config = config
                self._table.forget_refined()
                self._labels_cache.pop("refined", None)

    @property
    def refined_views(self) -> np.ndarray | None:
        """``(S, T)`` bool: the views refined with SAM 2 for at least one object (all present
        views with ``refine_views="all"``); None before a light field is set."""
        return None if self._engine is None else self._engine.refined_views(self._table)

    def require_lightfield(self) -> LightField:
        """The light field set; an :class:`LfsamError` when none is."""
        if self.lightfield is None:
            raise LfsamError("no light field set; call set_lightfield(lightfield) first")
        return self.lightfield

    @property
    def engine(self) -> StreamingEngine:
        """The streaming engine of the light field set (embeddings, disparities, timings)."""
        self.require_lightfield()
        return self._engine

    @property
    def timer(self) -> StageTimer:
        """Seconds per stage since the light field was set."""
        return self.engine.timer

    @property
    def decode_counts(self) -> Mapping[int, int]:
        """Prompts decoded per object id (each decoder row counts once)."""
        return self.engine.decode_counts

    @property
    def views_encoded(self) -> int:
        """Image-encoder runs on views so far (0 when all came from the disk cache)."""
        return 0 if self.lightfield is None else self._engine.store.views_encoded

    def embedding(self, view: View) -> ViewEmbedding:
        """The embedding of ``view`` (encoded on first use, then cached)."""
        return self.engine.embedding(view)

    def disparity(self, view: View) -> Any:
        """Disparity of ``view`` as a tensor on the segmenter's device (resolved once)."""
        return self.engine.disparity(view)

    # --- objects -----------------------------------------------------------------------------
    @property
    def objects(self) -> dict[int, ObjectPrompts]:
        """The prompts of every prompted object, by id."""
        return self._table.prompts()

    @property
    def object_ids(self) -> list[int]:
        """Ids of every object (prompted, automatic or imported), ascending."""
        return self._table.ids

    def next_id(self) -> int:
        """The smallest id larger than every id in use."""
        return self._table.next_id()

    def add_prompts(
        self,
        obj_id: int,
        points: Sequence[Sequence[float]] | None = None,
        labels: Sequence[int] | None = None,
        box: Sequence[float] | None = None,
        view: View | None = None,
    ) -> ObjectPrompts:
        """Add clicks (and/or set the box) of object ``obj_id`` in ``view`` (None = center).

        Points are ``(x, y)`` = (pixel column, pixel row); ``labels`` 1 = positive, 0 =
        negative (default all positive). A box replaces the object's box. Only this object is
        recomputed at the next prediction.

        Returns
        -------
        ObjectPrompts
            The object's prompts after the edit.
        """
        lf = self.require_lightfield()
        view = lf.center if view is None else (int(view[0]), int(view[1]))
        points = [] if points is None else [tuple(map(float, p)) for p in points]
        labels = [1] * len(points) if labels is None else [int(x) for x in labels]
        if len(labels) != len(points):
            raise LfsamError(f"object {obj_id}: {len(points)} points but {len(labels)} labels")
        base = getattr(self._table.objects.get(obj_id), "prompts", None) or ObjectPrompts(
            int(obj_id))
        new = base.with_points(PointPrompt(x, y, label == 1, view)
                               for (x, y), label in zip(points, labels, strict=True))
        if box is not None:
            new = new.with_box(BoxPrompt(*map(float, box), view=view))
        self.set_object(new)
        return new

    def set_object(self, prompts: ObjectPrompts) -> None:
        """Set (or replace) one object's prompts; only it is recomputed."""
        lf = self.require_lightfield()
        prompts = prompts.resolved(lf.center)
        validate_objects([prompts], lf.grid_shape, lf.view_shape)
        for view in prompts.views(lf.center):
            if not lf.present[view]:
                raise LfsamError(f"object {prompts.obj_id}: view {view[0]},{view[1]} is absent "
                                 "from this light field; prompt a view that exists")
        self._table.put(prompts.obj_id, TrackedObject(prompts=prompts))
        self._labels_cache.clear()

    def add_mask(
        self,
        obj_id: int,
        mask: np.ndarray,
        view: View | None = None,
        score: float = 1.0,
        *,
        automatic: bool = False,
        category: str | None = None,
    ) -> None:
        """Add an object given by its mask in one view (automatic masks, imported labels, text
        detections: ``category`` is the phrase, kept in results; docs/design.md section 9)."""
        lf = self.require_lightfield()
        view = lf.center if view is None else (int(view[0]), int(view[1]))
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != lf.view_shape:
            raise LfsamError(
                f"object {obj_id}: mask has shape {mask.shape}, expected {lf.view_shape}"
            )
        if int(obj_id) < 1:
            raise LfsamError(f"object {obj_id}: id must be an integer >= 1")
        self._table.put(obj_id, TrackedObject(
            prompts=None, given_mask=mask, given_view=view, given_score=float(score),
            automatic=automatic, category=category,
        ))
        self._labels_cache.clear()

    def category(self, obj_id: int) -> str | None:
        """The phrase a text prompt found object ``obj_id`` by (None for other objects)."""
        return self._table[self._table.check([obj_id])[0]].category

    def given_mask(self, obj_id: int) -> tuple[View, np.ndarray] | None:
        """The view and mask an object was given by (:meth:`add_mask`); None for a prompted
        object."""
        obj = self._table[self._table.check([obj_id])[0]]
        return None if obj.prompts is not None else (obj.given_view, obj.given_mask)

    def remove_object(self, obj_id: int) -> None:
        """Forget one object (its label disappears from every view)."""
        self._table.remove(obj_id)
        self._labels_cache.clear()

    def reset_objects(self) -> None:
        """Forget every object (embeddings and disparities are kept)."""
        self._table.clear()
        self._labels_cache.clear()

    def renumber(self, ids: Sequence[int]) -> list[int]:
        """Give the objects ``ids`` (in order) consecutive ids from the smallest of them,
        closing gaps (e.g. after merges); returns their new ids."""
        mapping = self._table.renumber(list(ids))
        if self._engine is not None:
            self._engine.renumber_counts(mapping)
        self._labels_cache.clear()
        return list(mapping.values())

    # --- predictions at each stage ------------------------------------------------------------
    def predict_reference(self, obj_id: int) -> tuple[View, np.ndarray, float]:
        """Stage 1 alone: the object's mask in its reference (clicked) view.

        Returns
        -------
        view : (s, t)
        mask : (U, V) bool ndarray
        score : float
        """
        ids = self._ids([obj_id])
        start = time.perf_counter()
        self._engine.ensure_references(self._table, ids)
        self.seconds += time.perf_counter() - start
        ref = self._table[obj_id].reference
        return ref.view, ref.mask.cpu().numpy(), ref.score

    def predict_coarse(self, obj_ids: Iterable[int] | None = None) -> LightFieldPrediction:
        """Steps 1-3 (propagation and occluding, no refinement) for the given objects (default
        all); objects computed before are reused."""
        ids = self._ids(obj_ids)
        self._run([i for i in ids if self._table[i].coarse is None], refine=False)
        return self._prediction("coarse")

    def predict(self, obj_ids: Iterable[int] | None = None) -> LightFieldPrediction:
        """All four steps for the given objects (default all); objects computed before and
        not edited since are reused as they were."""
        ids = self._ids(obj_ids)
        self._run([i for i in ids if self._table[i].refined is None], refine=True)
        return self._prediction("refined")

    def masks_in_view(self, ids: Sequence[int], view: View) -> np.ndarray:
        """The objects ``ids``' final masks in one view, ``(N, U, V)`` bool, computed for this
        view only and not stored (:meth:`lfsam.pipeline.engine.StreamingEngine.masks_in_view`)."""
        return self.engine.masks_in_view(self._table, self._ids(ids), view)

    def paint_order(self, ids: Sequence[int] | None = None) -> list[int]:
        """Object ids in paint order: larger reference-view masks first, smaller on top (ties
        by id); docs/design.md section 3.6."""
        return self._table.paint_order(self.object_ids if ids is None else list(ids))

    def _ids(self, obj_ids: Iterable[int] | None) -> list[int]:
        self.require_lightfield()
        return self.object_ids if obj_ids is None else self._table.check(obj_ids)

    def _run(self, ids: list[int], refine: bool) -> None:
        if not ids:
            return
        start = time.perf_counter()
        engine = self._engine
        engine.ensure_references(self._table, ids)
        # Every object computed in this pass (a batch run): labels are fused on the device.
        everything = set(ids) == set(self._table.objects)
        stage = "refined" if refine or not self.config.refine else "coarse"
        order = self._table.paint_order(ids) if everything else None
        labels = engine.run(self._table, ids, refine, order)
        self._labels_cache.clear()
        if labels is not None:
            self._labels_cache[stage] = labels
        self.seconds += time.perf_counter() - start

    def _prediction(self, stage: str) -> LightFieldPrediction:
        lf = self.require_lightfield()
        shape = (*lf.grid_shape, *lf.view_shape)
        prediction = self._table.prediction(
            stage, shape, self._engine.fuse, self._labels_cache.get(stage)
        )
        self._labels_cache[stage] = prediction.labels
        return prediction

    # --- results ------------------------------------------------------------------------------
    def to_result(self) -> SegmentationResult:
        """The objects' refined masks as a :class:`~lfsam.result.SegmentationResult`
        (:func:`lfsam.result_objects.build_result`: prompts kept, so it reopens editable;
        ``meta["views_encoded"]`` counts image-encoder runs)."""
        lf = self.require_lightfield()
        prediction = self.predict()
        timings = dict(self._engine.timer.seconds)
        timings["total"] = self.seconds + self._engine.timer.outermost.get("disparity", 0.0)
        meta = {"method": "lfsam", "package_version": __version__, **self._engine.run_meta(),
                "refined_views": self.refined_views.tolist()}
        return build_result(lf, self._table.objects, prediction.labels, timings, meta)

    def open_result(self, result: SegmentationResult) -> None:
        """Take a result's objects: prompted ones by their prompts, the others (automatic or
        imported) by their reference-view masks; then :meth:`predict` reproduces it."""
        for obj in result_objects(result, self.require_lightfield()):
            if isinstance(obj, GivenMask):
                self.add_mask(
                    obj.obj_id, obj.mask, view=obj.view, score=obj.score, category=obj.category
                )
            else:
                self.set_object(obj)

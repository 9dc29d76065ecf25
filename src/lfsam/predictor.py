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
:meth:`predict_coarse` (steps 1-3 in all views), :meth:`predict` (all four steps). Views are
encoded lazily, at most once (:class:`lfsam.embeddings.EmbeddingStore`: an in-memory LRU within
a budget, optionally an on-disk cache). Changing one object recomputes that object only; every
other object's masks are kept as they were. Overlaps between objects keep the pipeline's paint
order (larger reference-view masks first, smaller on top; docs/design.md section 3.6), and an
object's label value is its id.

The batch path (:func:`lfsam.pipeline.segment_lightfield`, ``lfsam segment``, evaluation and
benchmarks) runs on this predictor too.
"""

from __future__ import annotations

import time
from collections import Counter, OrderedDict, defaultdict
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from lfsam import __version__
from lfsam.embeddings import EmbeddingStore
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import initial_segmentation
from lfsam.pipeline.occlusion import semantic_occlusion, source_features, uniform_weights
from lfsam.pipeline.propagation import (
    ForwardWarp,
    forward_warp,
    propagate_masks,
)
from lfsam.pipeline.refinement import refine_masks
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt, prompts_to_json, validate_objects
from lfsam.result import PackedMasks, SegmentationResult, pack_masks
from lfsam.segmenters.base import Prompts, Segmenter, ViewEmbedding
from lfsam.timing import StageTimer

__all__ = ["LightFieldPrediction", "LightFieldPredictor"]

View = tuple[int, int]

#: Prompts of one view refined per decoder call on CUDA (one call for the paper's 100 masks;
#: measured on an H100 with bench_gpu.py, docs/performance.md); 64 elsewhere.
REFINE_CHUNK_CUDA = 128

#: Generator rounds in an extra reference view of the automatic mode: the thinned grid, then
#: points in the regions no answer explains (docs/design.md section 8).
EXTRA_VIEW_ROUNDS = 3

#: Forward warps (reference view, target view) kept for reuse across edits, in bytes.
WARP_CACHE_BYTES = 512 * 2**20


def _warp_nbytes(warp: ForwardWarp) -> int:
    """Memory of a cached warp: its arrays, plus the seen-pixel map it keeps once asked (the
    holes it keeps are a small fraction of a view)."""
    arrays = (warp.target, warp.valid, warp.zbuffer)
    return sum(x.numel() * x.element_size() for x in arrays) + warp.valid.numel()


@dataclass
class _Reference:
    """Step 1 of one object: its mask in its reference view."""

    view: View
    mask: torch.Tensor  # (U, V) bool on the device
    score: float
    feature: torch.Tensor | None = None  # (C,) unit source feature (semantic occluding)


@dataclass
class _Views:
    """Steps 2-4 of one object in every view, bit-packed per view."""

    bits: np.ndarray  # (S, T, ceil(U V / 8)) uint8
    fallback: np.ndarray  # (S, T) bool
    iou: np.ndarray  # (S, T) float32


class _PackedMaskMap(Mapping):
    """``obj_id -> (S, T, U, V) bool`` unpacked on access (never all at once)."""

    def __init__(self, bits: dict[int, np.ndarray], shape: tuple[int, int, int, int]):
        self._bits = bits
        self._shape = shape

    def __getitem__(self, obj_id: int) -> np.ndarray:
        s, t, u, v = self._shape
        bits = np.unpackbits(self._bits[obj_id], axis=-1, count=u * v)
        return bits.reshape(s, t, u, v).astype(bool)

    def __iter__(self) -> Iterator[int]:
        return iter(self._bits)

    def __len__(self) -> int:
        return len(self._bits)


@dataclass
class LightFieldPrediction:
    """Masks of the objects over all views.

    Attributes
    ----------
    labels : (S, T, U, V) int32 ndarray
        Label field; an object's label value is its id, 0 = unlabeled.
    masks : mapping obj_id -> (S, T, U, V) bool ndarray
        Each object's own mask (overlaps kept), unpacked on access.
    scores : dict obj_id -> float
        The segmenter's score of the reference-view mask.
    reference_views : dict obj_id -> (s, t)
    stage : {"coarse", "refined"}
    """

    labels: np.ndarray
    masks: Mapping[int, np.ndarray]
    scores: dict[int, float]
    reference_views: dict[int, View]
    stage: str = "refined"


@dataclass
class _Object:
    prompts: ObjectPrompts | None
    given_mask: np.ndarray | None = None  # automatic or imported objects: reference-view mask
    given_view: View | None = None
    given_score: float = 1.0
    reference: _Reference | None = None
    coarse: _Views | None = None
    refined: _Views | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def invalidate(self) -> None:
        self.reference = self.coarse = self.refined = None


class LightFieldPredictor:
    """Prompt objects in any view of a light field; get view-consistent 4D masks.

    Parameters
    ----------
    segmenter : Segmenter
        SAM 2 or the oracle (:func:`lfsam.segmenters.load_segmenter`).
    config : PipelineConfig, optional
        Switches and thresholds (default: the paper's full method).
    cache_dir : path, optional
        On-disk embedding cache (keyed by view content, model and weights).
    memory_budget_mb : float
        In-memory embedding budget (least recently used views dropped beyond it).
    progress : bool
        Progress bars over views.
    keep_decoder_state : bool
        Keep SAM 2's prompt-independent decoder work with each cached embedding (faster edits,
        about three times the memory per view; counted in the budget).

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> from lfsam.segmenters import load_segmenter
    >>> lf = generate_scene(grid=(3, 3), size=(48, 64), seed=0)
    >>> predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf))
    >>> predictor.set_lightfield(lf, disparity="gt")
    >>> predictor.add_prompts(1, points=[(32, 24)], labels=[1])
    ObjectPrompts(obj_id=1, points=(PointPrompt(x=32.0, y=24.0,
                  positive=True, view=(1, 1)),), box=None)
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
        keep_decoder_state: bool = True,
    ) -> None:
        self.segmenter = segmenter
        if hasattr(segmenter, "keep_decoder_state"):
            segmenter.keep_decoder_state = bool(keep_decoder_state)
        self.config = config or PipelineConfig()
        self.cache_dir = cache_dir
        self.memory_budget_mb = memory_budget_mb
        self.progress = progress
        self.device = segmenter.device
        self.timer = StageTimer(self.device)
        self.decode_counts: Counter[int] = Counter()
        """Prompts decoded per object id (each decoder row counts once)."""
        self.seconds = 0.0
        self._objects: dict[int, _Object] = {}
        self.lightfield: LightField | None = None

    # --- light field -------------------------------------------------------------------------
    def set_lightfield(
        self, lightfield: LightField, disparity: Any = "estimate"
    ) -> None:
        """Take a light field and where its disparity comes from; forget every object.

        Parameters
        ----------
        lightfield : LightField
        disparity : {"estimate", "gt"}, path to a .npy, or ndarray
            Resolved lazily, once per reference view (docs/design.md section 8): the view of
            each object's prompts. A ``(U, V)`` array is the center view's disparity; an
            ``(S, T, U, V)`` array gives every view's.
        """
        from lfsam.disparity.views import ViewDisparities

        self.lightfield = lightfield
        self._disparities = ViewDisparities(lightfield, disparity, device=str(self.device))
        self._store = EmbeddingStore(
            self.segmenter,
            lightfield.views,
            cache_dir=self.cache_dir,
            memory_budget_mb=self.memory_budget_mb,
        )
        self._disp_tensors: dict[View, torch.Tensor] = {}
        self._warps: OrderedDict[tuple[View, View], ForwardWarp] = OrderedDict()
        self._warp_bytes = 0
        self._objects = {}
        self._labels_cache: dict[str, np.ndarray] = {}

    def _require(self) -> LightField:
        if self.lightfield is None:
            raise LfsamError("no light field set; call set_lightfield(lightfield) first")
        return self.lightfield

    @property
    def views_encoded(self) -> int:
        """Image-encoder runs on views so far (0 when all came from the disk cache)."""
        return 0 if self.lightfield is None else self._store.views_encoded

    def embedding(self, view: View) -> ViewEmbedding:
        """The embedding of ``view`` (encoded on first use, then cached)."""
        self._require()
        with self.timer("encode"):
            return self._store.get(view)

    def disparity(self, view: View) -> torch.Tensor:
        """Disparity of ``view`` on the segmenter's device (resolved once)."""
        view = (int(view[0]), int(view[1]))
        if view not in self._disp_tensors:
            with self.timer("disparity"):
                disp = self._disparities.get(view)
            self._disp_tensors[view] = torch.tensor(disp, dtype=torch.float32, device=self.device)
        return self._disp_tensors[view]

    # --- objects -----------------------------------------------------------------------------
    @property
    def objects(self) -> dict[int, ObjectPrompts]:
        """The prompts of every prompted object, by id."""
        return {i: o.prompts for i, o in self._objects.items() if o.prompts is not None}

    @property
    def object_ids(self) -> list[int]:
        """Ids of every object (prompted, automatic or imported), ascending."""
        return sorted(self._objects)

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
        lf = self._require()
        view = lf.center if view is None else (int(view[0]), int(view[1]))
        points = [] if points is None else [tuple(map(float, p)) for p in points]
        labels = [1] * len(points) if labels is None else [int(x) for x in labels]
        if len(labels) != len(points):
            raise LfsamError(f"object {obj_id}: {len(points)} points but {len(labels)} labels")
        current = self._objects.get(obj_id)
        base = (
            current.prompts
            if current is not None and current.prompts is not None
            else ObjectPrompts(int(obj_id))
        )
        new = base.with_points(
            PointPrompt(x, y, label == 1, view)
            for (x, y), label in zip(points, labels, strict=True)
        )
        if box is not None:
            new = new.with_box(BoxPrompt(*map(float, box), view=view))
        self.set_object(new)
        return new

    def set_object(self, prompts: ObjectPrompts) -> None:
        """Set (or replace) one object's prompts; only it is recomputed."""
        lf = self._require()
        prompts = prompts.resolved(lf.center)
        validate_objects([prompts], lf.grid_shape, lf.view_shape)
        for view in prompts.views(lf.center):
            if not lf.present[view]:
                raise LfsamError(
                    f"object {prompts.obj_id}: view {view[0]},{view[1]} is absent from this "
                    "light field; prompt a view that exists"
                )
        self._objects[prompts.obj_id] = _Object(prompts=prompts)
        self._labels_cache.clear()

    def add_mask(
        self, obj_id: int, mask: np.ndarray, view: View | None = None, score: float = 1.0
    ) -> None:
        """Add an object given by its mask in one view (automatic masks, imported labels)."""
        lf = self._require()
        view = lf.center if view is None else (int(view[0]), int(view[1]))
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != lf.view_shape:
            raise LfsamError(
                f"object {obj_id}: mask has shape {mask.shape}, expected {lf.view_shape}"
            )
        if int(obj_id) < 1:
            raise LfsamError(f"object {obj_id}: id must be an integer >= 1")
        self._objects[int(obj_id)] = _Object(
            prompts=None, given_mask=mask, given_view=view, given_score=float(score)
        )
        self._labels_cache.clear()

    def remove_object(self, obj_id: int) -> None:
        """Forget one object (its label disappears from every view)."""
        if obj_id not in self._objects:
            raise LfsamError(f"no object {obj_id}; objects: {self.object_ids}")
        del self._objects[obj_id]
        self._labels_cache.clear()

    def reset_objects(self) -> None:
        """Forget every object (embeddings and disparities are kept)."""
        self._objects = {}
        self._labels_cache.clear()

    def next_id(self) -> int:
        """The smallest id larger than every id in use."""
        return max(self._objects, default=0) + 1

    # --- step 1: the reference view -----------------------------------------------------------
    def _reference_view(self, obj: _Object) -> View:
        lf = self._require()
        if obj.prompts is None:
            assert obj.given_view is not None
            return obj.given_view
        return obj.prompts.reference_view(lf.center)

    def _ensure_references(self, ids: Iterable[int]) -> None:
        todo = [i for i in ids if self._objects[i].reference is None]
        groups: dict[View, list[int]] = defaultdict(list)
        for i in todo:
            groups[self._reference_view(self._objects[i])].append(i)
        for view, members in groups.items():
            embedding = self.embedding(view)
            self._store.pin(view)
            masks: dict[int, torch.Tensor] = {}
            scores: dict[int, float] = {}
            prompted = []
            for i in members:
                obj = self._objects[i]
                if obj.prompts is None:
                    masks[i] = torch.as_tensor(obj.given_mask, device=self.device)
                    scores[i] = obj.given_score
                else:
                    prompted.append(i)
            with self.timer("initial"):
                self._decode_references(view, embedding, prompted, masks, scores)
            stacked = torch.stack([masks[i] for i in members]).to(torch.bool)
            with self.timer("occlude"):
                features = (
                    source_features(self.segmenter, embedding, stacked)
                    if self.config.semantic
                    else None
                )
            for k, i in enumerate(members):
                self._objects[i].reference = _Reference(
                    view=view,
                    mask=stacked[k],
                    score=scores[i],
                    feature=None if features is None else features[k],
                )

    def _decode_references(
        self,
        view: View,
        embedding: ViewEmbedding,
        ids: list[int],
        masks: dict[int, torch.Tensor],
        scores: dict[int, float],
    ) -> None:
        """Decode the prompts of objects in their reference view, one batch per prompt shape
        (same number of points, box or not): a single point without a box asks for SAM 2's
        three candidates and keeps the best (paper section 3.1, as :func:`initial_segmentation`).
        """
        shapes: dict[tuple[int, bool], list[int]] = defaultdict(list)
        carried = {i: self._points_in_view(self._objects[i], view) for i in ids}
        for i in ids:
            has_box = self._objects[i].prompts.box is not None
            shapes[(len(carried[i][1]), has_box)].append(i)
        for (count, has_box), members in shapes.items():
            if count == 0 and not has_box:  # every click was dropped: nothing to segment
                for i in members:
                    masks[i] = torch.zeros(
                        self.lightfield.view_shape, dtype=torch.bool, device=self.device
                    )
                    scores[i] = 0.0
                continue
            prompts = Prompts(
                points=np.stack([carried[i][0] for i in members]) if count else None,
                point_labels=np.stack([carried[i][1] for i in members]) if count else None,
                boxes=np.array([self._objects[i].prompts.box.xyxy for i in members])
                if has_box
                else None,
            )
            source = initial_segmentation(
                self.segmenter, embedding, self.lightfield.views[view], [prompts]
            )
            for k, i in enumerate(members):
                masks[i] = source.masks[k]
                scores[i] = float(source.scores[k])
                self.decode_counts[i] += 1

    def _clicks(self, obj: _Object) -> dict[str, np.ndarray]:
        """The object's clicks as arrays, with the disparity of each click's own view at the
        click (looked up once per object, on the CPU)."""
        if "clicks" not in obj.extra:
            lf = self._require()
            height, width = lf.view_shape
            points = obj.prompts.points if obj.prompts is not None else ()
            source = np.array([p.view for p in points], dtype=np.int64).reshape(-1, 2)
            x = np.array([p.x for p in points], dtype=np.float64)
            y = np.array([p.y for p in points], dtype=np.float64)
            d = np.zeros(len(points), dtype=np.float64)
            for k, (s, t) in enumerate(source):
                disp = self._disparities.get((int(s), int(t)))
                row = min(max(round(y[k]), 0), height - 1)
                col = min(max(round(x[k]), 0), width - 1)
                d[k] = float(disp[row, col])
            obj.extra["clicks"] = {
                "x": x, "y": y, "d": d, "source": source,
                "label": np.array([int(p.positive) for p in points], dtype=np.int64),
            }
        return obj.extra["clicks"]

    def _points_in_view(
        self, obj: _Object, view: View, zbuffer_test: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """The object's clicks carried into ``view``: ``(P, 2)`` xy and ``(P,)`` labels.

        A click given in view ``w`` moves by ``D_w`` at the click (docs/design.md section 8);
        it is dropped where it lands outside ``view`` and, with ``zbuffer_test``, where a
        closer surface of ``w`` covers it there (z-buffer of the forward warp of ``D_w``).
        """
        lf = self._require()
        height, width = lf.view_shape
        clicks = self._clicks(obj)
        ds = view[0] - clicks["source"][:, 0]
        dt = view[1] - clicks["source"][:, 1]
        y = clicks["y"] - clicks["d"] * ds
        x = clicks["x"] - clicks["d"] * dt
        keep = (x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1)
        if zbuffer_test:
            moved = keep & ((ds != 0) | (dt != 0))
            for k in np.flatnonzero(moved):
                source = (int(clicks["source"][k, 0]), int(clicks["source"][k, 1]))
                zbuffer = self._warp(source, view).zbuffer.reshape(height, width)
                landed = float(zbuffer[round(y[k]), round(x[k])])
                keep[k] = landed <= clicks["d"][k] + self.config.zbuffer_tolerance
        return (
            np.stack([x[keep], y[keep]], axis=1).astype(np.float32).reshape(-1, 2),
            clicks["label"][keep],
        )

    def _warp(self, source: View, target: View) -> ForwardWarp:
        key = (source, target)
        if key in self._warps:
            self._warps.move_to_end(key)
            return self._warps[key]
        with self.timer("propagate"):
            warp = forward_warp(
                self.disparity(source), target[0] - source[0], target[1] - source[1]
            )
        self._warps[key] = warp
        self._warp_bytes += _warp_nbytes(warp)
        while self._warp_bytes > WARP_CACHE_BYTES and len(self._warps) > 1:
            _, old = self._warps.popitem(last=False)
            self._warp_bytes -= _warp_nbytes(old)
        return warp

    def predict_reference(self, obj_id: int) -> tuple[View, np.ndarray, float]:
        """Stage 1 alone: the object's mask in its reference (clicked) view.

        Returns
        -------
        view : (s, t)
        mask : (U, V) bool ndarray
        score : float
        """
        if obj_id not in self._objects:
            raise LfsamError(f"no object {obj_id}; objects: {self.object_ids}")
        start = time.perf_counter()
        self._ensure_references([obj_id])
        self.seconds += time.perf_counter() - start
        ref = self._objects[obj_id].reference
        return ref.view, ref.mask.cpu().numpy(), ref.score

    # --- steps 2-4 in every view --------------------------------------------------------------
    def predict_coarse(self, obj_ids: Iterable[int] | None = None) -> LightFieldPrediction:
        """Steps 1-3 (propagation and occluding, no refinement) for the given objects (default
        all); objects computed before are reused."""
        ids = self._ids(obj_ids)
        self._run([i for i in ids if self._objects[i].coarse is None], refine=False)
        return self._prediction("coarse")

    def predict(self, obj_ids: Iterable[int] | None = None) -> LightFieldPrediction:
        """All four steps for the given objects (default all); objects computed before and
        not edited since are reused as they were."""
        ids = self._ids(obj_ids)
        self._run([i for i in ids if self._objects[i].refined is None], refine=True)
        return self._prediction("refined")

    def _ids(self, obj_ids: Iterable[int] | None) -> list[int]:
        self._require()
        ids = self.object_ids if obj_ids is None else [int(i) for i in obj_ids]
        missing = [i for i in ids if i not in self._objects]
        if missing:
            raise LfsamError(f"no object {missing[0]}; objects: {self.object_ids}")
        return ids

    def _run(self, ids: list[int], refine: bool) -> None:
        """Stream the views once for the objects ``ids``: each view encoded at most once,
        all objects' prompts of a view decoded together (per reference view)."""
        if not ids:
            return
        lf = self._require()
        start = time.perf_counter()
        config = self.config
        refine = refine and config.refine
        self._ensure_references(ids)
        s_count, t_count = lf.grid_shape
        nbytes = (lf.view_shape[0] * lf.view_shape[1] + 7) // 8
        out = {
            i: _Views(
                bits=np.zeros((s_count, t_count, nbytes), dtype=np.uint8),
                fallback=np.zeros((s_count, t_count), dtype=bool),
                iou=np.full((s_count, t_count), np.nan, dtype=np.float32),
            )
            for i in ids
        }
        coarse_out = {
            i: _Views(out[i].bits.copy(), out[i].fallback.copy(), out[i].iou.copy()) for i in ids
        }
        views = list(lf.view_indices(present_only=True))
        needs_embedding = refine or config.semantic
        batch_size = config.batch_size_for(self.device)
        bar = tqdm(
            total=len(views), desc="views", unit="view", disable=not self.progress or None,
            leave=False,
        )
        # Every object computed in this pass (a batch run): fuse each view's labels on the
        # device as it is done, instead of unpacking every mask again afterwards.
        everything = set(ids) == set(self._objects)
        stage = "refined" if refine or not config.refine else "coarse"
        labels = np.zeros((s_count, t_count, *lf.view_shape), dtype=np.int32)
        if everything:
            order = self.paint_order(ids)
            rank = {i: k for k, i in enumerate(ids)}
            paint = torch.as_tensor([rank[i] for i in order], device=self.device)
            lookup = torch.as_tensor([0, *ids], dtype=torch.int32, device=self.device)
        # The reference views are encoded already (step 1): they go first, on their own, so
        # that every later batch encodes a full ``batch_size`` of new views. Views whose
        # embedding is in memory (e.g. the extra reference views of the automatic mode) come
        # next, before new encodes could push them out of the memory budget.
        references = {self._objects[i].reference.view for i in ids}
        pending = [v for v in views if v not in references]
        pending.sort(key=lambda v: not self._store.in_memory(v))
        batches = [[v for v in views if v in references]]
        batches += [pending[k : k + batch_size] for k in range(0, len(pending), batch_size)]
        for batch in batches:
            # A view needs its embedding unless it is the reference of every object here.
            others = [v for v in batch if any(v != r for r in references)]
            embeddings = {}
            if needs_embedding and others:
                with self.timer("encode"):
                    embeddings = dict(zip(others, self._store.get_many(others), strict=True))
            for view in batch:
                final = self._view_step(view, ids, embeddings.get(view), refine, out, coarse_out)
                if everything:
                    with self.timer("fuse"):
                        fused = fuse_labels(torch.stack([final[i] for i in ids]), paint)
                        labels[view] = lookup[fused.long()].cpu().numpy()
                bar.update(1)
        bar.close()
        for i in ids:
            obj = self._objects[i]
            obj.coarse = coarse_out[i]
            if refine:
                obj.refined = out[i]
            elif not config.refine:
                obj.refined = coarse_out[i]  # the ablation without refinement ends here
        self._labels_cache.clear()
        if everything:
            self._labels_cache[stage] = labels
        self.seconds += time.perf_counter() - start

    def _view_step(
        self,
        view: View,
        ids: list[int],
        embedding: ViewEmbedding | None,
        refine: bool,
        out: dict[int, _Views],
        coarse_out: dict[int, _Views],
    ) -> dict[int, torch.Tensor]:
        """Steps 2-4 of the objects ``ids`` in one view; returns each object's final mask there
        (refined, or coarse without refinement) on the device."""
        final: dict[int, torch.Tensor] = {}
        config = self.config
        lf = self.lightfield
        height, width = lf.view_shape
        groups: dict[View, list[int]] = defaultdict(list)
        for i in ids:
            groups[self._objects[i].reference.view].append(i)
        for ref_view, members in groups.items():
            refs = [self._objects[i].reference for i in members]
            if ref_view == view:  # the reference view keeps its step-1 mask
                stacked = torch.stack([r.mask for r in refs])
                with self.timer("fuse"):
                    bits = pack_masks(stacked)
                for k, i in enumerate(members):
                    out[i].bits[view] = coarse_out[i].bits[view] = bits[k]
                    final[i] = stacked[k]
                continue
            source_masks = torch.stack([r.mask for r in refs])
            disp = self.disparity(ref_view)
            ds, dt = view[0] - ref_view[0], view[1] - ref_view[1]
            warp = self._warp(ref_view, view)
            with self.timer("propagate"):
                coarse = propagate_masks(
                    source_masks, disp, ds, dt, config.propagation, warp=warp,
                    fill_holes=config.fill_holes,
                    occlusion_tolerance=config.zbuffer_tolerance if config.geometric else None,
                )
            with self.timer("occlude"):
                weights = None
                if config.semantic:
                    sources = torch.stack([r.feature for r in refs])
                    weights = semantic_occlusion(
                        self.segmenter, embedding, coarse, sources, config.t_sim
                    )
                    coarse = weights.surviving_masks()
                elif refine:
                    weights = uniform_weights(coarse)
            with self.timer("fuse"):
                coarse_bits = pack_masks(coarse)
            for k, i in enumerate(members):
                coarse_out[i].bits[view] = coarse_bits[k]
            if not refine:
                for k, i in enumerate(members):
                    final[i] = coarse[k]
                continue
            with self.timer("refine"):
                seen = warp.seen((height, width))
                extra = self._carried_points(members, view, coarse)
                outcome = refine_masks(
                    self.segmenter, embedding, coarse, weights, config.t_iou,
                    seen=seen, frame_runs=warp.frame_runs((height, width), seen),
                    extra_points=extra,
                    chunk_size=REFINE_CHUNK_CUDA if self.device.type == "cuda" else 64,
                )
                prompted = (weights.weight > 0).new_zeros(len(members))
                prompted[weights.mask_index[weights.weight > 0]] = True
            for k in torch.nonzero(prompted, as_tuple=True)[0].tolist():
                self.decode_counts[members[k]] += 1
            with self.timer("fuse"):
                bits = pack_masks(outcome.masks)
                fallback = outcome.fallback.cpu().numpy()
                iou = outcome.iou.cpu().numpy()
            for k, i in enumerate(members):
                out[i].bits[view] = bits[k]
                out[i].fallback[view] = fallback[k]
                out[i].iou[view] = iou[k]
                final[i] = outcome.masks[k]
        return final

    def _carried_points(
        self, members: list[int], view: View, coarse: torch.Tensor
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The members' own clicks carried into ``view``, padded with label -1.

        A carried click must agree with the object's surviving coarse mask there: a positive
        click is kept only inside it and a negative one only outside it (a click carried by a
        slightly wrong disparity, or onto a surface that hides the object here, would otherwise
        merge or cut objects).
        """
        carried = [self._points_in_view(self._objects[i], view, zbuffer_test=False)
                   for i in members]
        counts = [len(kinds) for _, kinds in carried]
        if sum(counts) == 0:
            return None
        height, width = self.lightfield.view_shape
        xy = np.concatenate([points for points, _ in carried])
        kinds = np.concatenate([k for _, k in carried])
        owner = np.repeat(np.arange(len(members)), counts)
        rows = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, height - 1)
        cols = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, width - 1)
        index = torch.as_tensor(np.stack([owner, rows, cols]), device=coarse.device)
        inside = coarse[index[0], index[1], index[2]].cpu().numpy()
        agree = inside == (kinds == 1)
        kept = np.bincount(owner[agree], minlength=len(members))
        width_p = int(kept.max()) if len(kept) else 0
        if width_p == 0:
            return None
        out_xy = np.zeros((len(members), width_p, 2), dtype=np.float32)
        out_labels = np.full((len(members), width_p), -1, dtype=np.int64)
        slot = np.zeros(len(members), dtype=np.int64)
        for k in np.flatnonzero(agree):  # clicks, not pixels: a few per object
            m = owner[k]
            out_xy[m, slot[m]] = xy[k]
            out_labels[m, slot[m]] = kinds[k]
            slot[m] += 1
        return out_xy, out_labels

    # --- labels -------------------------------------------------------------------------------
    def paint_order(self, ids: Sequence[int] | None = None) -> list[int]:
        """Object ids in paint order: larger reference-view masks first, smaller on top (ties
        by id); docs/design.md section 3.6."""
        ids = self.object_ids if ids is None else list(ids)
        areas = {i: int(self._objects[i].reference.mask.sum()) for i in ids}
        return sorted(ids, key=lambda i: (-areas[i], i))

    def _prediction(self, stage: str) -> LightFieldPrediction:
        lf = self._require()
        attr = "refined" if stage == "refined" else "coarse"
        ready = [i for i in self.object_ids if getattr(self._objects[i], attr) is not None]
        bits = {i: getattr(self._objects[i], attr).bits for i in ready}
        if stage not in self._labels_cache:
            self._labels_cache[stage] = self._fuse(ready, bits)
        refs = {i: self._objects[i].reference for i in ready}
        return LightFieldPrediction(
            labels=self._labels_cache[stage],
            masks=_PackedMaskMap(bits, (*lf.grid_shape, *lf.view_shape)),
            scores={i: refs[i].score for i in ready},
            reference_views={i: refs[i].view for i in ready},
            stage=stage,
        )

    def _fuse(self, ids: list[int], bits: dict[int, np.ndarray]) -> np.ndarray:
        """Label field of the objects ``ids`` (values = ids), painted view by view."""
        lf = self._require()
        s_count, t_count = lf.grid_shape
        height, width = lf.view_shape
        labels = np.zeros((s_count, t_count, height, width), dtype=np.int32)
        if not ids:
            return labels
        order = self.paint_order(ids)
        rank = {i: k for k, i in enumerate(ids)}
        paint = torch.as_tensor([rank[i] for i in order])
        lookup = np.concatenate([[0], np.asarray(ids, dtype=np.int32)])
        with self.timer("fuse"):
            for s, t in lf.view_indices(present_only=True):
                packed = np.stack([bits[i][s, t] for i in ids])
                masks = np.unpackbits(packed, axis=1, count=height * width).astype(bool)
                fused = fuse_labels(torch.from_numpy(masks.reshape(-1, height, width)), paint)
                labels[s, t] = lookup[fused.numpy()]
        return labels

    # --- automatic mode -----------------------------------------------------------------------
    def generate(self, references: str = "center") -> list[int]:
        """Automatic mask generation; each mask becomes an object (returns the new ids).

        ``center`` is the paper's setting (section 4, implementation details): masks of the
        center view, ids in order of decreasing area. ``corners``, ``ring`` and ``all`` then
        visit further reference views (:func:`lfsam.pipeline.references.reference_views`): in
        each, the objects found so far are carried there (steps 1-4), the generator asks only
        where no mask lands and the center view could not look
        (:func:`lfsam.pipeline.references.seen_from`: hidden there behind something nearer, or
        outside its frame; :func:`~lfsam.pipeline.references.extra_view_points`), and a new
        mask that mostly lies on such covered pixels is dropped. Up to
        :data:`EXTRA_VIEW_ROUNDS` rounds per view: later rounds ask once in each region that
        no answer explains (:func:`~lfsam.pipeline.references.unasked_region_points`). A new
        object that is an object of an earlier extra view seen again is merged with it
        (the find with the larger reference mask stays). Each genuinely new object is
        propagated from its own view (docs/design.md section 8: objects that the center view
        cannot see).
        """
        from lfsam.pipeline.references import reference_views

        lf = self._require()
        views = [v for v in reference_views(lf.grid_shape, references) if lf.present[v]]
        new_ids: list[int] = []
        for k, view in enumerate(views):
            if k == 0:
                with self.timer("initial"):
                    source = initial_segmentation(
                        self.segmenter, self.embedding(view), lf.views[view], None
                    )
                masks = source.masks.cpu().numpy()
                new_ids += self._add_automatic(view, masks, source.scores, np.arange(len(masks)))
            else:
                new_ids = self._generate_in_extra_view(view, views[0], new_ids)
        return self._renumber(new_ids)

    def _generate_in_extra_view(self, view: View, center: View, new_ids: list[int]) -> list[int]:
        """One extra reference view of :meth:`generate`; returns ``new_ids`` updated (objects
        added, objects that turned out to be found twice removed)."""
        from lfsam.metrics.recall import default_min_area
        from lfsam.pipeline.references import (
            drop_covered_masks,
            extra_view_points,
            seen_from,
            unasked_region_points,
        )

        lf = self._require()
        embedding = self.embedding(view)
        per_side = int(getattr(self.segmenter, "amg_options", {}).get("points_per_side") or 32)
        min_region = default_min_area(lf.view_shape) // 2
        carried_ids = self.object_ids
        carried = self._masks_in_view(carried_ids, view)
        # objects found in earlier extra views, with their masks carried here
        found_before = [
            (i, carried[n]) for n, i in enumerate(carried_ids)
            if i in new_ids and self._objects[i].given_view != center
        ]
        covered = carried.any(axis=0)
        with self.timer("disparity"):
            covered |= seen_from(
                self.disparity(view), self.disparity(center), center[0] - view[0],
                center[1] - view[1], self.config.zbuffer_tolerance,
            ).cpu().numpy()
        points = extra_view_points(per_side, covered, min_region)
        asked = np.zeros((0, 2), dtype=np.float64)
        explained = covered.copy()
        for _ in range(EXTRA_VIEW_ROUNDS):
            if len(points) == 0:
                break
            with self.timer("initial"):
                source = initial_segmentation(
                    self.segmenter, embedding, lf.views[view], None, points=points
                )
            masks = source.masks.cpu().numpy()
            keep = drop_covered_masks(masks, covered)
            replaced = self._larger_views(masks, keep, found_before)
            keep[list(replaced)] = True
            added = self._add_automatic(view, masks, source.scores, np.flatnonzero(keep))
            for obj_id in replaced.values():
                self.remove_object(obj_id)
            removed = set(replaced.values())
            removed |= set(self._merge_found_before(added, [i for i, _ in found_before
                                                            if i not in removed]))
            new_ids = [i for i in new_ids + added if i not in removed]
            found_before = [(i, m) for i, m in found_before if i not in removed]
            covered |= masks[keep].any(axis=0)
            explained |= covered | masks.any(axis=0)
            asked = np.concatenate([asked, points])
            # Regions that no answer explains and no point was asked in: e.g. a second
            # hidden object beside one that a grid point found, in one uncovered strip.
            points = unasked_region_points(~explained, min_region, asked)
        return new_ids

    def _larger_views(
        self, masks: np.ndarray, keep: np.ndarray, found_before: list[tuple[int, np.ndarray]]
    ) -> dict[int, int]:
        """Dropped answers that are a larger view of an object found in an earlier extra view.

        An answer dropped because an earlier find's carried mask covers most of it, with more
        pixels than that find's own reference mask, shows the object better: it replaces the
        find (a larger view carries an object further; docs/design.md section 8).

        Returns
        -------
        dict
            Answer index -> id of the object it replaces (each object replaced at most once,
            by its largest such answer).
        """
        best: dict[int, tuple[int, int]] = {}  # object id -> (area, answer index)
        if not found_before:
            return {}
        for index in np.flatnonzero(~keep):
            area = int(np.count_nonzero(masks[index]))
            if area == 0:
                continue
            overlaps = [np.count_nonzero(masks[index] & carried) for _, carried in found_before]
            n = int(np.argmax(overlaps))
            obj_id = found_before[n][0]
            if 2 * overlaps[n] <= area:
                continue
            if area > np.count_nonzero(self._objects[obj_id].given_mask) and area > best.get(
                obj_id, (0, -1)
            )[0]:
                best[obj_id] = (area, int(index))
        return {index: obj_id for obj_id, (_, index) in best.items()}

    def _renumber(self, ids: list[int]) -> list[int]:
        """Give the objects ``ids`` (new ones, in order) consecutive ids from the smallest,
        closing the gaps that merged finds left; returns the new ids."""
        if not ids:
            return []
        start = min(ids)
        moved = {old: self._objects.pop(old) for old in ids}
        counts = {old: self.decode_counts.pop(old, 0) for old in ids}
        for k, old in enumerate(ids):
            self._objects[start + k] = moved[old]
            if counts[old]:
                self.decode_counts[start + k] = counts[old]
        self._objects = dict(sorted(self._objects.items()))
        self._labels_cache.clear()
        return list(range(start, start + len(ids)))

    def _merge_found_before(self, added: list[int], earlier: list[int]) -> list[int]:
        """Resolve the new objects ``added`` that are objects of ``earlier`` seen again.

        An object found in one extra reference view may not be carried into another one when
        the two views see disjoint parts of it (a small object peeking out on different sides
        of its occluder): it is then found a second time. Each new object is carried back into
        the reference view of each earlier one; when most of what lands there lands on that
        object's reference mask, the two are one object, and the one with the smaller
        reference mask is removed (a larger view of an object carries it further).

        Returns
        -------
        list of int
            The ids removed (new or earlier).
        """
        removed: list[int] = []
        for obj_id in added:
            new = self._objects[obj_id]
            carried: dict[View, np.ndarray] = {}  # the new object in each earlier view, once
            for other in earlier:
                if other in removed:
                    continue
                old = self._objects[other]
                if old.given_view == new.given_view:
                    continue
                if old.given_view not in carried:
                    carried[old.given_view] = self._masks_in_view([obj_id], old.given_view)[0]
                there = carried[old.given_view]
                on_old = np.count_nonzero(there & old.given_mask)
                if on_old == 0 or 2 * on_old <= np.count_nonzero(there):
                    continue
                smaller = (
                    obj_id
                    if np.count_nonzero(new.given_mask) <= np.count_nonzero(old.given_mask)
                    else other
                )
                self.remove_object(smaller)
                removed.append(smaller)
                if smaller == obj_id:
                    break
        return removed

    def _add_automatic(
        self, view: View, masks: np.ndarray, scores: Any, keep: np.ndarray
    ) -> list[int]:
        """Add the generator's masks ``masks[keep]`` of ``view`` as new objects (their ids)."""
        first = self.next_id()
        ids = []
        for n, index in enumerate(keep):
            obj_id = first + n
            self.add_mask(obj_id, masks[index], view=view, score=float(scores[index]))
            self._objects[obj_id].extra["auto"] = True
            ids.append(obj_id)
        return ids

    def _masks_in_view(self, ids: list[int], view: View) -> np.ndarray:
        """The objects ``ids``' final masks in one view (steps 1-4, or 1-3 without refinement),
        ``(N, U, V)`` bool; computed for this view only and not stored."""
        lf = self._require()
        height, width = lf.view_shape
        if not ids:
            return np.zeros((0, height, width), dtype=bool)
        self._ensure_references(ids)
        nbytes = (height * width + 7) // 8
        s_count, t_count = lf.grid_shape

        def blank() -> _Views:
            return _Views(
                bits=np.zeros((s_count, t_count, nbytes), dtype=np.uint8),
                fallback=np.zeros((s_count, t_count), dtype=bool),
                iou=np.zeros((s_count, t_count), dtype=np.float32),
            )

        out = {i: blank() for i in ids}
        coarse = {i: blank() for i in ids}
        refine = self.config.refine
        needs_embedding = refine or self.config.semantic
        embedding = self.embedding(view) if needs_embedding else None
        self._view_step(view, ids, embedding, refine, out, coarse)
        final = out if refine else coarse
        packed = np.stack([final[i].bits[view] for i in ids])
        bits = np.unpackbits(packed, axis=1, count=height * width)
        return bits.reshape(len(ids), height, width).astype(bool)

    # --- results ------------------------------------------------------------------------------
    def to_result(self) -> SegmentationResult:
        """The objects' refined masks as a :class:`~lfsam.result.SegmentationResult`.

        Masks are stored in id order (``meta["object_ids"]``) and the prompts in
        ``meta["objects"]``, so the result can be reopened and edited
        (:meth:`load_objects`); ``meta["views_encoded"]`` counts image-encoder runs.
        """
        lf = self._require()
        ids = self.object_ids
        self.predict(ids)
        prediction = self._prediction("refined")
        shape = (len(ids), *lf.grid_shape, *lf.view_shape)
        packed = PackedMasks(
            shape,
            np.stack([self._objects[i].refined.bits for i in ids])
            if ids
            else None,
        )
        objects_meta = []
        for i in ids:
            obj = self._objects[i]
            entry: dict[str, Any] = {"id": i, "reference_view": list(obj.reference.view)}
            if obj.prompts is not None:
                entry.update(prompts_to_json([obj.prompts])[0])
            else:
                entry["mask"] = "automatic" if obj.extra.get("auto") else "given"
            objects_meta.append(entry)
        timings = dict(self.timer.seconds)
        timings["total"] = self.seconds + timings.get("disparity", 0.0)
        meta = {
            "method": "lfsam",
            "package_version": __version__,
            "segmenter": self.segmenter.describe(),
            "config": self.config.to_dict(),
            "prompt_mode": "auto"
            if ids and all(self._objects[i].prompts is None for i in ids)
            else "prompts",
            "num_masks": len(ids),
            "center": list(lf.center),
            "object_ids": ids,
            "objects": objects_meta,
            "views_encoded": self.views_encoded,
            "views_present": int(lf.present.sum()),
            "disparity_source": self._disparities.source(lf.center)
            if lf.center in self._disparities.resolved or not self._disparities.resolved
            else self._disparities.source(self._disparities.resolved[0]),
            "disparity_sources": {
                f"{s},{t}": self._disparities.source((s, t))
                for s, t in self._disparities.resolved
            },
        }
        return SegmentationResult(
            labels=prediction.labels,
            masks=packed,
            scores=np.array([self._objects[i].reference.score for i in ids], dtype=np.float32),
            fallback=np.stack([self._objects[i].refined.fallback for i in ids])
            if ids
            else np.zeros((0, *lf.grid_shape), dtype=bool),
            refine_iou=np.stack([self._objects[i].refined.iou for i in ids])
            if ids
            else np.zeros((0, *lf.grid_shape), dtype=np.float32),
            timings=timings,
            meta=meta,
            present=lf.present.copy(),
        )

    @staticmethod
    def load_objects(result: SegmentationResult) -> list[ObjectPrompts]:
        """The prompted objects stored in a result (to reopen it for editing)."""
        from lfsam.prompts import prompts_from_json

        entries = [
            {k: v for k, v in e.items() if k in ("id", "points", "box")}
            for e in result.meta.get("objects", [])
            if "mask" not in e
        ]
        return prompts_from_json(entries)

    def open_result(self, result: SegmentationResult) -> None:
        """Take a result's objects: prompted ones by their prompts, the others (automatic or
        imported) by their reference-view masks; then :meth:`predict` reproduces it."""
        lf = self._require()
        if tuple(result.labels.shape) != (*lf.grid_shape, *lf.view_shape):
            raise LfsamError(
                f"the result's labels have shape {result.labels.shape}, the light field is "
                f"{(*lf.grid_shape, *lf.view_shape)}; open the result with its own light field"
            )
        ids = result.meta.get("object_ids") or list(range(1, result.num_masks + 1))
        entries = {e["id"]: e for e in result.meta.get("objects", [])}
        prompted = {o.obj_id: o for o in self.load_objects(result)}
        for n, obj_id in enumerate(ids):
            if obj_id in prompted:
                self.set_object(prompted[obj_id])
                continue
            view = tuple(entries.get(obj_id, {}).get("reference_view", lf.center))
            if result.masks is not None:
                mask = result.masks.mask(n)[view]
            else:
                mask = result.labels[view] == obj_id
            score = 1.0 if result.scores is None else float(result.scores[n])
            self.add_mask(obj_id, mask, view=view, score=score)

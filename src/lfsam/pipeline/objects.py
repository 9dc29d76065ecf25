"""The objects of an interactive session and the carrying of their clicks between views.

An object (docs/design.md section 8) has a stable id >= 1 and is given either by prompts (points
and at most one box, each in any view) or by a mask in one view (automatic or imported). Its
*reference view* is where step 1 runs: the view of its prompts, or of its mask. This module keeps

- :class:`ObjectTable`: the objects by id, with what was computed for each (step 1 in the
  reference view, the coarse masks of steps 1-3 and the refined masks of step 4 in every view),
  forgotten when the object is edited;
- the clicks of an object carried into another view by the disparity of the view each click was
  given in (:class:`Clicks`, :func:`clicks_in_view`, :func:`agreeing_clicks`).

The streaming engine (:mod:`lfsam.pipeline.engine`) fills the computed parts.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.prediction import LightFieldPrediction, PackedMaskMap
from lfsam.prompts import ObjectPrompts

__all__ = [
    "Clicks",
    "FeatureGroup",
    "ObjectTable",
    "ObjectViews",
    "Reference",
    "TrackedObject",
    "View",
    "agreeing_clicks",
    "clicks_in_view",
]

View = tuple[int, int]


@dataclass
class FeatureGroup:
    """The references decoded together in one view, whose source features (paper 3.3) are
    computed together on first use (:meth:`Reference.source_feature`): the same batch, so
    the same numbers, as when computed at once; an answer that is replaced before the
    pipeline runs (the tracker's refused prompts, docs/design.md sections 3.4 and 10) never
    pays for them."""

    view: View
    masks: torch.Tensor  # (N, U, V) bool on the device
    features: torch.Tensor | None = None  # (N, C), once computed


@dataclass
class Reference:
    """Step 1 of one object: its mask in its reference view."""

    view: View
    mask: torch.Tensor  # (U, V) bool on the device
    score: float
    feature: torch.Tensor | None = None  # (C,) unit source feature (semantic occluding)
    #: Where :attr:`feature` comes from while it is not computed yet: its group and row.
    pending: tuple[FeatureGroup, int] | None = None

    def source_feature(
        self, compute: Callable[[View, torch.Tensor], torch.Tensor]
    ) -> torch.Tensor | None:
        """The unit source feature (None without semantic occluding), computed on first use
        by ``compute(view, masks)`` for the whole :class:`FeatureGroup` (e.g.
        :meth:`lfsam.pipeline.engine.StreamingEngine.source_features`)."""
        if self.feature is None and self.pending is not None:
            group, row = self.pending
            if group.features is None:
                group.features = compute(group.view, group.masks)
            self.feature, self.pending = group.features[row], None
        return self.feature


@dataclass
class ObjectViews:
    """Steps 2-4 of one object in every view, bit-packed per view."""

    bits: np.ndarray  # (S, T, ceil(U V / 8)) uint8
    fallback: np.ndarray  # (S, T) bool
    iou: np.ndarray  # (S, T) float32
    #: (S, T) bool: refined masks the multi-view consensus replaced (None without it)
    replaced: np.ndarray | None = None

    @classmethod
    def empty(
        cls, grid_shape: tuple[int, int], view_shape: tuple[int, int], iou: float = np.nan
    ) -> ObjectViews:
        """No mask in any view, no fallback, ``iou`` everywhere."""
        nbytes = (view_shape[0] * view_shape[1] + 7) // 8
        return cls(
            bits=np.zeros((*grid_shape, nbytes), dtype=np.uint8),
            fallback=np.zeros(grid_shape, dtype=bool),
            iou=np.full(grid_shape, iou, dtype=np.float32),
        )

    def copy(self) -> ObjectViews:
        """An independent copy."""
        return ObjectViews(self.bits.copy(), self.fallback.copy(), self.iou.copy(),
                           None if self.replaced is None else self.replaced.copy())


@dataclass(frozen=True)
class Clicks:
    """An object's clicks as arrays: pixel ``x`` (column), ``y`` (row), the disparity ``d`` of
    the click's own view at the click, that view ``source`` ``(P, 2)``, ``label`` 1/0."""

    x: np.ndarray
    y: np.ndarray
    d: np.ndarray
    source: np.ndarray
    label: np.ndarray

    @classmethod
    def of(
        cls,
        prompts: ObjectPrompts | None,
        disparity: Callable[[View], np.ndarray],
        view_shape: tuple[int, int],
    ) -> Clicks:
        """The clicks of ``prompts`` (none for an object given by a mask); ``disparity(view)``
        is the ``(U, V)`` disparity of a view, looked up once per click on the CPU."""
        points = prompts.points if prompts is not None else ()
        height, width = view_shape
        source = np.array([p.view for p in points], dtype=np.int64).reshape(-1, 2)
        x = np.array([p.x for p in points], dtype=np.float64)
        y = np.array([p.y for p in points], dtype=np.float64)
        rows = np.clip(np.rint(y), 0, height - 1).astype(np.int64)
        cols = np.clip(np.rint(x), 0, width - 1).astype(np.int64)
        d = np.array(
            [float(disparity((int(s), int(t)))[r, c])
             for (s, t), r, c in zip(source, rows, cols, strict=True)],
            dtype=np.float64,
        )
        label = np.array([int(p.positive) for p in points], dtype=np.int64)
        return cls(x=x, y=y, d=d, source=source, label=label)


def clicks_in_view(
    clicks: Clicks,
    view: View,
    view_shape: tuple[int, int],
    zbuffer: Callable[[View], torch.Tensor] | None = None,
    tolerance: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The clicks carried into ``view``: ``(P, 2)`` xy and ``(P,)`` labels.

    A click given in view ``w`` moves by ``D_w`` at the click (docs/design.md section 8); it is
    dropped where it lands outside ``view`` and, with ``zbuffer`` (``zbuffer(w)`` = the z-buffer
    of the forward warp of ``D_w`` into ``view``, flat), where a closer surface of ``w`` covers
    it there by more than ``tolerance``.
    """
    height, width = view_shape
    ds = view[0] - clicks.source[:, 0]
    dt = view[1] - clicks.source[:, 1]
    y = clicks.y - clicks.d * ds
    x = clicks.x - clicks.d * dt
    keep = (x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1)
    if zbuffer is not None:
        moved = keep & ((ds != 0) | (dt != 0))
        for k in np.flatnonzero(moved):  # clicks, not pixels: a few per object
            source = (int(clicks.source[k, 0]), int(clicks.source[k, 1]))
            landed = float(zbuffer(source).reshape(height, width)[round(y[k]), round(x[k])])
            keep[k] = landed <= clicks.d[k] + tolerance
    return (
        np.stack([x[keep], y[keep]], axis=1).astype(np.float32).reshape(-1, 2),
        clicks.label[keep],
    )


def agreeing_clicks(
    carried: Sequence[tuple[np.ndarray, np.ndarray]], coarse: torch.Tensor
) -> tuple[np.ndarray, np.ndarray] | None:
    """Carried clicks of ``N`` objects that agree with their coarse masks, padded with label -1.

    A positive click is kept only inside the object's surviving coarse mask ``coarse[n]`` and a
    negative one only outside it (a click carried by a slightly wrong disparity, or onto a
    surface that hides the object here, would otherwise merge or cut objects).

    Returns
    -------
    (N, P, 2) float32 xy and (N, P) int64 labels, or None when no click is kept
    """
    counts = [len(kinds) for _, kinds in carried]
    if sum(counts) == 0:
        return None
    height, width = coarse.shape[-2:]
    xy = np.concatenate([points for points, _ in carried])
    kinds = np.concatenate([k for _, k in carried])
    owner = np.repeat(np.arange(len(carried)), counts)
    rows = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, height - 1)
    cols = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, width - 1)
    index = torch.as_tensor(np.stack([owner, rows, cols]), device=coarse.device)
    inside = coarse[index[0], index[1], index[2]].cpu().numpy()
    agree = inside == (kinds == 1)
    kept = np.bincount(owner[agree], minlength=len(carried))
    width_p = int(kept.max()) if len(kept) else 0
    if width_p == 0:
        return None
    out_xy = np.zeros((len(carried), width_p, 2), dtype=np.float32)
    out_labels = np.full((len(carried), width_p), -1, dtype=np.int64)
    slot = np.zeros(len(carried), dtype=np.int64)
    for k in np.flatnonzero(agree):  # clicks, not pixels: a few per object
        m = owner[k]
        out_xy[m, slot[m]] = xy[k]
        out_labels[m, slot[m]] = kinds[k]
        slot[m] += 1
    return out_xy, out_labels


@dataclass
class TrackedObject:
    """One object: how it is given, and what has been computed for it so far."""

    prompts: ObjectPrompts | None
    given_mask: np.ndarray | None = None  # automatic or imported objects: reference-view mask
    given_view: View | None = None
    given_score: float = 1.0
    automatic: bool = False
    category: str | None = None  # the phrase a text prompt found it by (docs/design.md 9)
    reference: Reference | None = None
    coarse: ObjectViews | None = None
    refined: ObjectViews | None = None
    clicks: Clicks | None = None

    def reference_view(self, center: View) -> View:
        """Where step 1 runs: the view of the prompts (docs/design.md section 8) or the mask."""
        if self.prompts is None:
            assert self.given_view is not None
            return self.given_view
        return self.prompts.reference_view(center)


@dataclass
class ObjectTable:
    """The objects of a session by id (ascending), each with its computed stages."""

    objects: dict[int, TrackedObject] = field(default_factory=dict)

    def __getitem__(self, obj_id: int) -> TrackedObject:
        return self.objects[obj_id]

    def __contains__(self, obj_id: object) -> bool:
        return obj_id in self.objects

    def __iter__(self) -> Iterator[int]:
        return iter(self.ids)

    def __len__(self) -> int:
        return len(self.objects)

    @property
    def ids(self) -> list[int]:
        """Every id, ascending."""
        return sorted(self.objects)

    def prompts(self) -> dict[int, ObjectPrompts]:
        """The prompts of every prompted object, by id."""
        return {i: o.prompts for i, o in self.objects.items() if o.prompts is not None}

    def next_id(self) -> int:
        """The smallest id larger than every id in use."""
        return max(self.objects, default=0) + 1

    def check(self, ids: Iterable[int]) -> list[int]:
        """``ids`` as ints; an unknown one is an :class:`LfsamError` naming the known ones."""
        ids = [int(i) for i in ids]
        for i in ids:
            if i not in self.objects:
                raise LfsamError(f"no object {i}; objects: {self.ids}")
        return ids

    def put(self, obj_id: int, obj: TrackedObject) -> None:
        """Set (or replace) object ``obj_id``."""
        self.objects[int(obj_id)] = obj

    def remove(self, obj_id: int) -> None:
        """Forget object ``obj_id``."""
        del self.objects[self.check([obj_id])[0]]

    def clear(self) -> None:
        """Forget every object."""
        self.objects = {}

    def prediction(
        self,
        stage: str,
        shape: tuple[int, int, int, int],
        fuse: Callable[[list[int], dict[int, np.ndarray], list[int]], np.ndarray],
        labels: np.ndarray | None = None,
    ) -> LightFieldPrediction:
        """The objects' masks at ``stage`` (``"coarse"`` or ``"refined"``; objects without them
        yet are left out) with their labels: ``labels`` when the caller holds them, else
        ``fuse(ids, bits, paint_order)`` (:meth:`lfsam.pipeline.engine.StreamingEngine.fuse`).
        ``shape`` is the light field's ``(S, T, U, V)``."""
        ready = [i for i in self.ids if getattr(self.objects[i], stage) is not None]
        bits = {i: getattr(self.objects[i], stage).bits for i in ready}
        if labels is None:
            labels = fuse(ready, bits, self.paint_order(ready))
        refs = {i: self.objects[i].reference for i in ready}
        return LightFieldPrediction(
            labels=labels,
            masks=PackedMaskMap(bits, shape),
            scores={i: refs[i].score for i in ready},
            reference_views={i: refs[i].view for i in ready},
            stage=stage,
        )

    def forget_refined(self) -> None:
        """Drop every object's refined masks (refined again at the next prediction, e.g. under
        another ``refine_views``); step 1 and the coarse masks stay."""
        for obj in self.objects.values():
            obj.refined = None

    def paint_order(self, ids: Sequence[int]) -> list[int]:
        """``ids`` in paint order: larger reference-view masks first, smaller on top (ties by
        id); docs/design.md section 3.6. Step 1 must have run for each."""
        areas = {i: int(self.objects[i].reference.mask.sum()) for i in ids}
        return sorted(ids, key=lambda i: (-areas[i], i))

    def renumber(self, ids: Sequence[int]) -> dict[int, int]:
        """Give the objects ``ids`` (in order) consecutive ids from the smallest of them,
        closing gaps; returns old id -> new id."""
        if not ids:
            return {}
        start = min(ids)
        moved = {old: self.objects.pop(old) for old in ids}
        mapping = {old: start + k for k, old in enumerate(ids)}
        for old, new in mapping.items():
            self.objects[new] = moved[old]
        self.objects = dict(sorted(self.objects.items()))
        return mapping

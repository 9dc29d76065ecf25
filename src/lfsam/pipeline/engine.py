"""The streaming engine: the four steps run over a light field's views for a set of objects.

Paper section 3, streamed (docs/design.md sections 3 and 8): step 1 in each object's reference
view (:meth:`StreamingEngine.ensure_references`); then the views in batches, each view encoded at
most once (:class:`lfsam.embeddings.EmbeddingStore`), and in each view steps 2-4 for every object,
all prompts of a view decoded together, whatever their reference view
(:meth:`StreamingEngine.view_step`); masks kept bit-packed, and labels fused view by view on
the device when every object is in the pass. The engine owns what a light field's objects
share: embeddings, disparities, forward warps (:class:`lfsam.pipeline.warps.WarpCache`), the
stage timer and which views are refined, from its base
:class:`lfsam.pipeline.shared.SharedViews`. Which objects exist, and which of their stages are up
to date, is the caller's (:class:`lfsam.predictor.LightFieldPredictor`).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.fusion import ViewLabels
from lfsam.pipeline.initial import initial_segmentation
from lfsam.pipeline.objects import (
    FeatureGroup,
    ObjectViews,
    Reference,
    TrackedObject,
    View,
    agreeing_clicks,
)
from lfsam.pipeline.occlusion import (
    semantic_occlusion,
    source_features,
    stack_source_features,
    uniform_weights,
)
from lfsam.pipeline.propagation import ForwardWarp, propagate_masks
from lfsam.pipeline.refinement import (
    RefinementOutcome,
    RefineRequest,
    read_back,
    refine_many,
    seen_per_mask,
)
from lfsam.pipeline.shared import SharedViews
from lfsam.pipeline.voting import ViewVoter
from lfsam.pipeline.warps import WARP_CACHE_BYTES
from lfsam.result import pack_masks
from lfsam.segmenters.base import Prompts, Segmenter, ViewEmbedding

__all__ = ["WARP_CACHE_BYTES", "StreamingEngine"]

#: What becomes of a view's refinement outcome (:meth:`StreamingEngine._refined_writer`).
Writer = Callable[[RefinementOutcome, np.ndarray, np.ndarray], None]


class StreamingEngine(SharedViews):
    """The four steps over one light field's views (module docstring).

    Parameters
    ----------
    segmenter : Segmenter
    config : PipelineConfig
    lightfield : LightField
    disparity : {"estimate", "gt"}, path to a .npy, or ndarray
        Resolved lazily, once per view asked (:class:`lfsam.disparity.views.ViewDisparities`).
    cache_dir : path, optional
        On-disk embedding cache.
    memory_budget_mb : float
        In-memory embedding budget.
    progress : bool
        A progress bar over views in :meth:`run`.
    """

    def __init__(
        self,
        segmenter: Segmenter,
        config: PipelineConfig,
        lightfield: LightField,
        disparity: Any = "estimate",
        *,
        cache_dir: Any = None,
        memory_budget_mb: float = 2048.0,
        progress: bool = False,
    ) -> None:
        super().__init__(segmenter, config, lightfield, disparity, cache_dir=cache_dir,
                         memory_budget_mb=memory_budget_mb, progress=progress)
        #: The fill and the consensus: votes of refined views (:mod:`lfsam.pipeline.voting`).
        self.voter = ViewVoter(self)

    # --- step 1 ------------------------------------------------------------------------------
    def ensure_references(self, objects: Mapping[int, TrackedObject], ids: Sequence[int]) -> None:
        """Step 1 for the objects ``ids`` without one: grouped by reference view, each view
        encoded once (and pinned in memory), prompts decoded in batches."""
        center = self.lightfield.center
        groups: dict[View, list[int]] = defaultdict(list)
        for i in ids:
            if objects[i].reference is None:
                groups[objects[i].reference_view(center)].append(i)
        for view, members in groups.items():
            embedding = self.embedding(view)
            self.store.pin(view)
            masks: dict[int, torch.Tensor] = {}
            scores: dict[int, float] = {}
            prompted = []
            for i in members:
                obj = objects[i]
                if obj.prompts is None:
                    masks[i] = torch.as_tensor(obj.given_mask, device=self.device)
                    scores[i] = obj.given_score
                else:
                    prompted.append(i)
            with self.timer("initial"):
                self._decode_references(objects, view, embedding, prompted, masks, scores)
            stacked = torch.stack([masks[i] for i in members]).to(torch.bool)
            group = FeatureGroup(view, stacked) if self.config.semantic else None  # on first use
            for k, i in enumerate(members):
                objects[i].reference = Reference(
                    view, stacked[k], scores[i], pending=None if group is None else (group, k))
            self._surface_masks(objects, view)

    def source_features(self, view: View, masks: torch.Tensor) -> torch.Tensor:
        """The unit source features (paper 3.3) of ``masks`` in ``view``: what
        :meth:`~lfsam.pipeline.objects.Reference.source_feature` computes on first use."""
        embedding = self.embedding(view)
        with self.timer("occlude"):
            return source_features(self.segmenter, embedding, masks)

    def _surface_masks(self, objects: Mapping[int, TrackedObject], view: View) -> None:
        """Keep the silhouettes of every object referenced in ``view`` for its disparity
        (an estimate only; ``config.surface_depth``) and forget what its old disparity gave."""
        if not (self.config.surface_depth and self.disparities.estimated):
            return
        refs = [objects[i].reference for i in objects]
        masks = [r.mask for r in refs if r is not None and r.view == view]
        if not masks:
            return
        self._surfaces[view] = torch.stack(masks).bool().cpu().numpy()
        self._disp_tensors.pop((view, False), None)
        self.warps.forget_source(view)

    def _decode_references(
        self,
        objects: Mapping[int, TrackedObject],
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
        carried = {i: self.clicks_in_view(objects[i], view) for i in ids}
        for i in ids:
            shapes[(len(carried[i][1]), objects[i].prompts.box is not None)].append(i)
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
                boxes=np.array([objects[i].prompts.box.xyxy for i in members])
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

    # --- steps 2-4, streamed -----------------------------------------------------------------
    def run(
        self,
        objects: Mapping[int, TrackedObject],
        ids: list[int],
        refine: bool,
        paint_order: list[int] | None = None,
    ) -> np.ndarray | None:
        """Stream the views once for the objects ``ids`` (step 1 must have run): each view
        encoded at most once, all objects' prompts of a view decoded together (per reference
        view). Sets each object's ``coarse`` masks, and ``refined`` with ``refine`` (or, when the
        configuration does not refine, the coarse ones).

        With ``refine_views`` other than ``"all"`` the views an object is refined in come
        first; every other view is then filled from them (:mod:`lfsam.pipeline.fill`) and is
        neither encoded nor semantically occluded (its coarse masks are propagated, with the
        z-buffer when geometric occluding is on).

        With ``paint_order`` (``ids`` in paint order: every object of the session is in this
        pass) each view's labels are fused on the device as soon as it is done, and returned.
        """
        lf = self.lightfield
        config = self.config
        refine = refine and config.refine
        consensus = refine and config.consensus
        out = {i: ObjectViews.empty(lf.grid_shape, lf.view_shape) for i in ids}
        coarse_out = {i: out[i].copy() for i in ids}
        views = list(lf.view_indices(present_only=True))
        batch_size = config.batch_size_for(self.device)
        references = {objects[i].reference.view for i in ids}
        refined_here = [v for v in views if any(self.refines(v, r) for r in references)]
        filled_here = [v for v in views if not all(self.refines(v, r) for r in references)]
        bar = tqdm(
            total=len(views), desc="views", unit="view", disable=not self.progress or None,
            leave=False,
        )
        sink = (None if paint_order is None else
                ViewLabels(lf.grid_shape, lf.view_shape, ids, paint_order, self.device))
        pending: dict[View, set[int]] = defaultdict(set)

        def done(view: View, final: dict[int, torch.Tensor]) -> None:
            """Count a view done once every object has its final masks there (fused then)."""
            if sink is not None:
                with self.timer("fuse"):
                    sink.add(view, final)
            pending[view].update(final)
            if len(pending[view]) == len(ids):
                del pending[view]
                bar.update(1)

        # The reference views are encoded already (step 1): they go first, on their own, so
        # that every later batch encodes a full ``batch_size`` of new views. Views whose
        # embedding is in memory (e.g. the extra reference views of the automatic mode) come
        # next, before new encodes could push them out of the memory budget.
        pending_views = [v for v in refined_here if v not in references]
        pending_views.sort(key=lambda v: not self.store.in_memory(v))
        batches = [[v for v in refined_here if v in references]]
        batches += [
            pending_views[k : k + batch_size] for k in range(0, len(pending_views), batch_size)
        ]
        # every (reference view, view) pair is warped once, in this order: built ahead in
        # batched passes
        order = [v for batch in batches for v in batch] + filled_here
        self.warps.plan((r, v) for v in order for r in sorted(references) if r != v)
        for batch in batches:
            # A view needs its embedding where some object is propagated into it and
            # refined or semantically occluded there.
            others = [
                v for v in batch if any(v != r and self.refines(v, r) for r in references)
            ]
            embeddings = {}
            if (refine or config.semantic) and others:
                with self.timer("encode"):
                    embeddings = dict(zip(others, self.store.get_many(others), strict=True))
            # Steps 2-3 in every view of the batch, then step 4 of all of them at once: their
            # prompts go through the decoder together (docs/design.md section 3.5).
            deferred: list[tuple[RefineRequest, Writer]] = []
            finals = [
                (view, self.view_step(objects, view, ids, embeddings.get(view), refine, out,
                                      coarse_out, stage="refine", deferred=deferred))
                for view in batch
            ]
            self._refine_deferred(deferred)
            for view, final in finals if not consensus else ():
                done(view, final)
        self.voter.clear()  # forget the voting views' masks
        if consensus:  # every refined view is in: each is voted with its neighbours
            refined = {i: out[i].copy() for i in ids}
            for view in refined_here:
                self.consensus_step(objects, view, ids, refined, out)
                here = [i for i in ids if self.refines(view, objects[i].reference.view)]
                done(view, self._unpacked(view, here, out))
            self.voter.clear()
        for view in filled_here:
            done(view, self.view_step(
                objects, view, ids, None, refine, out, coarse_out, stage="fill"
            ))
        self.voter.clear()
        self.warps.plan(())
        bar.close()
        labels = None
        if sink is not None:
            with self.timer("fuse"):
                labels = sink.field()  # on a GPU: every view's labels in one copy
        for i in ids:
            obj = objects[i]
            obj.coarse = coarse_out[i]
            if refine:
                obj.refined = out[i]
            elif not config.refine:
                obj.refined = coarse_out[i]  # the ablation without refinement ends here
        return labels

    def view_step(
        self,
        objects: Mapping[int, TrackedObject],
        view: View,
        ids: list[int],
        embedding: ViewEmbedding | None,
        refine: bool,
        out: dict[int, ObjectViews],
        coarse_out: dict[int, ObjectViews],
        stage: str = "refine",
        deferred: list[tuple[RefineRequest, Writer]] | None = None,
    ) -> dict[int, torch.Tensor]:
        """Steps 2-4 of the objects ``ids`` in one view; writes their packed masks into
        ``out`` (final) and ``coarse_out`` and returns each object's final mask there (refined,
        or coarse without refinement) on the device.

        ``stage`` ``"refine"`` handles the objects refined in this view (:meth:`refines`; every
        object with ``refine_views="all"``) and ``"fill"`` the others, whose sources
        (:meth:`fill_sources`) must be in ``out`` already.

        With ``deferred``, step 4 waits there for :meth:`_refine_deferred` (with the other views
        of a batch), which then writes ``out`` and the returned masks.
        """
        final: dict[int, torch.Tensor] = {}
        config = self.config
        groups: dict[View, list[int]] = defaultdict(list)
        for i in ids:
            groups[objects[i].reference.view].append(i)
        # (objects, references, warp, coarse masks) per reference view: steps 3-4 at once
        propagated: list[tuple[list[int], list, ForwardWarp, torch.Tensor]] = []
        for ref_view, members in groups.items():
            if self.refines(view, ref_view) != (stage == "refine"):
                continue
            refs = [objects[i].reference for i in members]
            if ref_view == view:  # the reference view keeps its step-1 mask
                stacked = torch.stack([r.mask for r in refs])
                with self.timer("fuse"):
                    bits = pack_masks(stacked)
                for k, i in enumerate(members):
                    out[i].bits[view] = coarse_out[i].bits[view] = bits[k]
                    final[i] = stacked[k]
                continue
            ds, dt = view[0] - ref_view[0], view[1] - ref_view[1]
            warp = self.warp(ref_view, view)
            with self.timer("propagate"):
                coarse = propagate_masks(
                    torch.stack([r.mask for r in refs]), self.disparity(ref_view), ds, dt,
                    config.propagation, warp=warp, fill_holes=config.fill_holes,
                    occlusion_tolerance=config.zbuffer_tolerance if config.geometric else None,
                )
            if stage == "fill":
                with self.timer("fuse"):
                    coarse_bits = pack_masks(coarse)
                for k, i in enumerate(members):
                    coarse_out[i].bits[view] = coarse_bits[k]
                masks = (self.voter.fill(view, ref_view, members, coarse, out) if refine
                         else coarse)
                if refine:
                    with self.timer("fuse"):
                        bits = pack_masks(masks)
                    for k, i in enumerate(members):
                        out[i].bits[view] = bits[k]
                for k, i in enumerate(members):
                    final[i] = masks[k]
                continue
            propagated.append((members, refs, warp, coarse))
        if propagated:
            self._occlude_and_refine(objects, view, propagated, embedding, refine, out,
                                     coarse_out, final, deferred)
        return final

    def _occlude_and_refine(
        self,
        objects: Mapping[int, TrackedObject],
        view: View,
        propagated: list[tuple[list[int], list, ForwardWarp, torch.Tensor]],
        embedding: ViewEmbedding | None,
        refine: bool,
        out: dict[int, ObjectViews],
        coarse_out: dict[int, ObjectViews],
        final: dict[int, torch.Tensor],
        deferred: list[tuple[RefineRequest, Writer]] | None,
    ) -> None:
        """Steps 3-4 in ``view`` of the objects propagated into it from every reference view
        at once (:meth:`view_step`; docs/design.md section 3.5, "one request per view").
        Writes ``coarse_out``, and ``out`` and ``final`` (now, or with ``deferred`` when
        :meth:`_refine_deferred` runs)."""
        config = self.config
        members = [i for group, *_ in propagated for i in group]
        refs = [r for _, group, *_ in propagated for r in group]
        coarse = (propagated[0][3] if len(propagated) == 1
                  else torch.cat([masks for *_, masks in propagated]))
        with self.timer("occlude"):
            weights = None
            if config.semantic:
                sources = stack_source_features(
                    [r.source_feature(self.source_features) for r in refs])
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
            return
        with self.timer("refine"):
            seen, runs = seen_per_mask([warp for *_, warp, _ in propagated],
                                       [len(group) for group, *_ in propagated],
                                       self.lightfield.view_shape)
            carried = [self.clicks_in_view(objects[i], view, zbuffer_test=False)
                       for i in members]
            request = RefineRequest(
                embedding, coarse, weights, seen=seen, frame_runs=runs,
                extra_points=agreeing_clicks(carried, coarse),
            )
        finish = self._refined_writer(view, members, out, final)
        if deferred is None:
            self._refine_deferred([(request, finish)])
        else:
            deferred.append((request, finish))

    def _refine_deferred(self, deferred: list[tuple[RefineRequest, Writer]]) -> None:
        """Step 4 of the views in ``deferred`` together (:func:`~lfsam.pipeline.refinement.
        refine_many`); their outcomes read back at once (:func:`~lfsam.pipeline.refinement.
        read_back`) and handed to their writers (:meth:`_refined_writer`)."""
        if not deferred:
            return
        with self.timer("refine"):
            outcomes = refine_many(
                self.segmenter, [request for request, _ in deferred], self.config.t_iou,
                chunk_size=self.config.refine_chunk_for(self.device),
            )
        with self.timer("fuse"):
            bits, flags = read_back(outcomes)
        sizes = [len(o.masks) for o in outcomes]
        for (_, finish), o, end, n in zip(deferred, outcomes, np.cumsum(sizes), sizes, strict=True):
            finish(o, bits[end - n : end], flags[:, end - n : end])

    def _refined_writer(self, view: View, members: list[int], out: dict[int, ObjectViews],
                        final: dict[int, torch.Tensor]) -> Writer:
        """What :meth:`view_step` does with a view's refinement outcome: count the decoded
        prompts (those with an IoU), write the packed masks, fallback flags and IoUs into
        ``out`` and the masks into ``final``."""
        def finish(outcome: RefinementOutcome, bits: np.ndarray, flags: np.ndarray) -> None:
            fallback, iou = flags[0].astype(bool), flags[1]
            self.decode_counts.update(members[k] for k in np.flatnonzero(~np.isnan(iou)))
            for k, i in enumerate(members):
                out[i].bits[view] = bits[k]
                out[i].fallback[view] = fallback[k]
                out[i].iou[view] = iou[k]
                final[i] = outcome.masks[k]
        return finish

    def consensus_step(self, objects: Mapping[int, TrackedObject], view: View, ids: list[int],
                       refined: dict[int, ObjectViews], out: dict[int, ObjectViews]) -> None:
        """The multi-view consensus in a refined ``view`` (docs/design.md section 3.9): each
        object refined here (not in its own reference view) takes the vote of its refined
        masks here and in the nearest refined views (``refined``: the masks as refinement left
        them, read by every vote), written into ``out`` with its replaced flag."""
        groups: dict[View, list[int]] = defaultdict(list)
        for i in ids:
            groups[objects[i].reference.view].append(i)
        for ref_view, members in groups.items():
            for i in members:
                if out[i].replaced is None:
                    out[i].replaced = np.zeros(self.lightfield.grid_shape, dtype=bool)
            if ref_view == view or not self.refines(view, ref_view):
                continue
            masks, replaced = self.voter.consensus(view, ref_view, members, refined)
            with self.timer("fuse"):
                bits = pack_masks(masks)
                flags = replaced.cpu().numpy()
            for k, i in enumerate(members):
                out[i].bits[view] = bits[k]
                out[i].replaced[view] = flags[k]

    def _unpacked(self, view: View, ids: list[int],
                  table: dict[int, ObjectViews]) -> dict[int, torch.Tensor]:
        """Each object's mask in ``view`` from the packed ``table``, on the device."""
        height, width = self.lightfield.view_shape
        packed = np.stack([table[i].bits[view] for i in ids])
        bits = np.unpackbits(packed, axis=1, count=height * width).astype(bool)
        masks = torch.from_numpy(bits.reshape(len(ids), height, width)).to(self.device)
        return {i: masks[k] for k, i in enumerate(ids)}

    def masks_in_view(
        self, objects: Mapping[int, TrackedObject], ids: list[int], view: View
    ) -> np.ndarray:
        """The objects ``ids``' final masks in one view (steps 1-4, or 1-3 without
        refinement), ``(N, U, V)`` bool; computed for this view only (and, for objects not
        refined here, in their fill sources; with the consensus, in the voters of the refined
        views it needs) and not stored: the masks :meth:`run` gives that view."""
        lf = self.lightfield
        height, width = lf.view_shape
        if not ids:
            return np.zeros((0, height, width), dtype=bool)
        self.ensure_references(objects, ids)
        out = {i: ObjectViews.empty(lf.grid_shape, lf.view_shape, iou=0.0) for i in ids}
        coarse = {i: out[i].copy() for i in ids}
        refine = self.config.refine
        consensus = refine and self.config.consensus
        references = {objects[i].reference.view for i in ids}
        voted: dict[View, list[View]] = {}  # reference view -> refined views to vote in
        for ref_view in references:
            members = [i for i in ids if objects[i].reference.view == ref_view]
            if self.refines(view, ref_view) or not refine:
                targets = [view] if self.refines(view, ref_view) else []
            else:
                targets = self.fill_sources(view, ref_view)
            needed = list(targets)
            if consensus:
                voted[ref_view] = [t for t in targets if t != ref_view]
                for target in voted[ref_view]:
                    needed += [v for v in self.voter.consensus_voters(target, ref_view)
                               if v not in needed]
                if voted[ref_view]:  # an object's own disparity is matched there
                    needed += [v for v in self.voter.match_views(ref_view) if v not in needed]
            for source in needed:
                embedding = (self.embedding(source) if source != ref_view
                             and self.config.needs_view_encoding else None)
                self.view_step(objects, source, members, embedding, refine, out, coarse)
        if consensus:
            refined = {i: out[i].copy() for i in ids}
            for ref_view, targets in voted.items():
                members = [i for i in ids if objects[i].reference.view == ref_view]
                for target in targets:
                    self.consensus_step(objects, target, members, refined, out)
            self.voter.clear()
        if refine and not all(self.refines(view, r) for r in references):
            self.voter.clear()
            self.view_step(objects, view, ids, None, refine, out, coarse, stage="fill")
            self.voter.clear()
        final = out if refine else coarse
        packed = np.stack([final[i].bits[view] for i in ids])
        bits = np.unpackbits(packed, axis=1, count=height * width)
        return bits.reshape(len(ids), height, width).astype(bool)

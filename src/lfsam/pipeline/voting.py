"""Masks decided by a vote of refined views carried by disparity: the fill of views that are not
refined (docs/design.md section 3.7) and the multi-view consensus of refined views (section
3.9, issue 36).

:class:`ViewVoter` works for a :class:`lfsam.pipeline.engine.StreamingEngine` (its warps,
disparities, timer and configuration) within one pass over the views:

- :meth:`ViewVoter.fill` — a view not refined takes each object's mask from the
  :data:`~lfsam.pipeline.sparse.FILL_SOURCES` refined views nearest to it
  (:func:`lfsam.pipeline.fill.fill_from_sources`); an object the center's estimate does not see
  is carried with its own disparity, matched from its masks in the sources
  (:meth:`ViewVoter.own_disparity`), and filled alone;
- :meth:`ViewVoter.consensus` — a refined view's mask of each object is voted by its own
  refined mask and those of the :data:`CONSENSUS_VOTERS` refined views nearest to it, carried
  the same way (their z-buffers, their distance weights; the view's own mask weighs as a voter
  :data:`SELF_DISTANCE` steps away, landed on every pixel, so it is outvoted only by a clear
  majority). A neighbour's landed pixel votes only where it carries the surface this view
  shows there (:data:`AGREE_DISPARITY`, :data:`AGREE_GRAY`): at depth edges a neighbour's
  carried mask is wrong in the same way as its neighbours' (rounding, an estimate's edges), and
  without this check those errors outvote a right answer. Contested pixels (a vote within
  :data:`CONTESTED_MARGIN` of a tie) take the answer of the vote guided-filtered by the view's
  own image. An answer the vote changes beyond recognition (IoU below :data:`REPLACED_IOU`
  with the voted mask) is a segmenter failure, replaced and counted.

The voters of a view depend on geometry only (which views are refined for the object's
reference view), never on the masks, and every vote reads the masks as refinement left them,
so the answer does not depend on the order of the views or of the objects (incremental edits
give the labels of a fresh run).
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import numpy as np
import torch

from lfsam.pipeline.fill import fill_from_sources
from lfsam.pipeline.mask_disparity import matched_disparity, unseen_by_estimate
from lfsam.pipeline.objects import ObjectViews, View
from lfsam.pipeline.propagation import forward_warp
from lfsam.pipeline.sparse import nearest_sources

__all__ = ["AGREE_DISPARITY", "AGREE_GRAY", "CONSENSUS_VOTERS", "CONTESTED_MARGIN",
           "REPLACED_IOU", "SELF_DISTANCE", "ViewVoter"]

#: Other refined views that vote on a refined view's masks (the nearest ones: with every view
#: refined, the 8 around it).
CONSENSUS_VOTERS = 8
#: The view's own refined mask votes as if it were this many view steps away (weight 1 / d =
#: 2.5 against 6.8 for the 8 views around it): it is outvoted only where about three quarters
#: of its neighbours' weight disagrees with it.
SELF_DISTANCE = 0.4
#: A neighbour's landed pixel votes only where its surface is the one this view shows: its
#: disparity within this of the view's own (pixels per view step) ...
AGREE_DISPARITY = 0.15
#: ... and its gray value within this of the view's own (intensities in [0, 1]).
AGREE_GRAY = 0.05
#: Contested pixels (a vote between this and 1 minus this) take the guided filter's answer;
#: stronger majorities keep theirs.
CONTESTED_MARGIN = 0.3
#: A refined mask whose IoU with the voted one is below this is counted as replaced.
REPLACED_IOU = 0.5


class ViewVoter:
    """Votes of carried refined masks for one engine (module docstring).

    Parameters
    ----------
    engine : lfsam.pipeline.engine.StreamingEngine
        Its warps, disparities, timer, configuration and gray views (not imported here: the
        engine owns the voter).
    """

    def __init__(self, engine: Any) -> None:
        # a proxy, not a reference: the engine owns the voter, and a cycle would keep every
        # engine (its embeddings and warps) alive until the cyclic garbage collector runs
        self.engine = weakref.proxy(engine)
        # unpacked masks of voting views within one pass: (view, objects, which table) -> masks
        self._masks: dict[tuple[View, tuple[int, ...], int], torch.Tensor] = {}
        # disparities matched from the masks of objects the estimate does not see, per
        # (object, its sources), within one pass (:meth:`own_disparity`)
        self._own: dict[tuple[int, tuple[View, ...]], float | None] = {}
        self._holes: dict[View, torch.Tensor] = {}

    def clear(self) -> None:
        """Forget the voters' masks and what was matched from them (end of a stage)."""
        self._masks.clear()
        self._own.clear()

    # --- which views vote ---------------------------------------------------------------------
    def consensus_voters(self, view: View, reference: View) -> list[View]:
        """The refined views (other than ``view``) that vote on ``view``'s masks of objects
        whose reference view is ``reference``, nearest first."""
        engine = self.engine
        base = engine.base_refined
        if base is None:
            refined = engine.lightfield.view_indices(present_only=True)
        else:
            refined = base | {reference}
        return nearest_sources(view, refined, CONSENSUS_VOTERS)

    # --- the votes ----------------------------------------------------------------------------
    def fill(self, view: View, ref_view: View, members: list[int], coarse: torch.Tensor,
             out: dict[int, ObjectViews]) -> torch.Tensor:
        """The final masks in ``view`` of objects with reference view ``ref_view`` that are
        not refined there, carried from their refined sources, whose masks ``out`` holds;
        ``coarse`` where no source sees a pixel."""
        engine = self.engine
        sources = engine.fill_sources(view, ref_view)
        with engine.timer("fill"):
            return self._vote(view, members, sources, out, coarse, self_mask=None)

    def consensus(self, view: View, ref_view: View, members: list[int],
                  refined: dict[int, ObjectViews]) -> tuple[torch.Tensor, torch.Tensor]:
        """The voted masks in the refined ``view`` of objects with reference view
        ``ref_view`` (not ``view`` itself: a reference view keeps its step-1 mask), from the
        refined masks ``refined`` holds.

        Returns
        -------
        masks : (N, U, V) bool tensor
        replaced : (N,) bool tensor
            The refined masks the vote changed beyond recognition (IoU < :data:`REPLACED_IOU`).
        """
        engine = self.engine
        voters = self.consensus_voters(view, ref_view)
        with engine.timer("consensus"):
            own = self._unpacked(view, members, refined)
            masks = self._vote(view, members, voters, refined, own, self_mask=own,
                               matched_from=self.match_views(ref_view))
            inter = (masks & own).flatten(1).sum(1).float()
            union = (masks | own).flatten(1).sum(1).float()
            iou = torch.where(union > 0, inter / union.clamp(min=1), torch.ones_like(union))
            return masks, iou < REPLACED_IOU

    def match_views(self, reference: View) -> list[View]:
        """The refined views an object's own disparity is matched from in the consensus (one
        set per reference view, whichever view is voted: it is matched once per object): the
        :data:`CONSENSUS_VOTERS` refined views nearest to the reference view."""
        return self.consensus_voters(reference, reference)

    def _vote(self, view: View, members: list[int], sources: list[View],
              table: dict[int, ObjectViews], fallback: torch.Tensor,
              self_mask: torch.Tensor | None,
              matched_from: list[View] | None = None) -> torch.Tensor:
        """Each object's mask in ``view`` voted by ``sources`` (and, given ``self_mask``, the
        view's own masks at :data:`SELF_DISTANCE`); an object the estimate does not see is
        carried with its own disparity, matched from its masks in ``matched_from`` (default
        ``sources``)."""
        engine = self.engine
        tolerance = engine.config.zbuffer_tolerance
        masks = [self._unpacked(source, members, table) for source in sources]
        disparities = [engine.disparity(source, carried=True) for source in sources]
        warps = [engine.warp(source, view, carried=True) for source in sources]
        distances = [math.hypot(s - view[0], t - view[1]) for s, t in sources]
        voters, voter_disp, voter_warps = list(masks), list(disparities), list(warps)
        if self_mask is not None:
            disparity = engine.disparity(view, carried=True)
            voters.insert(0, self_mask)
            voter_disp.insert(0, disparity)
            voter_warps.insert(0, engine.warp(view, view, carried=True))
            distances.insert(0, SELF_DISTANCE)
        guide = engine.gray(view)
        agree = None if self_mask is None else [None, *self._agreement(view, sources, warps,
                                                                       disparities)]
        voted = fill_from_sources(voters, voter_disp, voter_warps, distances, fallback,
                                  tolerance, guide=guide, agree=agree,
                                  contested=0.0 if self_mask is None else CONTESTED_MARGIN
                                  ).masks
        match = sources if matched_from is None else matched_from
        match_masks = masks if matched_from is None else [
            self._unpacked(source, members, table) for source in match]
        match_disp = disparities if matched_from is None else [
            engine.disparity(source, carried=True) for source in match]
        for n, i in enumerate(members):
            own = self.own_disparity(i, match, [m[n] for m in match_masks], match_disp)
            if own is None:
                continue
            # this object's pixels carried with its own disparity, the rest as they are
            carried = [torch.where(m[n], torch.full_like(d, own), d)
                       for m, d in zip(voters, voter_disp, strict=True)]
            offsets = ([view] if self_mask is not None else []) + list(sources)
            own_warps = [forward_warp(d, view[0] - s, view[1] - t)
                         for d, (s, t) in zip(carried, offsets, strict=True)]
            voted[n] = fill_from_sources(
                [m[n:n + 1] for m in voters], carried, own_warps, distances,
                fallback[n:n + 1], tolerance, guide=guide,
                contested=0.0 if self_mask is None else CONTESTED_MARGIN,
            ).masks[0]
        return voted

    def _agreement(self, view: View, sources: list[View], warps: list[Any],
                   disparities: list[torch.Tensor]) -> list[torch.Tensor]:
        """Per voter, the pixels of ``view`` where its landed surface is the one the view
        shows: disparity within :data:`AGREE_DISPARITY` and gray value within
        :data:`AGREE_GRAY` of the view's own (a voter's surface carried onto another one, at
        depth edges, does not vote there)."""
        engine = self.engine
        here = engine.disparity(view, carried=True)
        gray = engine.gray(view)
        tolerance = engine.config.zbuffer_tolerance
        agree = []
        for source, warp, disparity in zip(sources, warps, disparities, strict=True):
            landed = warp.zbuffer.reshape(here.shape)
            carried = _splat_values(engine.gray(source), warp, warp.visible(disparity, tolerance))
            agree.append(((landed - here).abs() <= AGREE_DISPARITY)
                         & ((carried - gray).abs() <= AGREE_GRAY))
        return agree

    def _unpacked(self, view: View, members: list[int],
                  table: dict[int, ObjectViews]) -> torch.Tensor:
        """``(N, U, V)`` bool masks of ``members`` in ``view`` from ``table`` (cached: each
        voter serves several views)."""
        key = (view, tuple(members), id(table))
        if key not in self._masks:
            height, width = self.engine.lightfield.view_shape
            packed = np.stack([table[i].bits[view] for i in members])
            bits = np.unpackbits(packed, axis=1, count=height * width).astype(bool)
            self._masks[key] = torch.from_numpy(bits.reshape(-1, height, width)).to(
                self.engine.device)
        return self._masks[key]

    # --- objects the estimate does not see (docs/design.md section 3.7) ----------------------
    def own_disparity(self, object_id: int, sources: list[View], masks: list[torch.Tensor],
                      disparities: list[torch.Tensor]) -> float | None:
        """The disparity an object is carried with out of ``sources`` when the center's
        estimate does not see it (:func:`lfsam.pipeline.mask_disparity.unseen_by_estimate`
        over the sources whose carried disparity is that estimate warped): matched from its
        refined ``masks`` there and the sources' carried ``disparities``
        (:func:`lfsam.pipeline.mask_disparity.matched_disparity`); None to carry it with the
        sources' disparity."""
        engine = self.engine
        key = (object_id, tuple(sources))
        if key not in self._own:
            warped = [k for k, source in enumerate(sources)
                      if engine.disparities.warps_center(source)]
            holes = [self._carried_holes(sources[k]) for k in warped]
            own = None
            if warped and unseen_by_estimate([masks[k] for k in warped], holes):
                own = matched_disparity(masks, disparities, sources,
                                        engine.config.zbuffer_tolerance)
            self._own[key] = own
        return self._own[key]

    def _carried_holes(self, view: View) -> torch.Tensor:
        """:meth:`lfsam.disparity.views.ViewDisparities.carried_holes` on the device (cached
        with the carried disparities)."""
        if view not in self._holes:
            self._holes[view] = torch.tensor(
                self.engine.disparities.carried_holes(view), device=self.engine.device
            )
        return self._holes[view]


def _splat_values(values: torch.Tensor, warp: Any, keep: torch.Tensor) -> torch.Tensor:
    """The mean of the kept source ``values`` landing on each target pixel (inf: none)."""
    height, width = values.shape
    size = height * width
    source = warp.valid & keep
    target = torch.where(source, warp.target, size)
    total = torch.zeros(size + 1, dtype=values.dtype, device=values.device)
    count = torch.zeros(size + 1, dtype=values.dtype, device=values.device)
    total.index_add_(0, target, values.reshape(-1))
    count.index_add_(0, target, torch.ones_like(values.reshape(-1)))
    mean = torch.where(count > 0, total / count.clamp(min=1), torch.full_like(total, float("inf")))
    return mean[:size].reshape(height, width)

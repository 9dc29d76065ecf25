"""Automatic mode: every object of a light field, as :class:`LightFieldMaskGenerator`.

It wraps a :class:`lfsam.predictor.LightFieldPredictor` from outside, as Meta's
``SAM2AutomaticMaskGenerator`` wraps ``SAM2ImagePredictor``: the segmenter's automatic mask
generation runs in reference views, and each mask it keeps becomes an object of the predictor,
which then carries it into every view (paper section 3; the paper's setting is the center view
alone, section 4). ``--references corners|ring|all`` adds extra reference views for objects the
center view cannot see (docs/design.md section 8), with the rules for asking only where nothing
is known yet, for objects found twice, and for consecutive ids.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfsam.metrics.recall import default_min_area
from lfsam.pipeline.initial import initial_segmentation
from lfsam.pipeline.references import (
    drop_covered_masks,
    extra_view_points,
    reference_views,
    seen_from,
    unasked_region_points,
)
from lfsam.predictor import LightFieldPredictor, View

__all__ = ["EXTRA_VIEW_ROUNDS", "LightFieldMaskGenerator"]

#: Generator rounds in an extra reference view: the thinned grid, then points in the regions no
#: answer explains (docs/design.md section 8).
EXTRA_VIEW_ROUNDS = 3


class LightFieldMaskGenerator:
    """Find every object of the predictor's light field and add it to the predictor.

    Parameters
    ----------
    predictor : LightFieldPredictor
        With a light field set (:meth:`~LightFieldPredictor.set_lightfield`). Objects it holds
        already stay, and count as found.
    references : {"center", "corners", "ring", "all"}
        Where masks are generated (:func:`lfsam.pipeline.references.reference_views`): the
        center view (the paper's setting), then the extra views in row-major order.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> from lfsam.segmenters import load_segmenter
    >>> lf = generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=3)
    >>> predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf))
    >>> predictor.set_lightfield(lf, disparity="gt")
    >>> ids = LightFieldMaskGenerator(predictor).generate()
    >>> predictor.predict().labels.shape == (3, 3, 48, 64), ids == predictor.object_ids
    (True, True)
    """

    def __init__(self, predictor: LightFieldPredictor, references: str = "center") -> None:
        self.predictor = predictor
        self.references = references

    def generate(self, references: str | None = None) -> list[int]:
        """Add every object found as a new object of the predictor; returns the new ids
        (consecutive, in order of discovery; masks of a view in decreasing area).

        In each extra reference view the objects found so far are carried there (steps 1-4),
        the generator asks only where no mask lands and the center view could not look
        (:func:`~lfsam.pipeline.references.seen_from`: hidden there behind something nearer,
        or outside its frame; :func:`~lfsam.pipeline.references.extra_view_points`), and a new
        mask that mostly lies on such covered pixels is dropped. Up to
        :data:`EXTRA_VIEW_ROUNDS` rounds per view: later rounds ask once in each region that no
        answer explains (:func:`~lfsam.pipeline.references.unasked_region_points`). A new
        object that is an object of an earlier extra view seen again is merged with it (the
        find with the larger reference mask stays).
        """
        predictor = self.predictor
        lf = predictor.require_lightfield()
        references = self.references if references is None else references
        views = [v for v in reference_views(lf.grid_shape, references) if lf.present[v]]
        new_ids: list[int] = []
        for k, view in enumerate(views):
            if k == 0:
                with predictor.timer("initial"):
                    source = initial_segmentation(
                        predictor.segmenter, predictor.embedding(view), lf.views[view], None
                    )
                masks = source.masks.cpu().numpy()
                new_ids += self._add(view, masks, source.scores, np.arange(len(masks)))
            else:
                new_ids = self._generate_in_extra_view(view, views[0], new_ids)
        return predictor.renumber(new_ids)

    def _generate_in_extra_view(self, view: View, center: View, new_ids: list[int]) -> list[int]:
        """One extra reference view; returns ``new_ids`` updated (objects added, objects that
        turned out to be found twice removed)."""
        predictor = self.predictor
        lf = predictor.require_lightfield()
        embedding = predictor.embedding(view)
        min_region = default_min_area(lf.view_shape) // 2
        carried_ids = predictor.object_ids
        carried = predictor.masks_in_view(carried_ids, view)
        # objects found in earlier extra views, with their masks carried here
        found_before = [
            (i, carried[n]) for n, i in enumerate(carried_ids)
            if i in new_ids and predictor.given_mask(i)[0] != center
        ]
        covered = carried.any(axis=0)
        with predictor.timer("disparity"):
            covered |= seen_from(
                predictor.disparity(view), predictor.disparity(center), center[0] - view[0],
                center[1] - view[1], predictor.config.zbuffer_tolerance,
            ).cpu().numpy()
        points = extra_view_points(predictor.segmenter.points_per_side, covered, min_region)
        asked = np.zeros((0, 2), dtype=np.float64)
        explained = covered.copy()
        for _ in range(EXTRA_VIEW_ROUNDS):
            if len(points) == 0:
                break
            with predictor.timer("initial"):
                source = initial_segmentation(
                    predictor.segmenter, embedding, lf.views[view], None, points=points
                )
            masks = source.masks.cpu().numpy()
            keep = drop_covered_masks(masks, covered)
            replaced = self._larger_views(masks, keep, found_before)
            keep[list(replaced)] = True
            added = self._add(view, masks, source.scores, np.flatnonzero(keep))
            for obj_id in replaced.values():
                predictor.remove_object(obj_id)
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
            own = np.count_nonzero(self.predictor.given_mask(obj_id)[1])
            if area > own and area > best.get(obj_id, (0, -1))[0]:
                best[obj_id] = (area, int(index))
        return {index: obj_id for obj_id, (_, index) in best.items()}

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
        predictor = self.predictor
        removed: list[int] = []
        for obj_id in added:
            new_view, new_mask = predictor.given_mask(obj_id)
            carried: dict[View, np.ndarray] = {}  # the new object in each earlier view, once
            for other in earlier:
                if other in removed:
                    continue
                old_view, old_mask = predictor.given_mask(other)
                if old_view == new_view:
                    continue
                if old_view not in carried:
                    carried[old_view] = predictor.masks_in_view([obj_id], old_view)[0]
                there = carried[old_view]
                on_old = np.count_nonzero(there & old_mask)
                if on_old == 0 or 2 * on_old <= np.count_nonzero(there):
                    continue
                smaller = (
                    obj_id
                    if np.count_nonzero(new_mask) <= np.count_nonzero(old_mask)
                    else other
                )
                predictor.remove_object(smaller)
                removed.append(smaller)
                if smaller == obj_id:
                    break
        return removed

    def _add(self, view: View, masks: np.ndarray, scores: Any, keep: np.ndarray) -> list[int]:
        """Add the generator's masks ``masks[keep]`` of ``view`` as new objects (their ids)."""
        first = self.predictor.next_id()
        for n, index in enumerate(keep):
            self.predictor.add_mask(
                first + n, masks[index], view=view, score=float(scores[index]), automatic=True
            )
        return [first + n for n in range(len(keep))]

"""Text prompts over a light field: each phrase's instances found by a text detector in one view
(or several reference views) and added as objects (docs/design.md section 9).

A phrase tagged with a view (``disc@0,0``) runs the detector in that view; an untagged one in
the center view and, with ``references`` other than ``center``, also in the extra reference
views of :func:`lfsam.pipeline.references.reference_views` (center first, then row-major),
where an instance is kept only when at most half of it lies where an object found so far lands
in that view (:func:`lfsam.pipeline.references.drop_covered_masks`, the automatic mode's rule):
an instance the center view found is not found again from a corner, one it could not see is.
Each kept instance becomes an object given by its mask in the view where it was found
(:func:`add_text`, through the predictor's ``add_mask``), with the phrase as its category.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.pipeline.references import check_references, drop_covered_masks, reference_views
from lfsam.predictor import LightFieldPredictor, View
from lfsam.prompts import TextPrompt, check_phrase, validate_objects
from lfsam.segmenters.text import TextDetector

__all__ = ["TextFind", "add_text", "find_text"]


@dataclass(frozen=True)
class TextFind:
    """What one phrase gave in one view.

    Parameters
    ----------
    phrase : str
    view : (s, t)
    ids : tuple of int
        The objects added (best score first).
    dropped : int
        Instances refused because objects found earlier already cover them.
    """

    phrase: str
    view: View
    ids: tuple[int, ...]
    dropped: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (the result's ``meta["text"]`` and ``lfsam segment``'s summary)."""
        return {
            "phrase": self.phrase,
            "view": list(self.view),
            "found": len(self.ids),
            "ids": list(self.ids),
            "dropped": self.dropped,
        }


class _Uncovered:
    """Keeps an instance when at most half of it is ``covered``; counts the others."""

    def __init__(self, covered: np.ndarray) -> None:
        self.covered = covered
        self.refused = 0

    def __call__(self, mask: np.ndarray) -> bool:
        kept = bool(drop_covered_masks(mask[None], self.covered)[0])
        self.refused += not kept
        return kept


def add_text(
    predictor: LightFieldPredictor,
    phrase: str,
    detector: TextDetector,
    view: View | None = None,
    threshold: float | None = None,
    keep: Callable[[np.ndarray], bool] | None = None,
) -> list[int]:
    """Find every instance of ``phrase`` in ``view`` (None = center) with ``detector`` and add
    each to ``predictor`` as an object given by its mask there, with the phrase as its category
    and the detector's score (docs/design.md section 9); ids follow the predictor's
    ``next_id``, best score first. ``keep(mask)`` may refuse an instance (e.g. one already
    found from another view). The detector's seconds count in the predictor's (stage
    ``text``).

    Returns
    -------
    list of int
        The ids of the objects added (empty when nothing was found).

    Raises
    ------
    LfsamError
        An empty phrase, a view outside the grid, or a view absent from the light field.
    """
    lf = predictor.require_lightfield()
    phrase = check_phrase(phrase)
    view = lf.center if view is None else (int(view[0]), int(view[1]))
    validate_objects([TextPrompt(phrase, view)], lf.grid_shape, lf.view_shape)
    if not lf.present[view]:
        raise LfsamError(
            f"text {phrase!r}: view {view[0]},{view[1]} is absent from this light field; "
            "find text in a view that exists"
        )
    start = time.perf_counter()
    with predictor.engine.timer("text"):
        found = detector.detect(lf.views[view], phrase, view=view, threshold=threshold)
    predictor.seconds += time.perf_counter() - start
    ids = []
    for mask, score in zip(found.masks, found.scores, strict=True):
        if keep is not None and not keep(mask):
            continue
        obj_id = predictor.next_id()
        predictor.add_mask(obj_id, mask, view=view, score=float(score), category=phrase)
        ids.append(obj_id)
    return ids


def find_text(
    predictor: LightFieldPredictor,
    detector: TextDetector,
    texts: Sequence[TextPrompt],
    references: str = "center",
    threshold: float | None = None,
) -> list[TextFind]:
    """Find every phrase of ``texts`` and add its instances to ``predictor`` as objects.

    Parameters
    ----------
    predictor : LightFieldPredictor
        With its light field set; objects it holds already count as found.
    detector : TextDetector
    texts : sequence of TextPrompt
    references : {"center", "corners", "ring", "all"}
        Where untagged phrases are looked for besides the center view.
    threshold : float, optional
        The score an instance needs (default: the detector's).

    Returns
    -------
    list of TextFind
        One per phrase and view searched, in order.
    """
    check_references(references)
    lf = predictor.require_lightfield()
    finds: list[TextFind] = []
    for text in texts:
        if text.view is not None:
            views = [text.resolved_view(lf.center)]
        else:
            views = [v for v in reference_views(lf.grid_shape, references) if lf.present[v]]
        for index, view in enumerate(views):
            if index == 0:
                ids = add_text(predictor, text.phrase, detector, view, threshold)
                finds.append(TextFind(text.phrase, view, tuple(ids)))
                continue
            known = predictor.object_ids
            covered = (
                predictor.masks_in_view(known, view).any(axis=0)
                if known
                else np.zeros(lf.view_shape, dtype=bool)
            )
            keep = _Uncovered(covered)
            ids = add_text(predictor, text.phrase, detector, view, threshold, keep=keep)
            finds.append(TextFind(text.phrase, view, tuple(ids), keep.refused))
    return finds

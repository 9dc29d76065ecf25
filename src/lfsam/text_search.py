"""Text prompts over a light field: each phrase's instances found by a text detector in one view
(or several reference views) and added as objects (docs/design.md section 9).

A phrase tagged with a view (``disc@0,0``) runs the detector in that view; an untagged one in
the center view and, with ``references`` other than ``center``, also in the extra reference
views of :func:`lfsam.pipeline.references.reference_views` (center first, then row-major),
where an instance is kept only when at most half of it lies where an object found so far lands
in that view (:func:`lfsam.pipeline.references.drop_covered_masks`, the automatic mode's rule):
an instance the center view found is not found again from a corner, one it could not see is.
Each kept instance becomes an object given by its mask in the view where it was found
(:meth:`lfsam.predictor.LightFieldPredictor.add_text`), with the phrase as its category.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.pipeline.references import check_references, drop_covered_masks, reference_views
from lfsam.predictor import LightFieldPredictor, View
from lfsam.prompts import TextPrompt
from lfsam.segmenters.text import TextDetector

__all__ = ["TextFind", "find_text"]


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
                ids = predictor.add_text(text.phrase, detector, view, threshold)
                finds.append(TextFind(text.phrase, view, tuple(ids)))
                continue
            known = predictor.object_ids
            covered = (
                predictor.masks_in_view(known, view).any(axis=0)
                if known
                else np.zeros(lf.view_shape, dtype=bool)
            )
            keep = _Uncovered(covered)
            ids = predictor.add_text(text.phrase, detector, view, threshold, keep=keep)
            finds.append(TextFind(text.phrase, view, tuple(ids), keep.refused))
    return finds

"""The text detector that answers from ground truth (docs/design.md sections 6 and 9).

It answers a phrase with every ground-truth object of that category visible in the view: each
label of the view whose category name the phrase names (:func:`phrase_matches`), as one mask
with score 1. So the text path's light-field logic (which instances are found in which view, how
they are carried into every other view) is testable with exact numbers, as the click path is
with :class:`lfsam.segmenters.oracle.OracleSegmenter`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.segmenters.text.base import Detections, TextDetector, View, phrase_matches
from lfsam.segmenters.text.registry import TEXT_ORACLE

__all__ = ["OracleTextDetector"]


class OracleTextDetector(TextDetector):
    """Ground-truth answers to text prompts (``--text-model oracle``).

    Parameters
    ----------
    lightfield : LightField
        Must have labels with ``categories`` (``lfsam synth`` writes them).

    Raises
    ------
    LfsamError
        If the light field has no labels or no category names.
    """

    name = TEXT_ORACLE
    random_weights = False
    default_threshold = 0.5

    def __init__(self, lightfield: LightField) -> None:
        if lightfield is None or lightfield.labels is None or not lightfield.categories:
            raise LfsamError(
                "the text oracle answers from ground-truth categories, but this light field "
                "has none; use one made by `lfsam synth` (or with 'categories' in its "
                "lfsam_scene.json or .npz), or choose --text-model sam3"
            )
        self.lightfield = lightfield
        self.categories = dict(lightfield.categories)

    def labels_for(self, phrase: str) -> list[int]:
        """The ground-truth label ids whose category ``phrase`` names, ascending."""
        return sorted(i for i, name in self.categories.items() if phrase_matches(phrase, name))

    def _detect(
        self, image: np.ndarray, phrase: str, view: View | None, threshold: float
    ) -> Detections:
        lf = self.lightfield
        if view is None:
            raise LfsamError("the text oracle needs to know which view it is shown; pass view=")
        labels = lf.view_labels(*view)
        if labels is None:
            raise LfsamError(
                f"no ground-truth labels for view {view[0]},{view[1]} (this light field has "
                "them for the center only); find text in the center view"
            )
        wanted = [i for i in self.labels_for(phrase) if np.any(labels == i)]
        masks = np.stack([labels == i for i in wanted]) if wanted else np.zeros((0, *labels.shape))
        return Detections.build(phrase, masks, np.ones(len(wanted)), labels.shape)

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description for result metadata."""
        return {**super().describe(), "backend": "oracle", "categories": len(self.categories)}

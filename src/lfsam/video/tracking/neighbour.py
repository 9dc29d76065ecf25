"""A placed object's mask in another view, as the segmenter answers it there (issue 47,
eighteenth pass; docs/design.md section 10, "Tracking", step 5).

An answer found again (the object unseen for frames) that holds half of an object placed
earlier in the frame is that object (:data:`lfsam.video.tracking.rules.HELD`). Where the answer
lies in another view than the placed object's reference view, that object's mask there is its
reference mask carried by disparity (:func:`lfsam.video.tracking.frame_search.carried_to`), which
leaves out what the reference view does not see. A thin, mostly hidden object shows
different parts in different views, and the carried mask misses most of what it shows:
fresh seed 3603 without jitter, frame 5, object 4 placed from its center mask (103 pixels)
covered 47 of the 143 pixels it showed in corner view (4, 0). A small disc hidden in every
view (object 3) was then "found" there by the widening on those 143 pixels (colours 0.47
alike, at a depth within the tolerance), a third of them on placed objects and under half of
object 4's carried mask: accepted. Object 3 took object 4's pixels over the next frames, and
the two swapped ids (144 lost triples, 2 shown switches).

So where a found-again answer meets the carried mask of an object placed from another view,
that object is asked in the answer's view (:func:`asked_mask`: one positive point at the
deepest pixel of its carried mask where that view shows the object's depth, under a
temporary id), and its mask there is the carried mask with that answer: the object as the
segmenter sees it in that view. The answer holding half of it is then that object's, as in
its reference view; an answer that is another object beside it holds little of it.
"""

from __future__ import annotations

import numpy as np

from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.tracking.carry import deepest

__all__ = ["AGREE", "ASK", "NEIGHBOUR_ID", "asked_mask"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.neighbour_ask`.
ASK = True
#: The temporary id a placed object is asked under (plus its placement's index).
NEIGHBOUR_ID = 2_000_000
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.neighbour_agree`.
AGREE = 0.3


def asked_mask(predictor: object, index: int, view: tuple[int, int], carried: np.ndarray,
               disparity: np.ndarray, object_disparity: float) -> np.ndarray | None:
    """A placed object's mask in ``view`` as the segmenter answers it there: one positive
    point at the deepest pixel of its ``carried`` mask where that view shows its depth (the
    view's ``disparity`` within :data:`AGREE` of the object's, ``object_disparity``: a pixel
    it is seen on there, not a nearer one covering it), asked under ``NEIGHBOUR_ID + index``
    and forgotten after; None where no such pixel is or the answer lands in another view.

    ``predictor``: the frame's :class:`lfsam.predictor.LightFieldPredictor` (or any object
    with its ``set_object``, ``predict_reference`` and ``remove_object``)."""
    seeds = carried & (np.abs(disparity - object_disparity) <= AGREE)
    if not seeds.any():
        return None
    row, col, _ = deepest(seeds)
    obj_id = NEIGHBOUR_ID + index
    predictor.set_object(ObjectPrompts(obj_id, (PointPrompt(float(col), float(row), True,
                                                            view),)))
    try:
        answer_view, mask, _ = predictor.predict_reference(obj_id)
    finally:
        predictor.remove_object(obj_id)
    return mask if answer_view == view else None

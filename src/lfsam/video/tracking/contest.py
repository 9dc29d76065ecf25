"""An answer that took a neighbour through one of its clicks (issue 47, seventeenth pass;
docs/design.md section 10, "Tracking", step 9).

The search prompts an object with several positive points on its template's support
(:func:`lfsam.video.tracking.carry.positive_points`), and a segmenter answers the union of what the
points lie on (the oracle by construction, SAM where the clicks fall on two objects). Where
a neighbour of alike colours has moved in front of the object, part of the support, and so
one of the points, lies on the neighbour, and the object's answer holds both: fresh seed
2901, frame 6, object 5's three clicks, one on object 2 (55 of its 454 supported pixels);
its answer held all 242 pixels object 2 showed, and object 2's own answers, lying on those
pixels, were refused as placed already in every view (hidden for a frame while it showed
218-277 pixels a view, 25 lost triples, an identity switch there and back). Colours and
depth do not separate the two (their templates explain the contested pixels 0.21-0.42 and
0.27-0.39; object 2 at disparity 1.13 in front of object 5's 0.75-1.55).

Fresh seed 3202 under the oracle's jitter, frame 2, the same with nothing asked: object 4's
click on object 2 (which came out in front of it, 424 pixels) took all of it, object 2's
support was then read as placed (not the object) in every view, and no stage had enough left
to prompt; its first look near the prediction (75 % of its template supported, before
anything was placed) lay on those pixels. Hidden for three frames while it showed 424 pixels
in the center view: 75 lost triples.

So an object about to be hidden for an answer, or a first look near its prediction (the
template's place there, where the support reached :data:`lfsam.video.tracking.rules.NEAR_SUPPORT`),
that an object placed earlier in the frame holds (:func:`blocker`: more than half of it)
contests it where that object was placed from
several positive points, one of them on the contested answer: the placed object is asked
again without the points that lie there (:func:`without_points`), and where its new answer
is its old one less the contested part (:func:`gives_up`) it is placed with that answer and
the contesting object is searched again. Where the points on the contested pixels were the
placed object's own (a hidden object's template matching a visible look-alike), the other
points answer the same region again, nothing changes, and the cost is one segmenter call.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
from scipy import ndimage

from lfsam.prompts import ObjectPrompts

__all__ = ["CHECK", "HELD", "KEPT", "blocker", "gives_up", "without_points"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.contest_check`.
CHECK = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.contest_held`.
HELD = 0.5
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.contest_kept`.
KEPT = 0.9


def blocker(answers: Iterable[tuple[tuple[int, int], np.ndarray]], eligible: Sequence[int],
            placed: Callable[[int, tuple[int, int]], np.ndarray]
            ) -> tuple[int, tuple[int, int], np.ndarray] | None:
    """The first of ``answers`` (``(view, mask)``: refused answers, a first look's place) that
    one placed object of ``eligible`` (indices into the frame's placements; ``placed(k,
    view)``: the ``k``-th placed mask in ``view``) holds more than :data:`HELD` of:
    ``(k, view, mask)``, or None."""
    for view, mask in answers:
        area = int(np.count_nonzero(mask))
        if area == 0:
            continue
        for k in eligible:
            if np.count_nonzero(mask & placed(k, view)) > HELD * area:
                return k, view, mask
    return None


def without_points(prompt: ObjectPrompts, contested: np.ndarray, view: tuple[int, int],
                   center: tuple[int, int]) -> ObjectPrompts | None:
    """``prompt`` without its positive points in ``view`` that lie on ``contested`` (that
    view's mask, grown by a pixel), or None where none lies there or none would be left."""
    near = ndimage.binary_dilation(contested)
    rows, cols = near.shape

    def on_it(p: object) -> bool:
        return bool(p.positive and (p.view or center) == view
                    and near[min(max(round(p.y), 0), rows - 1),
                             min(max(round(p.x), 0), cols - 1)])

    kept = tuple(p for p in prompt.points if not on_it(p))
    if len(kept) == len(prompt.points) or not any(p.positive for p in kept):
        return None
    return ObjectPrompts(prompt.obj_id, kept, prompt.box)


def gives_up(old: np.ndarray, new: np.ndarray, contested: np.ndarray) -> bool:
    """Whether the placed object's new answer ``new`` is its old one ``old`` less the
    ``contested`` part (all three in one view): it lies :data:`KEPT` inside the old answer,
    keeps more than :data:`HELD` of the old answer outside the contested part, and holds at
    most :data:`HELD` of the contested answer."""
    area = np.count_nonzero(new)
    if area == 0:
        return False
    rest = old & ~contested
    return bool(np.count_nonzero(new & old) >= KEPT * area
                and np.count_nonzero(new & rest) > HELD * np.count_nonzero(rest)
                and np.count_nonzero(new & contested) <= HELD * np.count_nonzero(contested))

"""An oracle of one image for the search's unit tests (tests/test_video_search_*.py;
docs/design.md section 10, "Tracking"): each answer is the label under the first positive
point, and the search runs over that image alone, the same in every view (disparity 0)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from lfsam.api import RunOptions, SegmentOptions
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.tracking.carry import deepest
from lfsam.video.tracking.online import OnlineTracker
from lfsam.video.tracking.search import Track, search_object

CENTER = (2, 2)
QUIET = SegmentOptions(run=RunOptions(progress=False))


def label_answer(labels: np.ndarray, view: tuple[int, int] | None = None) -> Callable:
    """The oracle of one image: the label under the first positive point, answered as
    ``view`` (default: the point's view, else the center view)."""

    def answer(obj: ObjectPrompts):
        point = next(p for p in obj.points if p.positive)
        return view or point.view or CENTER, labels == labels[round(point.y), round(point.x)]

    return answer


def search_one_image(track: Track, image: np.ndarray, answer: Callable, **options):
    """:func:`search_object` for object 1 over ``image`` in every view, no other view
    searched, nothing placed, no negative or fresh clicks, no box."""
    placed = options.pop("placed", None)
    return search_object(1, track, lambda v: image, CENTER, [], answer, lambda v: placed,
                         None, (), False, **options)


def covered_object(shown: int, seed: int, skirt: tuple[slice, slice]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An object of 20 x 30 random bright pixels at (20, 30) on a dark random background
    (label 1), all but its first ``shown`` pixels (row by row) behind a black cover (label 3)
    that also spreads over ``skirt`` outside the object: ``(look, image, labels, cover)``."""
    rng = np.random.default_rng(seed)
    look = rng.uniform(150, 250, (20, 30, 3)).astype(np.float32)
    image = rng.uniform(20, 90, (80, 100, 3)).astype(np.float32)
    labels = np.ones((80, 100), np.int64)
    image[20:40, 30:60] = look
    labels[20:40, 30:60] = 2
    hidden = np.ones((20, 30), bool)
    hidden.ravel()[:shown] = False
    cover = np.zeros((80, 100), bool)
    cover[skirt] = True
    cover[20:40, 30:60] = hidden
    image[cover] = 0.0
    labels[cover] = 3
    return look, image, labels, cover


def least_ious(frames: list, pairs: dict[int, int], options: SegmentOptions = QUIET
               ) -> dict[int, float]:
    """Tracked from one click per object in frame 0 (the deepest pixel of each object showing
    100 pixels in the center view, ids in label order; the oracle, ground-truth disparity;
    ``options``: e.g. the oracle's imperfections): per ``{label: obj_id}`` of ``pairs``, the
    least IoU of ``obj_id`` in the last frame's views where the object of ``label`` shows at
    least 100 pixels."""
    labels = frames[0].labels[frames[0].center]
    prompts = []
    for value in np.unique(labels[labels > 1]):
        mask = labels == value
        if mask.sum() >= 100:
            row, col, _ = deepest(mask)
            prompts.append(ObjectPrompts(len(prompts) + 1, (PointPrompt(float(col), float(row)),)))
    tracker = OnlineTracker("oracle", disparity="gt", options=options, search=True,
                            memory=False)
    tracker.add_prompts(prompts)
    for lf in frames:
        ours = tracker.track(lf).labels
    out = {}
    for label, obj_id in pairs.items():
        truth, mine = frames[-1].labels == label, ours == obj_id
        shown = truth.sum(axis=(2, 3)) >= 100
        iou = (mine & truth).sum(axis=(2, 3)) / np.maximum((mine | truth).sum(axis=(2, 3)), 1)
        out[label] = float(iou[shown].min())
    return out

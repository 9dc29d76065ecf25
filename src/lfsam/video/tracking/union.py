"""An answer to several clicks that took an unprompted neighbour with one of them (issue 47,
eighteenth pass; docs/design.md section 10, "Tracking", step 5).

The search prompts an object with up to three positive points on its template's support
(:func:`lfsam.video.tracking.carry.positive_points`), and a segmenter answers the union of what the
points lie on (the oracle by construction, SAM where the clicks fall on two objects). Where a
neighbour of alike colours and depth has moved in front of the object, part of the support,
and so a point, may lie on it. The contest (:mod:`lfsam.video.tracking.contest`) settles this where
the neighbour is a tracked object; where it is not (an object nobody clicked), nothing did: fresh
seed 3303 without jitter, frame 2, object 3 (1,453 pixels, 670 of them showing behind an
unprompted object at disparity 2.0 against its 1.8, within the depth gate's tolerance of 1.2)
was supported on 808 pixels, 165 of them on the neighbour; its three clicks answered both
objects (1,823 pixels, colours 0.37 alike, over :data:`lfsam.video.tracking.rules.MIN_ALIKE`). The
track's template became the union, and from frame 3 on it followed the neighbour: 250 of the
701 visible triples lost over ten frames (38 %), while the object showed 1,441-1,453 pixels
from frame 4 on.

An answer larger than the object ever was (:data:`GROWTH` times its largest area) to several
clicks is suspect: each click is then asked alone (:func:`supported_clicks`), and where some
but not all of those answers lie mostly on the support (:data:`SUPPORTED` of their pixels),
the clicks whose answers do are asked together, and that answer is judged instead. An object
being uncovered grows past its largest area too, but then every click answers the object
(all are kept) and the answer stands; the cost is one call per click and one more.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["CHECK", "GROWTH", "SUPPORTED", "checked", "supported_clicks", "suspect"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.union_check`.
CHECK = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.union_growth`.
GROWTH = 1.2
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.union_supported`.
SUPPORTED = 0.5

Click = tuple[float, float]
Answer = tuple[tuple[int, int], np.ndarray]


def suspect(area: int, largest: int, clicks: int) -> bool:
    """Whether an answer of ``area`` pixels to ``clicks`` positive points, for an object whose
    largest area so far is ``largest``, is split by click (:func:`supported_clicks`).

    >>> suspect(1823, 1453, 3), suspect(1500, 1453, 3), suspect(1823, 1453, 1)
    (True, False, False)
    """
    return bool(CHECK and clicks > 1 and area > GROWTH * max(largest, 1))


def supported_clicks(ask: Callable[[Sequence[Click]], Answer], clicks: Sequence[Click],
                     view: tuple[int, int], support: np.ndarray) -> Answer | None:
    """Ask each of ``clicks`` alone (``ask(points)``: the object prompted with those positive
    points, its reference view and mask); where some but not all of them answer mostly on the
    ``support`` (:data:`SUPPORTED` of the answer, in ``view``), the answer to those clicks
    together; else None, the clicks asked together again (the predictor holds the object's
    prompt as before).

    >>> support = np.zeros((4, 8), bool); support[:, :4] = True
    >>> regions = {0: support, 1: ~support}  # the object left, a neighbour right
    >>> def ask(points):
    ...     mask = np.zeros((4, 8), bool)
    ...     for x, _ in points:
    ...         mask |= regions[int(x >= 4)]
    ...     return (2, 2), mask
    >>> int(supported_clicks(ask, [(1.0, 1.0), (6.0, 1.0)], (2, 2), support)[1].sum())
    16
    >>> supported_clicks(ask, [(1.0, 1.0), (2.0, 2.0)], (2, 2), support) is None
    True
    """
    kept = [click for click in clicks if _on_support(ask([click]), view, support)]
    if 0 < len(kept) < len(clicks):
        return ask(kept)
    ask(clicks)
    return None


def checked(ask: Callable[[Sequence[Click]], Answer],
            judge: Callable[[tuple[int, int], np.ndarray], tuple[int, int] | None],
            clicks: Sequence[Click], answer: Answer, shift: tuple[int, int],
            support: np.ndarray, largest: int) -> tuple[Answer, tuple[int, int]]:
    """An accepted ``answer`` to ``clicks`` (its template ``shift``), or, where it is
    :func:`suspect`, the answer to its clicks on the support where ``judge`` (the search's
    acceptance, :func:`lfsam.video.tracking.answer.accept_answer`) accepts that one too (its shift
    with it). The predictor is left holding the prompt of the answer returned."""
    if not suspect(int(np.count_nonzero(answer[1])), largest, len(clicks)):
        return answer, shift
    split = supported_clicks(ask, clicks, answer[0], support)
    split_shift = None if split is None else judge(*split)
    if split is None or split_shift is None:
        if split is not None:
            ask(clicks)  # the predictor holds the clicks together again
        return answer, shift
    return split, split_shift


def _on_support(answer: Answer, view: tuple[int, int], support: np.ndarray) -> bool:
    """Whether an answer in ``view`` lies mostly on the support."""
    answer_view, mask = answer
    area = np.count_nonzero(mask)
    return bool(answer_view == view and area
                and np.count_nonzero(mask & support) >= SUPPORTED * area)

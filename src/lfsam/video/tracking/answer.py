"""One stage of the search prompted and its answer judged (issue 47; docs/design.md section
10, "Tracking", steps 4 and 5): :func:`prompt_stage` places the positive points on the match's
deepest supported pixels, negative points on the neighbours placed earlier in the frame and the
user's negative clicks, asks the segmenter, and :func:`accept_answer` decides whether the answer
is the searched object (its size, its place, its look, its depth); :func:`explaining_shift`
finds the shift at which a part of the template explains an answer.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial

import numpy as np
from scipy import ndimage

from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt
from lfsam.video.tracking import motion, rules, union
from lfsam.video.tracking.carry import (
    MIN_PIXELS,
    Template,
    box_around,
    looks_alike,
    neighbour_points,
    positive_points,
)
from lfsam.video.tracking.match import support_in_answer
from lfsam.video.tracking.motion import Track, predicted_disparity

__all__ = ["accept_answer", "explaining_shift", "prompt_stage"]


def prompt_stage(obj_id: int, track: Track, stage: tuple, center: tuple[int, int],
                  answer: Callable, placed: Callable, placed_ids: np.ndarray | None,
                  negatives: Sequence[PointPrompt], use_box: bool,
                  fresh: Sequence[PointPrompt], depth: Callable | None = None,
                  held: Callable | None = None, widened: bool = False,
                  refused: dict[tuple[int, int], np.ndarray] | None = None
                  ) -> tuple[tuple[int, int], np.ndarray, tuple[int, int], Template] | None:
    """Prompt one stage's match (:func:`search_object`, steps 4 and 5): the accepted view,
    mask, shift and located template, or None (``widened``: a match of the widening stage,
    needing :data:`WIDE_SUPPORT` and the answer at the object's depth, its shift None where
    the answer is a part of the object). The support needed near the prediction is a
    share of the template's part inside the frame (an object leaving the frame shows only
    that part; in the ring's views less what objects placed in this frame cover there,
    :data:`PLACED_SUPPORT`), elsewhere of the whole
    template. ``refused``: where given, the answers refused in the stage's view are
    added to it (``{view: mask}``, :data:`REFUSED_AGAIN`)."""
    view, radius, image, template, found, support = stage
    if found is None:
        return None
    carried, _, shift = found
    # near the prediction a share of the template's part inside the frame (an object leaving
    # the frame shows only that part); away from it a share of the whole template: a sliver
    # at the frame's border far from where the object should be is not enough to give its
    # id back (a look-alike entering there took a hidden object's id)
    core = carried
    known = placed(view)
    if rules.PLACED_SUPPORT and known is not None and view != track.view:
        core = core & ~known  # covered by an object placed in this frame: cannot show it
    needed = ((rules.WIDE_SUPPORT if widened else rules.NEAR_SUPPORT) * np.count_nonzero(core)
              if radius is not None else rules.FAR_SUPPORT * template.mask.sum())
    if np.count_nonzero(support) < max(MIN_PIXELS, needed):
        return None
    seeds = support.copy()
    for p in fresh:  # the positive point keeps away from a correction in this frame
        if (p.view or center) == view:
            seeds[min(max(round(p.y), 0), seeds.shape[0] - 1),
                  min(max(round(p.x), 0), seeds.shape[1] - 1)] = False
    positives = positive_points(seeds, 1 if fresh else 3)
    negative_xy = neighbour_points(carried, support, placed_ids if view == center else None)
    user = [p for p in negatives if (p.view or center) == view
            and (p in fresh or not carried[round(p.y), round(p.x)])]
    negative = (*(PointPrompt(x, y, False, view) for x, y in negative_xy),
                *(PointPrompt(p.x, p.y, False, view) for p in user))
    box = BoxPrompt(*box_around(carried, 0.15), view=view) if use_box else None
    # all positive points together; where that answer is refused, each alone (a point on a
    # look-alike pixel of the background must not sink the others)
    tries = [positives] + ([[p] for p in positives] if len(positives) > 1 else [])

    def ask(chosen: Sequence[tuple[float, float]]) -> tuple[tuple[int, int], np.ndarray]:
        points = (*(PointPrompt(x, y, True, view) for x, y in chosen), *negative)
        return answer(ObjectPrompts(obj_id, points, box))

    def judge(ref_view: tuple[int, int], mask: np.ndarray) -> tuple[int, int] | None:
        return accept_answer(mask, support, carried, track,
                       known if ref_view == view else placed(ref_view), image, template,
                       shift, None if widened else radius,
                       (ref_view, depth) if depth is not None else None, checked=widened,
                       held=None if held is None or track.unseen == 0 else partial(held, ref_view))

    for chosen in tries:
        ref_view, mask = ask(chosen)
        at = judge(ref_view, mask)
        track.support = np.count_nonzero(support) / max(np.count_nonzero(carried), 1)
        if at is not None:  # larger than the object ever was: a click on a neighbour?
            (ref_view, mask), at = union.checked(ask, judge, chosen, (ref_view, mask), at,
                                                 support, track.area)
        if at is not None and widened and mask.sum() < motion.KEEP_TEMPLATE * track.area:
            # a part of the object found away from the prediction: the template fits that
            # part at a range of shifts, so the place it gives is no measure of the motion
            # (a velocity of tens of pixels); the object is kept where it was predicted, its
            # motion unchanged (no shift: :func:`update`)
            return ref_view, mask, None, template
        if at is not None:
            located = replace(template, origin=(template.origin[0] + at[0],
                                                template.origin[1] + at[1]))
            return ref_view, mask, at, located
        if refused is not None and ref_view == view and mask.any():
            refused[view] = refused[view] | mask if view in refused else mask.copy()
    return None


def explaining_shift(mask: np.ndarray, template: Template, image: np.ndarray, radius: int
                     ) -> tuple[int, int] | None:
    """The shift within ``radius`` pixels of the template's place at which its pixels that
    still look the same (:func:`lfsam.video.tracking.match.robust_costs`' support) cover most of
    ``mask`` (ties: the nearer shift), if they cover :data:`EXPLAINED` of it and at least
    :data:`lfsam.video.tracking.carry.MIN_PIXELS`; else None (of the shifts within :data:`ALMOST` of
    the best count, the nearest). An answer is then a part of the object
    near where it should be, whatever the match chose: the support of a partly hidden
    object's match may lie on look-alike pixels beside it."""
    du, dv = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    du, dv = du.ravel(), dv.ravel()
    counts = support_in_answer(template, image, mask, du, dv)
    if counts.max() < max(MIN_PIXELS, rules.EXPLAINED * mask.sum()):
        return None
    # a part of the object fits the template at a range of shifts: of those within
    # ALMOST of the best, the nearest to the prediction (the motion decides)
    near = np.where(counts >= rules.ALMOST * counts.max(), du**2 + dv**2, np.iinfo(np.int64).max)
    k = int(np.argmin(near))
    return int(du[k]), int(dv[k])


def accept_answer(mask: np.ndarray, support: np.ndarray, carried: np.ndarray, track: Track,
            placed: np.ndarray | None, image: np.ndarray, template: Template,
            shift: tuple[int, int] = (0, 0), radius: int | None = None,
            depth: tuple | None = None, checked: bool = False,
            held: Callable[..., Sequence[np.ndarray]] | None = None) -> tuple[int, int] | None:
    """Whether an answer is the searched object (see the module docstring, step 5): the
    template's shift where it is (``shift``, or :func:`explaining_shift`'s), or None.

    ``depth``: ``(view, depth(view, mask))`` of :func:`search_object`: an object found again
    after hidden frames, or by :func:`explaining_shift`, must also lie at its depth.
    ``held()``: the masks of objects placed earlier in this frame in the answer's view; an
    answer holding :data:`HELD` of one of them is that object; ``held(mask)``, asked once the
    answer passed every other check, the same with the segmenter's masks there
    (:mod:`lfsam.video.tracking.neighbour`)."""
    area = int(mask.sum())
    covered = int((mask & support).sum())
    grown = area > rules.MAX_GROWTH * max(track.area, 1) + 50
    # an object first seen mostly covered grows past MAX_GROWTH as it is uncovered: it is
    # still the object where the answer holds its whole support, is at most UNCOVERED_VIEW of
    # the view (not the background) and lies at its depth (checked below)
    if area == 0 or (grown and not (rules.UNCOVERED and depth is not None
                                    and covered >= 0.9 * support.sum()
                                    and area <= rules.UNCOVERED_VIEW * mask.size)):
        return None
    if placed is not None and (mask & placed).sum() > 0.5 * area:
        return None
    if held is not None and _holds(mask, held()):
        return None
    explained = False
    if covered < 0.5 * support.sum():
        # a support partly on look-alike pixels around the object: the answer must then lie
        # where the object was carried to and hold a quarter of the support, or be a part of
        # the template near the prediction
        inside = int((mask & ndimage.binary_dilation(carried, iterations=2)).sum())
        if covered < 0.25 * support.sum() or inside < 0.7 * area:
            at = None if radius is None else explaining_shift(mask, template, image, radius)
            if at is None:
                return None
            shift, explained = at, True
    look = template.image[template.mask]
    if looks_alike(image[mask], look) < rules.MIN_ALIKE and not (
            rules.KNOWN_PART and covered >= rules.KNOWN_SUPPORT * support.sum()
            and looks_alike(image[mask & carried], look) >= rules.MIN_ALIKE):
        return None
    if depth is not None and (checked or explained or grown or track.unseen > 0):
        value = depth[1](depth[0], mask)
        expected, tolerance = predicted_disparity(track)
        if value is not None and abs(value - expected) > tolerance:
            return None
    return None if held is not None and _holds(mask, held(mask)) else shift


def _holds(mask: np.ndarray, others: Sequence[np.ndarray]) -> bool:
    """Whether ``mask`` holds :data:`HELD` of one of ``others`` (their pixels)."""
    return any(np.count_nonzero(mask & other)
               >= rules.HELD * max(np.count_nonzero(other), MIN_PIXELS) for other in others)

"""Tracks that come back: finding a carried object in every frame, hidden or not (issue 47;
docs/design.md section 10, "Tracking").

For segmenters without memory (the oracle, SAM 2's image model) each object is carried from the
frame where it was last found (:mod:`lfsam.video.tracking.carry`), and is never dropped for good: an
object that is not found in a frame is *hidden* there (empty masks) and keeps its id, its last
appearance (the template), its motion and its disparity; it is searched for again in every
later frame and comes back under its own id (*found*). The search of one object in a frame
(:func:`search_object`):

1. **Prediction.** Constant velocity from its last two sightings (in center-view pixels; a
   match supporting under :data:`VELOCITY_SUPPORT` of the template moves it by that share), and
   its disparity changing at its last rate: the template is placed where the object should be
   in a view, parallax included (a pixel of the center view at disparity ``d`` is at
   ``p - d (s - s_c, t - t_c)`` in view ``(s, t)``, section 1).
2. **Stages**, first accepted wins: the predicted place in the object's last reference view,
   then in the center view and the outer ring's views (an object hidden in the center view is
   often visible there: the light field, as ``--references ring`` finds hidden objects),
   ranked by how much of the template their match supports, the view where it is seen most
   first, each within :func:`search_radius` pixels (growing with every frame unseen); then the
   *widening*: where the prediction missed (the object turned while hidden, or was hidden
   before its velocity was known), the shifts within the radius where most of the template
   could be by colour and depth, not on objects placed nor on answers refused there
   (:func:`lfsam.video.tracking.match.likely_shifts_many`, every view at once), scored exactly, the
   :data:`WIDE_VIEWS` views showing most of it prompted (a part found there keeps the
   predicted place and velocity); then the whole of its own view
   and of the center view where the radius did not cover it. An answer in its own view
   covering under :data:`SMALL_SHARE` of its match's support waits for the ring's views
   (:data:`SMALL_ANSWER`: an eroded sliver where another view shows the object whole).
3. **Matching.** The masked SSD of the template at every shift (:func:`lfsam.video.tracking.match.
   cost_map`, one batch of FFTs); of its :data:`CANDIDATES` cheapest shifts the one whose
   *support* (pixels that still look like the template, :func:`lfsam.video.tracking.match.
   robust_costs`) is largest wins, so an object half behind another is still that object.
   With ``disparities`` the view's disparity is a fourth channel: a pixel farther in depth
   from the object's last disparity than :func:`predicted_disparity`'s tolerance is not the
   object whatever its colour (a background of the object's colours is told apart by its
   depth; :data:`DEPTH_GATE`, the object's disparity the median over its answers). It
   needs at least :data:`NEAR_SUPPORT` of its template supported near the prediction (in
   the ring's views less what objects placed earlier in the frame cover,
   :data:`PLACED_SUPPORT`), :data:`FAR_SUPPORT` elsewhere.
4. **Prompts**: up to three positive points at the deepest supported pixels (where their
   answer is refused, each alone), negative points on neighbouring objects placed earlier in
   the frame (center view), the user's negative clicks of that view, and for SAM 2 a box
   around the carried mask.
5. **Acceptance**: the answer covers at least half of the support (or a quarter, lying
   mostly where the template was carried to: a support partly on look-alike pixels around the
   object; or, near the prediction, a part of the template explains it at a shift within the
   search radius, :func:`explaining_shift`, the shift then used), is at most
   :data:`MAX_GROWTH` times the object's largest area (or, an object being uncovered, holds
   90 % of the support, is at most :data:`UNCOVERED_VIEW` of the view and lies at its depth),
   does not lie mostly on an object
   placed earlier in that view, looks like the template (colour histograms,
   :func:`looks_alike`; an answer holding :data:`KNOWN_SUPPORT` of the support, by its part
   inside the carried template: the rest may be a part the template never held,
   :data:`KNOWN_PART`) and, when found again after hidden frames or explained so, lies at
   the object's depth (its median disparity within :func:`predicted_disparity`'s tolerance):
   appearance, motion and depth before an id is given back, so that a look-alike elsewhere
   in depth cannot take it. Where the answers in the object's own view are refused and the
   ring finds nothing, that view is matched again with the refused answers' pixels as not
   the object (:data:`REFUSED_AGAIN`: a match on a background of its colours beside it).
   The support needed is a share of the template's part inside the frame (an object leaving
   the frame shows only that part), and an object cut by the frame's border in its own view
   is prompted in the view that sees most of it. An accepted answer to several clicks larger
   than the object ever was is split by click (:mod:`lfsam.video.tracking.union`).

The template is replaced by the answer when the answer shows most of the object; a mostly
hidden answer keeps the fuller template (moved to where it was found). Each object's state per
frame is one of :data:`STATES` (``meta["tracks"]`` of each frame's result).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.tracking import rules
from lfsam.video.tracking.answer import explaining_shift, prompt_stage
from lfsam.video.tracking.carry import (
    MIN_PIXELS,
    Template,
    looks_alike,
)
from lfsam.video.tracking.match import (
    cost_map,
    cost_maps,
    likely_shifts_many,
    margins_in,
    placed_at,
    robust_costs,
    with_depth,
)
from lfsam.video.tracking.motion import (
    STATES,
    Track,
    near_reach,
    predicted,
    predicted_disparity,
    search_radius,
)

__all__ = [
    "STATES",
    "Track",
    "explaining_shift",
    "looks_alike",
    "search_object",
    "search_radius",
]


def near_support(template: Template, image: np.ndarray, reach: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robust cost (:func:`lfsam.video.tracking.match.robust_costs`: the sum over the template
    of each pixel's distance, summed over channels, truncated at
    :data:`lfsam.video.tracking.carry.MAX_PIXEL_DIFFERENCE`, so that pixels covered by something in
    front cost the same wherever the template is: an object mostly behind another is found by
    its visible part, where the SSD is led astray by the cover) of every shift within
    ``reach`` pixels of the template's place.

    Returns
    -------
    cost : (2 reach + 1, 2 reach + 1) float array
    du, dv : int arrays of the same shape
    """
    du, dv = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    cost, _ = robust_costs(template, image, du, dv)
    return cost.reshape(du.shape), du, dv


def _best_shift(template: Template, image: np.ndarray, radius: int | None, reach: int = 0,
                costs_given: tuple | None = None
                ) -> tuple[np.ndarray, np.ndarray, tuple[int, int]] | None:
    """The shifted mask and support of the shift with the least robust cost
    (:func:`near_support`) among the :data:`CANDIDATES` cheapest by masked SSD
    (:func:`lfsam.video.tracking.match.cost_map`; ``costs_given``: its result, computed already)
    and, with ``reach`` and where none of those shows most of the template, every shift that
    close to the predicted place (ties: the nearer shift)."""
    cost, du, dv = costs_given if costs_given is not None else cost_map(template, image,
                                                                        radius)
    flat = cost.ravel()
    finite = np.flatnonzero(np.isfinite(flat))
    best: tuple[float, int, tuple[int, int]] | None = None
    values = flat[finite]
    if values.size > rules.CANDIDATES:  # the CANDIDATES cheapest, in the order a stable sort gives
        keep = values <= np.partition(values, rules.CANDIDATES - 1)[rules.CANDIDATES - 1]
        finite, values = finite[keep], values[keep]
    chosen = finite[np.argsort(values, kind="stable")[:rules.CANDIDATES]]
    if chosen.size:
        costs, counts = robust_costs(template, image, du.ravel()[chosen], dv.ravel()[chosen])
        k = int(np.argmin(costs))  # the first of equal costs, as the cheaper SSD
        best = (float(costs[k]), int(counts[k]),
                (int(du.ravel()[chosen[k]]), int(dv.ravel()[chosen[k]])))
    if reach > 0 and (best is None or best[1] < rules.SURE * template.mask.sum()):
        costs, ru, rv = near_support(template, image, reach)
        index = np.lexsort(((ru**2 + rv**2).ravel(), costs.ravel()))[0]
        if best is None or costs.ravel()[index] <= best[0]:
            shift = (int(ru.ravel()[index]), int(rv.ravel()[index]))
            best = (float(costs.ravel()[index]), 0, shift)
    if best is None:
        return None
    placed = placed_at(template, image, *best[2])
    if placed is None:
        return None
    return placed[0], placed[1], best[2]


def search_object(
    obj_id: int,
    track: Track,
    images: Callable[[tuple[int, int]], np.ndarray],
    center: tuple[int, int],
    views: Sequence[tuple[int, int]],
    answer: Callable[[ObjectPrompts], tuple[tuple[int, int], np.ndarray]],
    placed: Callable[[tuple[int, int]], np.ndarray | None],
    placed_ids: np.ndarray | None,
    negatives: Sequence[PointPrompt],
    use_box: bool,
    first: tuple | None = None,
    fresh: Sequence[PointPrompt] = (),
    disparities: Callable[[tuple[int, int]], np.ndarray | None] | None = None,
    depth: Callable[[tuple[int, int], np.ndarray], float | None] | None = None,
    held: Callable[..., Sequence[np.ndarray]] | None = None,
) -> tuple[tuple[int, int], np.ndarray, tuple[int, int], Template] | None:
    """Find a carried object in this frame (see the module docstring).

    Parameters
    ----------
    obj_id : int
    track : Track
        Its state after the latest frame (read only: :func:`update` changes it).
    images : callable
        ``images(view)``: that view's ``(U, V, 3)`` image.
    center : (s, t)
    views : sequence of (s, t)
        The views to search besides the track's and the center (the outer ring's).
    answer : callable
        ``answer(prompts)`` sets the object's prompts in the frame's predictor and returns
        its reference view and mask.
    placed : callable
        ``placed(view)``: the union of the masks of objects placed earlier in this frame in
        that view (None: not known).
    placed_ids : (U, V) int array or None
        Those objects' ids in the center view (0 elsewhere), for negative points.
    negatives : sequence of PointPrompt
        The user's negative clicks that hold in this frame (those of earlier frames are
        dropped where they land on the carried mask: the object moved there).
    use_box : bool
        Prompt with a box around the carried mask too (SAM 2).
    first : tuple, optional
        The first stage's match (:func:`first_look`), computed already.
    fresh : sequence of PointPrompt
        Those of ``negatives`` given in this frame: always kept, and the positive point (one
        then) is the supported pixel farthest from them and from the support's border.
    disparities : callable, optional
        ``disparities(view)``: that view's ``(U, V)`` disparity map (None: unknown); a
        template pixel is then supported only where the view's disparity is near the object's
        predicted disparity (:func:`with_depth`).
    depth : callable, optional
        ``depth(view, mask)``: an answer's median disparity in that view (None: unknown). An
        answer found again after hidden frames, or accepted by :func:`explaining_shift`,
        must then lie within :func:`predicted_disparity`'s tolerance of the object's
        disparity (:func:`~lfsam.video.tracking.answer.accept_answer`).
    held : callable, optional
        ``held(view)``: each object placed earlier in this frame, its mask in that view;
        ``held(view, mask)``: those the segmenter was asked for there, where they meet the
        answer ``mask`` (:mod:`lfsam.video.tracking.neighbour`). An answer found again that holds
        :data:`HELD` of one of them is that object
        (:func:`~lfsam.video.tracking.answer.accept_answer`).

    Returns
    -------
    (view, mask, shift, template) or None
        The accepted reference view and mask, the template's shift from its predicted place
        (None: a part of the object found by the widening stage, whose place is no measure
        of its motion; the template is then the predicted one) and the located template;
        None: not found.
    """
    expected, tolerance = predicted_disparity(track)
    radius = search_radius(track)

    def match(view: tuple[int, int], radius: int | None, given: tuple | None = None,
              reach: int | None = None) -> tuple:
        """The view's image, the predicted template there, its match and its support less
        the pixels of objects placed already (they are not this one)."""
        image, template, gated = prepared(view)
        if reach is None:
            reach = near_reach(track) if radius is not None else 0
        found = given if given is not None else _best_shift(
            *gated, radius, reach, ssd.get(view) if radius is not None else None)
        return staged(view, radius, image, template, found)

    def staged(view: tuple[int, int], radius: int | None, image: np.ndarray,
              template: Template, found: tuple | None) -> tuple:
        support = None
        if found is not None:
            known = placed(view)
            support = found[1] if known is None else found[1] & ~known
        return view, radius, image, template, found, support

    looks: dict[tuple[int, int], tuple] = {}
    ssd: dict[tuple[int, int], tuple] = {}  # each view's masked SSD within the radius

    def prepared(view: tuple[int, int]) -> tuple:
        """The view's image, the predicted template there and both gated by depth
        (:func:`with_depth`), once per view."""
        if view not in looks:
            image = np.asarray(images(view), np.float32)  # float32 views: not copied
            template = predicted(track, view, center)
            looks[view] = (image, template, with_depth(
                template, image, None if disparities is None else disparities(view),
                expected, tolerance))
        return looks[view]

    def ranked(views: Sequence[tuple[int, int]]) -> list[tuple]:
        """:func:`match` in each view, without the near shifts' scoring, the masked SSD of
        every view from one batch of FFTs (the template's transform once)."""
        if not views:
            return []
        ready = [prepared(v) for v in views]
        maps = cost_maps([r[2][0] for r in ready], [r[2][1] for r in ready], radius)
        ssd.update(zip(views, maps, strict=True))  # scored near the prediction after
        return [staged(v, radius, image, template, _best_shift(*gated, radius, 0, m))
                for v, (image, template, gated), m in zip(views, ready, maps, strict=True)]

    def widening(views: Sequence[tuple[int, int]]) -> list[tuple]:
        """Stage 3's matches (:func:`widened`, every view's likely shifts from one batch of
        FFTs, :func:`lfsam.video.tracking.match.likely_shifts_many`): the :data:`WIDE_VIEWS` views
        whose match shows most of the template, the most first."""
        ready = [prepared(v) for v in views]
        likely = likely_shifts_many([r[2][0] for r in ready], [r[2][1] for r in ready],
                                    radius, rules.WIDE_CANDIDATES,
                                    [not_the_object(v) for v in views])
        # every view where some shift could hold MIN_PIXELS is scored exactly: ranked by the
        # bound alone, the view showing the object was left out on seed 703 (its return a
        # frame late)
        return sorted((widened(v, du, dv) for v, (du, dv, bound) in zip(views, likely,
                                                                        strict=True)
                       if bound >= MIN_PIXELS), key=lambda st: -share(st))[:rules.WIDE_VIEWS]

    def widened(view: tuple[int, int], du: np.ndarray, dv: np.ndarray) -> tuple:
        """:func:`match` over the likely shifts ``du, dv`` within the radius (stage 3)."""
        image, template, (gated, view_image) = prepared(view)
        _, counts = robust_costs(gated, view_image, du, dv)
        # of the shifts supported nearly as well as the best, the nearest to the prediction:
        # a part of the object fits the template at a range of shifts (the motion decides)
        k = int(np.argmin(np.where(counts >= rules.ALMOST * counts.max(), du**2 + dv**2,
                                   np.iinfo(np.int64).max)))
        # scored on a sample of the template's pixels where the plateau is wide: the best
        # refined around it on all of them
        ru, rv = np.mgrid[-1:2, -1:2]
        du, dv = (du[k] + ru).ravel(), (dv[k] + rv).ravel()
        costs, _ = robust_costs(gated, view_image, du, dv)
        k = int(np.lexsort(((np.abs(ru) + np.abs(rv)).ravel(), costs))[0])
        placed_there = placed_at(gated, view_image, int(du[k]), int(dv[k]))
        return staged(view, radius, image, template, None if placed_there is None
                      else (*placed_there, (int(du[k]), int(dv[k]))))

    def not_the_object(view: tuple[int, int]) -> np.ndarray | None:
        """What the widening reads as not the object in ``view``: the objects placed earlier
        in the frame and, with :data:`WIDE_REFUSED`, the answers refused there."""
        known = placed(view)
        extra = ([m[view] for m in (refused, refused_ring) if view in m]
                 if rules.WIDE_REFUSED else [])
        if not extra:
            return known
        out = np.zeros(extra[0].shape, bool) if known is None else known.copy()
        for mask in extra:
            out |= mask
        return out

    def rematch(view: tuple[int, int], refused: np.ndarray) -> tuple:
        """:func:`match` in ``view`` once more, its ``refused`` pixels (answers refused
        there) read as :data:`REFUSED_VALUE` (not the object), every shift near the
        prediction scored (:data:`REFUSED_AGAIN`)."""
        image, template, _ = prepared(view)
        masked = image.copy()
        masked[refused] = rules.REFUSED_VALUE
        gated = with_depth(template, masked, None if disparities is None
                           else disparities(view), expected, tolerance)
        return staged(view, radius, image, template,
                      _best_shift(*gated, radius, near_reach(track)))

    def share(stage: tuple) -> float:
        if stage[4] is None:
            return 0.0
        return np.count_nonzero(stage[5]) / np.count_nonzero(stage[3].mask)

    # 1. the predicted place in its own view; 2. in the center and the outer views, where
    # it is seen most first (an object hidden in one view is often visible in others: it is
    # carried from there and prompted there); 3. the whole of its own view and the center's
    others = [v for v in dict.fromkeys([center, *views]) if v != track.view]
    first_stage = match(track.view, radius, first)
    # an object cut by the frame's border in its own view (less than SURE of its template
    # inside) is prompted in the view that sees most of it: its own view joins the ranking
    cut = bool(first_stage[4] is not None
               and first_stage[4][0].sum() < rules.SURE * track.template.mask.sum())
    refused: dict[tuple[int, int], np.ndarray] = {}
    small = None  # an answer in its own view much smaller than its match (SMALL_ANSWER)
    if not cut:
        asked: list[ObjectPrompts] = []

        def asking(prompts: ObjectPrompts) -> tuple[tuple[int, int], np.ndarray]:
            asked.append(prompts)
            return answer(prompts)

        found = prompt_stage(obj_id, track, first_stage, center, asking, placed, placed_ids,
                              negatives, use_box, fresh, depth, held, refused=refused)
        if found is not None:
            if not (rules.SMALL_ANSWER and np.count_nonzero(found[1])
                    < rules.SMALL_SHARE * np.count_nonzero(first_stage[5])):
                return found
            small = (found, asked[-1], track.support)
    # the views are ranked by their SSD candidates alone; every shift near the prediction
    # is scored (near_support) only in the RESCORED best-ranked views, about to be prompted
    near = sorted([*ranked(others), *([first_stage] * cut)], key=lambda st: -share(st))
    near = (st if share(st) >= rules.SURE or rank >= rules.RESCORED else match(st[0], radius)
            for rank, st in enumerate(near))
    refused_ring: dict[tuple[int, int], np.ndarray] = {}  # the answers refused in the ring
    for stage in near:
        found = prompt_stage(obj_id, track, stage, center, answer, placed, placed_ids,
                              negatives, use_box, fresh, depth, held, refused=refused_ring)
        if found is not None:
            return found
    if small is not None:  # no view of the ring did better: the small answer after all
        found, prompts, track.support = small
        answer(prompts)  # the object's prompts in the frame's predictor again
        return found
    # the answers refused in its own view were not the object: that view matched again
    # without them (a match on a background of its colours beside it), after the ring (a
    # view that sees more of it first: seed 1101)
    if rules.REFUSED_AGAIN and track.view in refused:
        found = prompt_stage(obj_id, track, rematch(track.view, refused[track.view]),
                              center, answer, placed, placed_ids, negatives, use_box,
                              fresh, depth, held)
        if found is not None:
            return found
    # 3. widening: the prediction missed (the object turned while hidden, or was hidden before
    # its velocity was known, and the masked SSD is led astray by the cover over most of
    # it): the likeliest shifts within the radius in every view, the views showing most of
    # it prompted, the answer at the object's depth
    for stage in widening([track.view, *others]):
        found = prompt_stage(obj_id, track, stage, center, answer, placed, placed_ids,
                              negatives, use_box, fresh, depth, held, widened=True)
        if found is not None:
            return found
    # 4. the whole view, where the radius has not covered it yet (a radius reaching every
    # shift that overlaps the view matched the same shifts in stage 2, with less support
    # needed)
    whole = [v for v in [track.view, *others[:1]]
             if margins_in([prepared(v)[1]], [prepared(v)[0]], radius)
             != margins_in([prepared(v)[1]], [prepared(v)[0]], None)]
    for stage in (match(v, None) for v in whole):
        found = prompt_stage(obj_id, track, stage, center, answer, placed, placed_ids,
                              negatives, use_box, fresh, depth, held)
        if found is not None:
            return found
    return None


def first_look(track: Track, image: np.ndarray, center: tuple[int, int],
               disparity: np.ndarray | None = None) -> tuple[float, tuple | None]:
    """The match at the predicted place in the object's own view (``disparity``: that
    view's map, :func:`with_depth`): the fraction of its template supported there, and the
    match (for :func:`search_object`'s ``first``)."""
    template = predicted(track, track.view, center)
    found = _best_shift(*with_depth(template, np.asarray(image, np.float32), disparity,
                                    *predicted_disparity(track)),
                        search_radius(track), near_reach(track))
    if found is None:
        return 0.0, None
    return np.count_nonzero(found[1]) / max(np.count_nonzero(template.mask), 1), found

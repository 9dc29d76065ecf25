"""One frame of constrained-prompt tracking with the search of issue 47 (docs/design.md
section 10, "Tracking"): the user's prompted objects first, then every carried object, the
surest first, each searched for by :func:`lfsam.video.tracking.search.search_object` and placed in
the frame's predictor where it is found; the bookkeeping of what is placed where (its masks
carried between views by disparity). An answer that jumped (:func:`lfsam.video.tracking.consistency.
jumped`) keeps the track before it as a shadow, searched for after every object is placed
(:func:`lfsam.video.tracking.consistency.look_again`). An answer found again that another hidden
object, still to be searched, explains clearly better (:func:`lfsam.video.tracking.claims.rival`) is
left to that object, searched first (each such rival once a frame). An object refused for an answer
that an object placed earlier from several clicks holds contests it
(:mod:`lfsam.video.tracking.contest`): that object, asked again without its clicks on the answer,
gives the answer up where its new answer is its old one less that part. An object placed
from another view than a found-again answer's, whose carried mask meets it, is asked there
(:mod:`lfsam.video.tracking.neighbour`): the answer holding half of it is that object's."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence

import numpy as np
from scipy import ndimage

from lfsam.pipeline.references import reference_views
from lfsam.prompts import ObjectPrompts
from lfsam.video.tracking import (
    claims,
    consistency,
    contest,
    motion,
    neighbour,
    placement,
    rules,
    search,
)
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.motion import update
from lfsam.video.tracking.prompts import latest_prompts, negatives_since, prompts_at, start_frame
from lfsam.video.tracking.search import Track, first_look, search_object

__all__ = ["RETRY_UNANSWERED", "carried_to", "median_disparity", "object_disparity",
           "search_frame"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.retry_unanswered`.
RETRY_UNANSWERED = True


def carried_to(mask: np.ndarray, disparity: object, source: tuple[int, int],
               target: tuple[int, int]) -> np.ndarray:
    """A mask of view ``source`` carried into view ``target`` by the source view's disparity
    (section 1: ``p - d (s_target - s_source, t_target - t_source)``), rounded, closed by one
    pixel: where an object placed in one view is in another (what the source view cannot see
    is left out)."""
    out = np.zeros_like(mask)
    rows, cols = np.nonzero(mask)
    if rows.size == 0 or source == target:
        return mask.copy()
    values = np.asarray(disparity.cpu().numpy() if hasattr(disparity, "cpu") else disparity)
    d = np.nan_to_num(values[rows, cols])
    r = np.rint(rows - d * (target[0] - source[0])).astype(int)
    c = np.rint(cols - d * (target[1] - source[1])).astype(int)
    keep = (r >= 0) & (r < mask.shape[0]) & (c >= 0) & (c < mask.shape[1])
    if not keep.any():
        return out
    r, c = r[keep], c[keep]
    r0, c0 = max(r.min() - 2, 0), max(c.min() - 2, 0)
    crop = out[r0:r.max() + 3, c0:c.max() + 3]  # a view: closed in place, in the crop only
    crop[r - r0, c - c0] = True
    crop |= ndimage.binary_closing(crop, iterations=1)
    return out


def median_disparity(disparity: object, mask: np.ndarray) -> float | None:
    """The median of a view's disparity over ``mask`` (None where it has no finite value):
    an answer's depth, robust to a boundary that spills onto the background."""
    values = np.asarray(disparity.cpu().numpy() if hasattr(disparity, "cpu") else disparity)
    picked = values[mask]
    picked = picked[np.isfinite(picked)]
    return float(np.median(picked)) if picked.size else None


def object_disparity(disparity: object, mask: np.ndarray) -> float:
    """An object's disparity: :func:`median_disparity` over its answer (0 where it has none).
    The median, not the mean: an answer whose boundary spills a pixel onto the background
    (the oracle's jitter, SAM's soft edges) would pull a small object's mean towards the
    background's depth, and the depth gate (:data:`lfsam.video.tracking.rules.DEPTH_GATE`) would
    then refuse the object's own pixels."""
    value = median_disparity(disparity, mask)
    return 0.0 if value is None else value


def search_frame(predictor: object, lf: object, index: int, order: Sequence[int],
                 prompts: dict[int, ObjectPrompts | None], tracks: dict[int, Track],
                 use_box: bool) -> dict[int, str]:
    """One frame of constrained-prompt tracking with the search (module docstring): every
    object of ``order`` is prompted (the user's positive prompts at ``index``) or searched for,
    added to ``predictor`` where it is found; returns each object's state (:data:`STATES`).

    ``prompts[obj_id]`` holds the object's prompts of every frame (None for an object found
    automatically); ``tracks`` is updated in place.
    """
    center = lf.center
    ring = [v for v in reference_views(lf.grid_shape, "ring")[1:] if lf.present[v]]
    placed_ids = np.zeros(lf.view_shape, np.int64)
    done: list[tuple[int, tuple[int, int], np.ndarray]] = []
    cache: dict[tuple[tuple[int, int], int], np.ndarray] = {}
    maps: dict[tuple[int, int], np.ndarray] = {}

    def disparity_of(view: tuple[int, int]) -> np.ndarray:
        """A view's disparity map as an array (once per frame)."""
        if view not in maps:
            values = predictor.disparity(view)
            maps[view] = np.asarray(values.cpu().numpy() if hasattr(values, "cpu")
                                    else values, np.float32)
        return maps[view]

    each: dict[tuple[int, tuple[int, int]], np.ndarray] = {}
    # placed objects asked in another view (neighbour), by (placement, view); None: not asked
    seen_there: dict[tuple[int, tuple[int, int]], np.ndarray | None] = {}

    def placed_one(k: int, view: tuple[int, int]) -> np.ndarray:
        """The ``k``-th object placed in this frame, its mask in ``view`` (carried once)."""
        if (k, view) not in each:
            _, source, mask = done[k]
            each[(k, view)] = mask if source == view else carried_to(
                mask, disparity_of(source), source, view)
        return each[(k, view)]

    def placed_each(view: tuple[int, int]) -> list[np.ndarray]:
        """Each object placed so far in this frame, its mask in ``view``."""
        return [placed_one(k, view) for k in range(len(done))]

    def placed_in(view: tuple[int, int]) -> np.ndarray:
        """Where the objects placed so far in this frame are in ``view`` (the union grows by
        the objects placed since it was last asked for)."""
        key = (view, len(done))
        if key not in cache:
            ready = max((n for v, n in cache if v == view), default=0)
            out = (cache[(view, ready)] if ready else np.zeros(lf.view_shape, bool)).copy()
            for k in range(ready, len(done)):
                out |= placed_one(k, view)
            cache[key] = out
        return cache[key]

    floats: dict[tuple[int, int], np.ndarray] = {}

    def view_of(view: tuple[int, int]) -> np.ndarray:
        """A view as float32, converted once per frame (every search of the frame reads it)."""
        if view not in floats:
            floats[view] = lf.views[view].astype(np.float32)
        return floats[view]

    # the latest search's answers and their prompts (contest; consistency.look_again reads
    # the last prompts)
    tried: list[tuple[tuple[int, int], np.ndarray, ObjectPrompts]] = []

    def answer(obj: ObjectPrompts) -> tuple[tuple[int, int], np.ndarray]:
        predictor.set_object(obj)
        view, mask, _ = predictor.predict_reference(obj.obj_id)
        tried.append((view, mask, obj))
        return view, mask

    def mark(obj_id: int, view: tuple[int, int], mask: np.ndarray) -> None:
        """``obj_id`` in the center view's ids where no object placed before it is."""
        here = mask if view == center else carried_to(mask, disparity_of(view), view, center)
        placed_ids[here & (placed_ids == 0)] = obj_id

    def place(obj_id: int, view: tuple[int, int], mask: np.ndarray) -> None:
        done.append((obj_id, view, mask))
        mark(obj_id, view, mask)

    def replace_placed(k: int, view: tuple[int, int], mask: np.ndarray) -> None:
        """The ``k``-th placement's mask replaced (contest.gives_up): what is placed where
        is worked out again."""
        done[k] = (done[k][0], view, mask)
        cache.clear()
        for cached in (each, seen_there):
            for key in [key for key in cached if key[0] == k]:
                del cached[key]
        placed_ids[:] = 0
        for entry in done:
            mark(*entry)

    states: dict[int, str] = {}
    own_prompts = {i: (None if prompts.get(i) is None else prompts_at(prompts[i], index))
                   for i in order}
    started = [i for i in order if prompts.get(i) is None
               or (start_frame(prompts[i]) is not None and index >= start_frame(prompts[i]))]
    prompted = [i for i in started if own_prompts[i] is not None and own_prompts[i].has_positive]
    carried = [i for i in started if i not in prompted and i in tracks
               and tracks[i].template is not None]
    # the surest first (most of the template still seen at its predicted place), so that an
    # object that went behind another cannot take that one's place
    first = {i: first_look(tracks[i], view_of(tracks[i].view), center,
                           disparity_of(tracks[i].view) if rules.DEPTH_GATE else None)
             for i in carried}
    carried.sort(key=lambda i: (tracks[i].unseen > 0, -first[i][0], i))

    def prompt_object(obj_id: int, own: ObjectPrompts, state: str) -> None:
        """``obj_id`` prompted with ``own`` (and its negative clicks that hold here): placed
        as ``state`` with a fresh template where the answer is not mostly on objects placed
        already, else hidden."""
        negatives = negatives_since(prompts[obj_id], index)
        view, mask = answer(own.with_points([p for p in negatives if p not in own.points]))
        known = placed_in(view)
        if not mask.any() or (mask & known).sum() > 0.5 * mask.sum():
            predictor.remove_object(obj_id)
            track = tracks.setdefault(obj_id, Track(view))
            track.unseen += 1
            states[obj_id] = track.state = "hidden"
            return
        disparity = object_disparity(disparity_of(view), mask)
        old = tracks.get(obj_id)
        track = Track(view, Template.from_mask(lf.views[view], mask), disparity=disparity,
                      area=int(mask.sum()), sightings=1, state=state)
        if old is not None:
            track.velocity, track.area = old.velocity, max(old.area, track.area)
        tracks[obj_id] = track
        states[obj_id] = state
        place(obj_id, view, mask)

    for obj_id in prompted:
        prompt_object(obj_id, own_prompts[obj_id], "prompted")

    def answer_depth(view: tuple[int, int], mask: np.ndarray) -> float | None:
        return median_disparity(disparity_of(view), mask)

    def held_by(view: tuple[int, int], mask: np.ndarray | None = None) -> list[np.ndarray]:
        """Each object placed so far in this frame, its mask in ``view``; with the answer
        ``mask``: those placed from another view whose carried mask meets it, as the segmenter
        answers them there (neighbour, each asked once a view and frame)."""
        if mask is None:
            return placed_each(view)
        out = []
        for k, carried in enumerate(placed_each(view)):
            if not neighbour.ASK or done[k][1] == view or not (carried & mask).any():
                continue
            if (k, view) not in seen_there:
                _, source, placed_mask = done[k]
                seen_there[(k, view)] = neighbour.asked_mask(
                    predictor, k, view, carried, disparity_of(view),
                    object_disparity(disparity_of(source), placed_mask))
            if seen_there[(k, view)] is not None:
                out.append(seen_there[(k, view)])
        return out

    def search_for(obj_id: int, search_id: int, track: Track,
                   image: Callable[[tuple[int, int]], np.ndarray], hint: object) -> tuple | None:
        """:func:`search_object` for ``track``, prompted under ``search_id``, with
        ``obj_id``'s negative clicks (those since its last prompt and this frame's own)."""
        negatives = () if prompts.get(obj_id) is None else negatives_since(prompts[obj_id], index)
        own = own_prompts[obj_id]
        fresh = () if own is None else tuple(p for p in own.points if not p.positive)
        return search_object(search_id, track, image, center, ring, answer, placed_in,
                             placed_ids, negatives, use_box, hint, fresh,
                             disparity_of if rules.DEPTH_GATE else None, answer_depth,
                             held_by)

    def settle(obj_id: int, track: Track, view: tuple[int, int], mask: np.ndarray,
               shift: tuple[int, int] | None, located: Template, k: int | None = None) -> None:
        """An accepted answer: the track moved to it (steps 6 and 8), the object placed (or
        its ``k``-th placement replaced, contest)."""
        disparity = object_disparity(disparity_of(view), mask)
        # an answer far from the prediction and at another depth: the track before it is
        # kept as its shadow and searched for (consistency.look_again, below)
        if consistency.CHECK and shift is not None and consistency.jumped(
                track, view, located, disparity, center):
            consistency.doubt(track)
        # a poorly supported match of a partly seen object: its template placed where it
        # explains the answer (placement), whatever texture the match fitted
        if (placement.CHECK and shift is not None and track.support < motion.VELOCITY_SUPPORT
                and mask.sum() < motion.KEEP_TEMPLATE * track.area):
            located = placement.placed_by_answer(located, mask, view_of(view),
                                                 disparity_of(view), disparity,
                                                 search.search_radius(track))
        update(track, view, mask, located, view_of(view), disparity, center,
               shift is not None)
        states[obj_id] = track.state
        if k is None:
            place(obj_id, view, mask)
        else:
            replace_placed(k, view, mask)

    # objects placed from several positive points: (their prompt, the track before it moved,
    # the search's shift and template), by placement index (contest)
    clicks: dict[int, tuple[ObjectPrompts, Track, tuple[int, int] | None, Template]] = {}

    def contested(obj_id: int) -> bool:
        """Whether an answer refused to ``obj_id`` is given up by the object placed from
        several clicks that held it (contest, module docstring there): that object is then
        placed with its answer less the contested part."""
        # its answers, and where its first look matched it near the prediction (its support
        # then read as placed: nothing was asked), the template's place there
        answers = [(v, m) for v, m, _ in tried]
        share, look = first[obj_id]
        if look is not None and share >= rules.NEAR_SUPPORT:
            answers.append((tracks[obj_id].view, look[0]))
        held = contest.blocker(answers, list(clicks), placed_one)
        if held is None:
            return False
        k, view, mask = held
        other, source, old = done[k]
        prompt, before, shift, located = clicks[k]
        here = mask if view == source else carried_to(mask, disparity_of(view), view, source)
        fewer = contest.without_points(prompt, here, source, center)
        if fewer is None:
            return False
        new_view, new = answer(fewer)
        if new_view != source or not contest.gives_up(old, new, here):
            predictor.set_object(prompt)  # as it was
            return False
        del clicks[k]
        tracks[other] = copy.deepcopy(before)
        settle(other, tracks[other], source, new, shift, located, k)
        return True

    queue, moved = list(carried), set()  # moved: rivals searched first (claims.rival), once
    contesting: set[int] = set()  # objects that contested an answer (contest), once a frame
    while queue:
        obj_id = queue.pop(0)
        track = tracks[obj_id]
        tried.clear()
        found = search_for(obj_id, obj_id, track, view_of, first[obj_id][1])
        if found is None and contest.CHECK and obj_id not in contesting and clicks:
            contesting.add(obj_id)
            if contested(obj_id):
                queue.insert(0, obj_id)
                continue
        if found is None:
            if obj_id in predictor.object_ids:
                predictor.remove_object(obj_id)
            track.unseen += 1
            track.lost = True
            states[obj_id] = track.state = "hidden"
            continue
        view, mask, shift, located = found
        # an answer found again that another hidden object explains clearly better, or an
        # answer grown past claims.GROWN times the object's area that another object still to
        # be searched (tracked too) explains so: that object is searched first, this one again
        # after it (claims.rival)
        grown = bool(mask.sum() > claims.GROWN * max(track.area, 1))
        other = (claims.rival(obj_id, view, mask, view_of(view), tracks,
                              [i for i in queue if i not in moved], center, answer_depth,
                              hidden_only=not grown)
                 if claims.CHECK and (track.unseen > 0 or grown) else None)
        if other is not None:  # each rival moved once: the frame's searches stay bounded
            moved.add(other)
            predictor.remove_object(obj_id)
            queue.remove(other)
            queue[:0] = [other, obj_id]
            continue
        prompt = next((p for v, m, p in reversed(tried)
                       if m is mask or np.array_equal(m, mask)), None)
        if (contest.CHECK and prompt is not None
                and sum(p.positive for p in prompt.points) > 1):
            clicks[len(done)] = (prompt, copy.deepcopy(track), shift, located)
        settle(obj_id, track, view, mask, shift, located)

    def shadow_image(view: tuple[int, int]) -> np.ndarray:
        """A view with the objects placed in this frame read as not the object (a shadow's
        search, consistency.look_again: the look-alike its id holds is no candidate)."""
        return np.where(placed_in(view)[..., None], np.float32(rules.REFUSED_VALUE),
                        view_of(view))

    for obj_id in carried if consistency.CHECK else ():
        if tracks[obj_id].shadow is None:
            continue

        def shadow_search(shadow_id: int, shadow: Track, obj_id: int = obj_id) -> tuple | None:
            tried.clear()
            return search_for(obj_id, shadow_id, shadow, shadow_image, None)

        back = consistency.look_again(
            obj_id, tracks, shadow_search, predictor, lambda: tried[-1][2] if tried else None,
            lambda v, m: object_disparity(disparity_of(v), m), view_of, center)
        if back is not None:
            states[obj_id] = tracks[obj_id].state
            place(obj_id, *back)
    # an object whose prompts were never answered with an accepted mask (no template: hidden
    # since they were given, its answer empty or mostly on an object placed before it) is
    # asked its latest prompts again in every frame until one is accepted, after every other
    # object is placed (its click may lie on one of them): never dropped for good
    for obj_id in started if RETRY_UNANSWERED else ():
        if (obj_id not in prompted and prompts.get(obj_id) is not None
                and (obj_id not in tracks or tracks[obj_id].template is None)):
            latest = latest_prompts(prompts[obj_id], index)
            if latest is not None:
                prompt_object(obj_id, latest, "found")
    for obj_id in order:
        states.setdefault(obj_id, "waiting")
    return states

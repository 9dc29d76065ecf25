"""A track that jumped: the object looked for where it was going while a look-alike holds its
id (issue 47, eighth pass; docs/design.md section 10, "Tracking", and section 3.9, "Videos").

The search (:func:`lfsam.video.tracking.search.search_object`) accepts a match when enough of the
template looks the same there and the answer passes appearance, motion and depth checks one
frame at a time. A mostly hidden object's match can then slide onto a look-alike (another,
unclicked object or background of its colours): the accepted answer lies far from where the
object should be *and* at another depth, the template is replaced by the look-alike's look,
and from then on the look-alike is followed with nearly all of its template supported (fresh
seeds 1302 and 1303: 92-95 % of the template supported, IoU 0 in every view, while the object
itself showed 107-492 pixels). Neither signal alone tells a look-alike from a real turn or
depth swing (on 66 videos of the generator, jitter 0 and 1, 9.8 % of the right answers lie
beyond 0.6 of the search radius and 16.4 % change disparity by more than 0.6 px; 1.6 % both,
against every onset of a look-alike), so a jump does not refuse the answer: it raises a
*doubt*.

* :func:`jumped`: the accepted answer lies more than :data:`JUMP_SHARE` of the search radius
  from the prediction and its median disparity more than :data:`DEPTH_JUMP` pixels from the
  track's last disparity (motion and depth both inconsistent with the track's history; once
  a velocity is measured, after two sightings), or it lies that far from the prediction on a
  poorly supported match (:data:`POORLY_SUPPORTED`: under
  :data:`lfsam.video.tracking.motion.VELOCITY_SUPPORT` of the template; a sliver that fits the
  template at a range of shifts, whose place is no measure of the motion), or its median
  disparity alone lies beyond
  the depth gate's tolerance (:func:`lfsam.video.tracking.search.predicted_disparity`: the gate
  reads such pixels as not the object; a sliver of background answered under jitter set a track's
  depth 2.9 px away, and the object, back at its own depth, was refused for good).
* :func:`doubt`: the track before the jump is kept as its *shadow* (template, motion,
  disparity of the object as it was last trusted).
* :func:`look_again`: every frame, after every object is placed, each shadow is searched for
  as a hidden object is (its predicted place first, then the ring, the widening and the whole
  view; the look-alike and every other placed object excluded), with the usual acceptance
  (found again after hidden frames: appearance, motion and depth). Found, the shadow takes
  the object's id back and the look-alike's answer is dropped: the candidate consistent with
  the track's history is preferred. A shadow not found for :data:`DOUBT_FRAMES` frames is
  forgotten (the jump was a real turn, or the object is gone).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from lfsam.prompts import ObjectPrompts
from lfsam.video.tracking import motion
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.motion import (
    Track,
    predicted,
    predicted_disparity,
    search_radius,
    update,
)

__all__ = ["CHECK", "DEPTH_JUMP", "DOUBT_FRAMES", "JUMP_SHARE", "POORLY_SUPPORTED", "doubt",
           "jumped", "look_again"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.consistency_check`.
CHECK = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.jump_share`.
JUMP_SHARE = 0.6
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.depth_jump`.
DEPTH_JUMP = 0.6
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.poorly_supported`.
POORLY_SUPPORTED = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.doubt_frames`.
DOUBT_FRAMES = 5
#: The shadow is prompted under this id plus the object's (never a user's id), so that the
#: object's own answer stays in the frame until the shadow is accepted.
SHADOW_ID = 1_000_000


def jumped(track: Track, view: tuple[int, int], located: Template, disparity: float,
           center: tuple[int, int]) -> bool:
    """Whether an answer accepted for ``track`` (before :func:`lfsam.video.tracking.motion.update`;
    ``located``: its template where it was found in ``view``, ``disparity``: its median
    disparity) jumped: beyond :data:`JUMP_SHARE` of the search radius from the prediction and
    beyond :data:`DEPTH_JUMP` from the track's disparity or on a poorly supported match
    (:data:`POORLY_SUPPORTED`; ``track.support``, set by the search for this answer)."""
    if track.template is None or track.sightings < 1:
        return False
    expected, tolerance = predicted_disparity(track)
    if abs(disparity - expected) > tolerance:
        return True  # beyond the depth gate: its pixels there are not the object's
    if track.sightings < 2:
        return False  # no velocity measured yet: the prediction is the last place
    place = predicted(track, view, center).origin
    far = float(np.hypot(located.origin[0] - place[0], located.origin[1] - place[1]))
    poor = POORLY_SUPPORTED and track.support < motion.VELOCITY_SUPPORT
    return (far > JUMP_SHARE * search_radius(track)
            and (poor or abs(disparity - track.disparity) > DEPTH_JUMP))


def doubt(track: Track) -> None:
    """Keep ``track`` as it is (before the jump is taken) as its own shadow; an older shadow
    stays (it was trusted longer)."""
    if track.shadow is None:
        track.shadow = replace(track, history=[], shadow=None)


def look_again(obj_id: int, tracks: dict[int, Track], search: Callable[..., tuple | None],
               predictor: object, last_prompts: Callable[[], ObjectPrompts | None],
               disparity: Callable[[tuple[int, int], np.ndarray], float],
               image: Callable[[tuple[int, int]], np.ndarray],
               center: tuple[int, int]) -> tuple[tuple[int, int], np.ndarray] | None:
    """Search for ``obj_id``'s shadow (module docstring) in this frame; where found it takes
    the id back: the predictor's object is set to the shadow's accepted prompts,
    ``tracks[obj_id]`` becomes the updated shadow, and its view and mask are returned.

    ``search(shadow_id, shadow)`` runs :func:`lfsam.video.tracking.search.search_object` for the
    shadow in the frame (everything placed so far excluded); ``last_prompts()`` gives the
    prompts of its last answer; ``disparity(view, mask)`` an answer's median disparity."""
    track = tracks[obj_id]
    shadow = track.shadow
    if shadow is None:
        return None
    shadow_id = SHADOW_ID + obj_id
    found = search(shadow_id, shadow)
    prompts = last_prompts()
    if shadow_id in predictor.object_ids:
        predictor.remove_object(shadow_id)
    if found is None or prompts is None:
        shadow.unseen += 1
        shadow.lost = True
        if shadow.unseen > DOUBT_FRAMES:
            track.shadow = None
        return None
    view, mask, shift, located = found
    predictor.set_object(ObjectPrompts(obj_id, prompts.points, prompts.box))
    update(shadow, view, mask, located, image(view), disparity(view, mask), center,
           shift is not None)
    tracks[obj_id] = shadow
    return view, mask

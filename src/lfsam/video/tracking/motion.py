"""What is known of a tracked object, and where it should be this frame (issue 47;
docs/design.md section 10, "Tracking", step 1).

A :class:`Track` keeps an object's last appearance (its template), motion, disparity and
bookkeeping between frames, also while it is hidden. The prediction places the template where
the object should be in a view: constant velocity in center-view pixels from its last
sightings, and its disparity changing at its last rate, parallax included (a pixel of the
center view at disparity ``d`` is at ``p - d (s - s_c, t - t_c)`` in view ``(s, t)``, section
1). How far from there it is looked for (:func:`search_radius`), and how far its depth may
have moved (:func:`predicted_disparity`), grow while it is unseen. Where the object is found
:func:`update` moves the track to the answer: its velocity (by the match's support, at most
:data:`VELOCITY_SUPPORT`'s share), disparity, and template (replaced by an answer of at least
:data:`KEEP_TEMPLATE` of its largest area, else moved to where it was found).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from lfsam.video.tracking.carry import Template

__all__ = [
    "BASE_RADIUS",
    "DISPARITY_FRAMES",
    "DISPARITY_TOLERANCE",
    "GROWTH",
    "KEEP_TEMPLATE",
    "NEAR_REACH",
    "STATES",
    "VELOCITY_SUPPORT",
    "Track",
    "near_reach",
    "predicted",
    "predicted_disparity",
    "search_radius",
    "update",
    "view_offset",
]

#: An object's state in a frame: prompted there by the user, carried from the frame before,
#: found again after frames hidden, not found (kept, searched again), or not started yet.
STATES = ("prompted", "tracked", "found", "hidden", "waiting")
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.base_radius`.
BASE_RADIUS = 8
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.radius_growth`.
GROWTH = 8
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.near_reach`.
NEAR_REACH = 4
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.disparity_tolerance`.
DISPARITY_TOLERANCE = 1.2
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.disparity_frames`.
DISPARITY_FRAMES = 2
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.keep_template`.
KEEP_TEMPLATE = 0.6
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.velocity_support`.
VELOCITY_SUPPORT = 0.3


@dataclass
class Track:
    """What is known of one object after the latest frame (docs/design.md section 10)."""

    view: tuple[int, int]
    template: Template | None = None
    lost: bool = False
    #: Center-view pixels per frame (rows, columns).
    velocity: tuple[float, float] = (0.0, 0.0)
    disparity: float = 0.0
    disparity_rate: float = 0.0
    #: Frames since it was last found (0: found in the latest frame).
    unseen: int = 0
    #: Largest reference-view area seen.
    area: int = 0
    sightings: int = 0
    #: Share of the template supported by the match of its latest sighting.
    support: float = 1.0
    state: str = "waiting"
    history: list[str] = field(default_factory=list)
    #: The track before a jump, searched for while it is doubted (:mod:`.consistency`).
    shadow: Track | None = None


def search_radius(track: Track) -> int:
    """How far from its predicted place an object is looked for: grows while it is unseen."""
    speed = float(np.hypot(*track.velocity))
    return int(BASE_RADIUS + 2 * speed + GROWTH * track.unseen)


def near_reach(track: Track) -> int:
    """How far from the prediction every shift's support is counted
    (:func:`lfsam.video.tracking.search.near_support`)."""
    return int(min(NEAR_REACH + 2 * track.unseen, 2 * NEAR_REACH))


def view_offset(view: tuple[int, int], center: tuple[int, int]) -> np.ndarray:
    """``(s - s_c, t - t_c)``: the view's step from the center, which a disparity scales into
    its shift (section 1)."""
    return np.array([view[0] - center[0], view[1] - center[1]], np.float64)


def predicted(track: Track, view: tuple[int, int], center: tuple[int, int]) -> Template:
    """The object's template placed where it should be in ``view`` this frame."""
    steps = track.unseen + 1
    origin = np.asarray(track.template.origin, np.float64)
    now = track.disparity + track.disparity_rate * steps
    place = (origin + track.disparity * view_offset(track.view, center)
             + np.asarray(track.velocity) * steps - now * view_offset(view, center))
    return replace(track.template, origin=(round(place[0]), round(place[1])))


def predicted_disparity(track: Track) -> tuple[float, float]:
    """The disparity the object's pixels are expected at this frame and the tolerance
    around it: its last disparity (moving it at its last rate lost more objects on the
    development videos, whose depth swings back and forth), :data:`DISPARITY_TOLERANCE` for
    each frame since it was seen, at most :data:`DISPARITY_FRAMES` frames' worth (depth
    swings are bounded: a gate that opened without end would let a hidden object be found on
    a background of its colours)."""
    return track.disparity, DISPARITY_TOLERANCE * min(track.unseen + 1, DISPARITY_FRAMES)


def update(track: Track, view: tuple[int, int], mask: np.ndarray, located: Template,
           image: np.ndarray, disparity: float, center: tuple[int, int],
           moved: bool = True) -> None:
    """The track after the object was found in ``view`` (``located``: its template where it
    was found; ``disparity``: the answer's median disparity; ``moved`` False: the place is
    the prediction's, not a measure, and the velocity is kept)."""
    steps = track.unseen + 1
    before = (np.asarray(track.template.origin, np.float64)
              + track.disparity * view_offset(track.view, center))
    now = np.asarray(located.origin, np.float64) + disparity * view_offset(view, center)
    measured = (now - before) / steps
    if track.sightings >= 1 and moved:
        # a poorly supported match moves the velocity only by its share (VELOCITY_SUPPORT)
        weight = 1.0 if track.sightings < 2 else min(1.0, track.support / VELOCITY_SUPPORT)
        blended = np.asarray(track.velocity) + weight * (measured - np.asarray(track.velocity))
        track.velocity = (float(blended[0]), float(blended[1]))
        track.disparity_rate = (disparity - track.disparity) / steps
    area = int(mask.sum())
    # mostly hidden: the fuller look is kept, moved to where it was found
    track.template = (Template.from_mask(image, mask)
                      if area >= KEEP_TEMPLATE * track.area or track.template is None
                      else located)
    track.view = view
    track.disparity = disparity
    track.area = max(track.area, area)
    track.state = "found" if track.unseen > 0 else "tracked"
    track.unseen = 0
    track.lost = False
    track.sightings += 1

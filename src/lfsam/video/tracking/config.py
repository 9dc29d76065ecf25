"""The tracker's rules in one place (issue 67; docs/design.md section 10, "The tracker's
rules"): :class:`TrackerConfig`, a frozen dataclass holding every rule of the search and of its
checks with its meaning, its default and the case that motivated it.

Each field is a module constant of :mod:`lfsam.video.tracking` (:data:`SOURCES`: the field
``depth_gate`` is ``rules.DEPTH_GATE``, ``contest_check`` is ``contest.CHECK``, ...), which the
tracker reads when it runs. The field's docstring is the rule's one description: the constant
points to it, and docs/design.md section 10's table repeats it (a test keeps that table's
fields and defaults those of the dataclass). ``TrackerConfig()`` holds today's values (the
tests check that each default is its constant's), so tracking with it is tracking as before,
byte for byte.
:meth:`TrackerConfig.applied` sets a configuration for the tracking inside a ``with`` block and
restores the constants after it; :meth:`TrackerConfig.without` turns rules off by name (every
boolean field is a rule's off switch, :func:`switches`)::

    from lfsam.video.tracking.config import TrackerConfig

    with TrackerConfig().without("depth_gate", "contest_check").applied():
        track_video(video, prompts, segmenter)

The constants are the process's: one configuration applies at a time. ``applied`` holds a
process-wide lock for its block, so two threads that each track inside ``applied()`` take turns
instead of mixing their rules; a thread tracking outside any ``applied()`` block meanwhile sees
the configuration applied.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from types import ModuleType

__all__ = ["SOURCES", "TrackerConfig", "switches"]

#: Held while a configuration is applied (:meth:`TrackerConfig.applied`).
_APPLIED = threading.RLock()

#: Each field's module (in :mod:`lfsam.video.tracking`) and constant.
SOURCES: dict[str, tuple[str, str]] = {
    "max_growth": ("rules", "MAX_GROWTH"),
    "candidates": ("rules", "CANDIDATES"),
    "near_support": ("rules", "NEAR_SUPPORT"),
    "far_support": ("rules", "FAR_SUPPORT"),
    "sure": ("rules", "SURE"),
    "rescored": ("rules", "RESCORED"),
    "min_alike": ("rules", "MIN_ALIKE"),
    "known_part": ("rules", "KNOWN_PART"),
    "known_support": ("rules", "KNOWN_SUPPORT"),
    "depth_gate": ("rules", "DEPTH_GATE"),
    "explained": ("rules", "EXPLAINED"),
    "almost": ("rules", "ALMOST"),
    "uncovered": ("rules", "UNCOVERED"),
    "uncovered_view": ("rules", "UNCOVERED_VIEW"),
    "wide_candidates": ("rules", "WIDE_CANDIDATES"),
    "wide_views": ("rules", "WIDE_VIEWS"),
    "wide_support": ("rules", "WIDE_SUPPORT"),
    "placed_support": ("rules", "PLACED_SUPPORT"),
    "refused_again": ("rules", "REFUSED_AGAIN"),
    "small_answer": ("rules", "SMALL_ANSWER"),
    "small_share": ("rules", "SMALL_SHARE"),
    "held": ("rules", "HELD"),
    "wide_refused": ("rules", "WIDE_REFUSED"),
    "base_radius": ("motion", "BASE_RADIUS"),
    "radius_growth": ("motion", "GROWTH"),
    "near_reach": ("motion", "NEAR_REACH"),
    "disparity_tolerance": ("motion", "DISPARITY_TOLERANCE"),
    "disparity_frames": ("motion", "DISPARITY_FRAMES"),
    "keep_template": ("motion", "KEEP_TEMPLATE"),
    "velocity_support": ("motion", "VELOCITY_SUPPORT"),
    "retry_unanswered": ("frame_search", "RETRY_UNANSWERED"),
    "placement_check": ("placement", "CHECK"),
    "placement_farther": ("placement", "FARTHER"),
    "placement_inside": ("placement", "INSIDE"),
    "placement_candidates": ("placement", "CANDIDATES"),
    "placement_explained": ("placement", "EXPLAINED"),
    "union_check": ("union", "CHECK"),
    "union_growth": ("union", "GROWTH"),
    "union_supported": ("union", "SUPPORTED"),
    "neighbour_ask": ("neighbour", "ASK"),
    "neighbour_agree": ("neighbour", "AGREE"),
    "contest_check": ("contest", "CHECK"),
    "contest_held": ("contest", "HELD"),
    "contest_kept": ("contest", "KEPT"),
    "claims_check": ("claims", "CHECK"),
    "rival_margin": ("claims", "RIVAL_MARGIN"),
    "claims_grown": ("claims", "GROWN"),
    "consistency_check": ("consistency", "CHECK"),
    "jump_share": ("consistency", "JUMP_SHARE"),
    "depth_jump": ("consistency", "DEPTH_JUMP"),
    "poorly_supported": ("consistency", "POORLY_SUPPORTED"),
    "doubt_frames": ("consistency", "DOUBT_FRAMES"),
}


@dataclass(frozen=True)
class TrackerConfig:
    """The tracker's rules (module docstring). The boolean fields switch a rule on or off; the
    others are a rule's setting."""

    # --- the search (design.md section 10, Tracking, steps 1-5): rules.py ------------------------
    max_growth: float = 4.0
    """An answer more than this many times larger than the object's largest area is rejected.
    Default ``4.0`` (``rules.MAX_GROWTH``)."""
    candidates: int = 12
    """Cheapest template shifts whose support is compared. Default ``12`` (``rules.CANDIDATES``)."""
    near_support: float = 0.1
    """Fraction of the template that must still look the same near the prediction / elsewhere.
    Default ``0.1`` (``rules.NEAR_SUPPORT``)."""
    far_support: float = 0.3
    """Set with the rule above (:attr:`near_support`), whose description covers both. Default
    ``0.3`` (``rules.FAR_SUPPORT``)."""
    sure: float = 0.6
    """A match showing this fraction of the template is not searched further near the prediction.
    Default ``0.6`` (``rules.SURE``)."""
    rescored: int = 2
    """Views of the ring (ranked by their SSD match) where every shift near the prediction is
    scored too before prompting. Default ``2`` (``rules.RESCORED``)."""
    min_alike: float = 0.35
    """Colour histogram intersection an answer away from the prediction needs. Default ``0.35``
    (``rules.MIN_ALIKE``)."""
    known_part: bool = True
    """An answer holding :data:`KNOWN_SUPPORT` of the support may look unlike the template as a
    whole where its part inside the carried template looks like it (an object showing a part
    its template never held; issue 47 fifteenth pass). Default ``True`` (``rules.KNOWN_PART``)."""
    known_support: float = 0.9
    """Set with the rule above (:attr:`known_part`), whose description covers both. Default
    ``0.9`` (``rules.KNOWN_SUPPORT``)."""
    depth_gate: bool = True
    """Whether :func:`lfsam.video.tracking.frame_search.search_frame` gates the match by depth
    (:func:`search_object`'s ``disparities``). On since the object's disparity is the median
    over its answer (:func:`lfsam.video.tracking.frame_search.object_disparity`): with the
    mean, an answer spilling a pixel onto the background (the oracle's jitter) pulled a small
    object's disparity towards the background's, and the gate refused the object's own pixels
    (development seeds 7-12, jitter 1: 5.49 % of the visible triples lost with the mean and the
    gate, 3.74 % without the gate, 3.49 % with the median and the gate). Default ``True``
    (``rules.DEPTH_GATE``)."""
    explained: float = 0.5
    """An answer whose support lies mostly beside it (look-alike pixels around a partly hidden
    object) is still the object where, at a shift within the search radius, the template shows
    this fraction of the answer's pixels (:func:`explaining_shift`). Default ``0.5``
    (``rules.EXPLAINED``)."""
    almost: float = 0.9
    """Of the shifts explaining an answer this nearly as well as the best, the nearest to the
    prediction is taken. Default ``0.9`` (``rules.ALMOST``)."""
    uncovered: bool = True
    """An answer grown past :data:`MAX_GROWTH` (an object first seen mostly covered, then
    uncovered) is accepted where it holds 90 % of the support, is at most this share of the
    view and lies at the object's depth (:func:`~lfsam.video.tracking.answer.accept_answer`).
    Default ``True`` (``rules.UNCOVERED``)."""
    uncovered_view: float = 0.25
    """Set with the rule above (:attr:`uncovered`), whose description covers both. Default
    ``0.25`` (``rules.UNCOVERED_VIEW``)."""
    wide_candidates: int = 150
    """The widening stage (:func:`search_object`, stage 3): where the prediction missed, the
    shifts within the search radius where most of the template's pixels could be the object
    (:func:`lfsam.video.tracking.match.likely_shifts_many`), at most this many scored exactly
    per view; the :data:`WIDE_VIEWS` views whose best shift shows most of the template
    prompted, each needing :data:`WIDE_SUPPORT` of the template's part inside the frame
    supported and the answer at the object's depth. Default ``150``
    (``rules.WIDE_CANDIDATES``)."""
    wide_views: int = 2
    """Set with the rule above (:attr:`wide_candidates`), whose description covers both. Default
    ``2`` (``rules.WIDE_VIEWS``)."""
    wide_support: float = 0.15
    """Set with the rule above (:attr:`wide_candidates`), whose description covers both. Default
    ``0.15`` (``rules.WIDE_SUPPORT``)."""
    placed_support: bool = True
    """In the views of the ring, the support needed near the prediction leaves out the template's
    pixels that an object placed earlier in the frame covers: they cannot show the object
    (sixteenth pass; fresh seed 2701: an object of 1451 pixels, 91 % behind a tracked one,
    showed 115-141 pixels a view and was supported on 76-119 of them, 145 needed; hidden for a
    frame, 25 lost triples). In its own view the whole template counts (seed 903 at jitter 1
    lost 27 triples more with it there). Default
    ``True`` (``rules.PLACED_SUPPORT``)."""
    refused_again: bool = True
    """Where the answers at the predicted place in the object's own view are refused and the ring
    finds nothing, that view is matched once more with the refused answers' pixels counted as
    not the object (every shift near the prediction scored): a mostly covered object beside a
    background of its own colours had its match, and so its prompts, on that background (seed
    802: hidden for its last three frames while it showed 127-174 pixels in the center view).
    After the ring: before it, the rematch took a poor answer in its own view where an outer
    view saw the object whole (seed 1101, 5 triples). Default ``True``
    (``rules.REFUSED_AGAIN``)."""
    small_answer: bool = True
    """An answer accepted in the object's own view that covers under :data:`SMALL_SHARE` of its
    match's support there is held back while the ring's views are tried (the view where the
    match shows most first), and given back where none of them is accepted. A thin object
    mostly hidden in its own view, its answer there eroded by a segmenter's boundary error to a
    sliver (fresh seed 1401 under the oracle's jitter: 9 pixels of the 42 it showed, from a
    support of 32), set every view's refinement prompts (their boxes cut from it), while a
    corner view showed all 118 of its pixels. Exact answers cover their support (no answer
    changed without jitter on 87 videos); with jitter 1, 53 fewer lost triples (docs/
    performance.md, issue 47 seventeenth pass; at 0.5 a ring view's answer lost seed 1301's
    object two frames later, 38 more). Default ``True`` (``rules.SMALL_ANSWER``)."""
    small_share: float = 0.3
    """Set with the rule above (:attr:`small_answer`), whose description covers both. Default
    ``0.3`` (``rules.SMALL_SHARE``)."""
    held: float = 0.5
    """An answer found again (the object unseen for frames) that holds this share of an object
    placed earlier in the frame, in the answer's view, is that object (its mask carried there,
    then as the segmenter answers it there, :mod:`lfsam.video.tracking.neighbour`; fresh seed
    1802's disc took a neighbour's place, docs/design.md section 10 "Tracking" step 5). Default
    ``0.5`` (``rules.HELD``)."""
    wide_refused: bool = True
    """The widening stage reads the answers refused in a view this frame (the object's own view
    and the ring's) as not the object, as it reads the objects placed (fresh seed 1801: every
    match of a hidden object on a background of its colours; docs/design.md section 10).
    Default ``True`` (``rules.WIDE_REFUSED``)."""
    # --- the prediction: motion.py ---------------------------------------------------------------
    base_radius: int = 8
    """Search radius (pixels): base, plus the speed, plus this much per frame unseen. Default
    ``8`` (``motion.BASE_RADIUS``)."""
    radius_growth: int = 8
    """Set with the rule above (:attr:`base_radius`), whose description covers both. Default ``8``
    (``motion.GROWTH``)."""
    near_reach: int = 4
    """Every shift this close to the prediction (plus 2 pixels per frame unseen) is scored.
    Default ``4`` (``motion.NEAR_REACH``)."""
    disparity_tolerance: float = 1.2
    """Disparity difference (pixels) from the object's last disparity, per frame since it was
    seen, beyond which a pixel is not the object whatever its colour: the light field tells an
    object from a background of the same colours by its depth (objects change depth by up to
    about a pixel of disparity per frame). Default ``1.2`` (``motion.DISPARITY_TOLERANCE``)."""
    disparity_frames: int = 2
    """The disparity tolerance grows with the frames unseen up to this many frames' worth. Default
    ``2`` (``motion.DISPARITY_FRAMES``)."""
    keep_template: float = 0.6
    """A template is replaced by an answer at least this fraction of the object's largest area.
    Default ``0.6`` (``motion.KEEP_TEMPLATE``)."""
    velocity_support: float = 0.3
    """A match supporting less of its template moves the velocity only by its share of this.
    Default ``0.3`` (``motion.VELOCITY_SUPPORT``)."""
    # --- the frame's order: frame_search.py ------------------------------------------------------
    retry_unanswered: bool = True
    """An object whose prompts were never answered with an accepted mask is asked its latest
    prompts again every frame (:func:`search_frame`), after every other object is placed.
    Default ``True`` (``frame_search.RETRY_UNANSWERED``)."""
    # --- the placed answer: placement.py ---------------------------------------------------------
    placement_check: bool = True
    """Place partly seen objects by their answers (off: by their template's match alone). Default
    ``True`` (``placement.CHECK``)."""
    placement_farther: float = 0.5
    """A view pixel at least this much farther (disparity pixels) than the object, outside the
    answer, contradicts the template lying on it. Default ``0.5`` (``placement.FARTHER``)."""
    placement_inside: float = 0.6
    """The template's share inside the frame below which its place stands (as
    :data:`lfsam.video.tracking.rules.SURE`'s cut objects). Default ``0.6``
    (``placement.INSIDE``)."""
    placement_candidates: int = 12
    """Shifts ranked by where the template lies that are also scored by its look. Default ``12``
    (``placement.CANDIDATES``)."""
    placement_explained: float = 0.5
    """The answer's share the chosen place must explain (its look the same there). Default ``0.5``
    (``placement.EXPLAINED``)."""
    # --- several clicks' answer: union.py --------------------------------------------------------
    union_check: bool = True
    """Whether an answer to several clicks larger than the object ever was is split by click.
    Default ``True`` (``union.CHECK``)."""
    union_growth: float = 1.2
    """An answer more than this many times the object's largest area is suspect. Default ``1.2``
    (``union.GROWTH``)."""
    union_supported: float = 0.5
    """A click is the object's where at least this share of its answer lies on the support.
    Default ``0.5`` (``union.SUPPORTED``)."""
    # --- the neighbour asked: neighbour.py -------------------------------------------------------
    neighbour_ask: bool = True
    """Whether a placed object is asked in the view of a found-again answer that meets it. Default
    ``True`` (``neighbour.ASK``)."""
    neighbour_agree: float = 0.3
    """A carried pixel shows the placed object in the view where the view's disparity there lies
    within this many pixels of the object's (its median disparity where it was placed). Default
    ``0.3`` (``neighbour.AGREE``)."""
    # --- the contest: contest.py -----------------------------------------------------------------
    contest_check: bool = True
    """Whether an object refused for an answer placed earlier contests it. Default ``True``
    (``contest.CHECK``)."""
    contest_held: float = 0.5
    """An answer is held by a placed object where that object's mask covers more than this share
    of it (the share at which :func:`lfsam.video.tracking.answer.accept_answer` refuses it as
    placed). Default ``0.5`` (``contest.HELD``)."""
    contest_kept: float = 0.9
    """A placed object gives the contested part up where its new answer lies at least this much
    inside its old one (and keeps more than :data:`HELD` of the old one outside the contested
    part: the contested answer, carried from another view, covers that part only roughly).
    Default ``0.9`` (``contest.KEPT``)."""
    # --- the claims of hidden objects: claims.py -------------------------------------------------
    claims_check: bool = True
    """Whether an answer found again is checked against the other hidden objects (:func:`rival`).
    Default ``True`` (``claims.CHECK``)."""
    rival_margin: float = 0.1
    """A rival takes the answer where it explains this much more of it (a share of the answer's
    pixels, :func:`explained`) than the object that found it: a clearly better explanation.
    Default ``0.1`` (``claims.RIVAL_MARGIN``)."""
    claims_grown: float = 1.5
    """An answer larger than this many times the object's largest area is checked against every
    object still to be searched, tracked ones too (``rival(hidden_only=False)``): an answer
    that also covers a neighbour (the oracle's jitter, seed 1801) would take its pixels.
    Default ``1.5`` (``claims.GROWN``)."""
    # --- doubts and shadows: consistency.py ------------------------------------------------------
    consistency_check: bool = True
    """Whether the tracker raises doubts and searches for shadows (:func:`look_again`). Default
    ``True`` (``consistency.CHECK``)."""
    jump_share: float = 0.6
    """An accepted answer farther than this share of
    :func:`lfsam.video.tracking.search.search_radius` from the predicted place is a jump in
    position (with :data:`DEPTH_JUMP`, a doubt). Default ``0.6`` (``consistency.JUMP_SHARE``)."""
    depth_jump: float = 0.6
    """An accepted answer whose median disparity is farther than this (pixels) from the track's
    last disparity is a jump in depth (with :data:`JUMP_SHARE`, a doubt). Default ``0.6``
    (``consistency.DEPTH_JUMP``)."""
    poorly_supported: bool = True
    """An accepted answer farther than :data:`JUMP_SHARE` of the search radius from the prediction
    on a match supporting under :data:`lfsam.video.tracking.motion.VELOCITY_SUPPORT` of the
    template is a jump whatever its depth (fourteenth pass): seed 401, an object behind an
    occluder showing 97 pixels in a corner view, matched there on 81 of its 485 carried pixels
    16 px from the prediction at the object's depth; its velocity jumped from (0.4, -4.8) to
    (9.6, -14.3) px a frame and it was lost the next frame, where the shadow (the track before
    the jump) is found. Default ``True`` (``consistency.POORLY_SUPPORTED``)."""
    doubt_frames: int = 5
    """A shadow not found for this many frames is forgotten: searched in the ``DOUBT_FRAMES + 1``
    frames after the jump, so an object hidden for up to 5 frames (issue 47's target) is still
    looked for in the first frame it shows again. Was 6 (a frame more than the target needs); 5
    gave the same lost triples, switches and returns on the 16 sets and three fresh ones at
    jitter 0 and 1, and cut the search's cost by a sixth (thirteenth pass); 3 lost seed 1303's
    object for good (40 triples). Default ``5`` (``consistency.DOUBT_FRAMES``)."""

    @classmethod
    def current(cls) -> TrackerConfig:
        """The configuration the tracker runs with now (the constants' values)."""
        return cls(**{name: getattr(_module(mod), const) for name, (mod, const) in SOURCES.items()})

    def without(self, *rules: str) -> TrackerConfig:
        """This configuration with the rules ``rules`` (names of boolean fields) turned off.

        Raises
        ------
        ValueError
            A name that is not a rule's switch (the valid ones listed).
        """
        unknown = sorted(set(rules) - set(switches()))
        if unknown:
            raise ValueError(f"not a rule's switch: {', '.join(unknown)}; "
                             f"valid: {', '.join(switches())}")
        return dataclasses.replace(self, **dict.fromkeys(rules, False))

    @contextlib.contextmanager
    def applied(self) -> Iterator[TrackerConfig]:
        """Track with this configuration inside the ``with`` block: each field's constant set to
        its value, and every constant restored afterwards (also on an error). One block at a
        time in the process: another thread's ``applied()`` waits for this one to end."""
        with _APPLIED:
            saved = {name: getattr(_module(mod), const) for name, (mod, const) in SOURCES.items()}
            try:
                for name, (mod, const) in SOURCES.items():
                    setattr(_module(mod), const, getattr(self, name))
                yield self
            finally:
                for name, (mod, const) in SOURCES.items():
                    setattr(_module(mod), const, saved[name])


def switches() -> tuple[str, ...]:
    """The rules' off switches: the names of :class:`TrackerConfig`'s boolean fields."""
    return tuple(f.name for f in dataclasses.fields(TrackerConfig) if f.type == "bool")


def _module(name: str) -> ModuleType:
    return importlib.import_module(f"lfsam.video.tracking.{name}")

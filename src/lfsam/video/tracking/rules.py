"""The rules of the tracker's search (issue 47; docs/design.md section 10, "Tracking"): each
setting and each switch of :func:`lfsam.video.tracking.search.search_object`, the acceptance of
its answers (:mod:`lfsam.video.tracking.answer`) and the depth gate of
:func:`lfsam.video.tracking.frame_search.search_frame`. What each decides, its default and the
case that motivated it are written once, in :class:`lfsam.video.tracking.config.TrackerConfig`
(issue 67); each constant here points to its field.

They are read at call time as ``rules.NAME``, so a test or a benchmark switches one off with
``monkeypatch.setattr(rules, "NAME", False)``. The checks that live in a module of their own keep
their switch there (``CHECK`` of :mod:`~lfsam.video.tracking.contest`,
:mod:`~lfsam.video.tracking.union` and :mod:`~lfsam.video.tracking.placement`, ``ASK`` of
:mod:`~lfsam.video.tracking.neighbour`, ``POORLY_SUPPORTED`` of
:mod:`~lfsam.video.tracking.consistency`, ``RETRY_UNANSWERED`` of
:mod:`~lfsam.video.tracking.frame_search`).
"""

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.max_growth`.
MAX_GROWTH = 4.0
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.candidates`.
CANDIDATES = 12
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.near_support`.
NEAR_SUPPORT = 0.1
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.far_support`.
FAR_SUPPORT = 0.3
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.sure`.
SURE = 0.6
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.rescored`.
RESCORED = 2
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.min_alike`.
MIN_ALIKE = 0.35
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.known_part`.
KNOWN_PART = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.known_support`.
KNOWN_SUPPORT = 0.9
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.depth_gate`.
DEPTH_GATE = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.explained`.
EXPLAINED = 0.5
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.almost`.
ALMOST = 0.9
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.uncovered`.
UNCOVERED = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.uncovered_view`.
UNCOVERED_VIEW = 0.25
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.wide_candidates`.
WIDE_CANDIDATES = 150
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.wide_views`.
WIDE_VIEWS = 2
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.wide_support`.
WIDE_SUPPORT = 0.15
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placed_support`.
PLACED_SUPPORT = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.refused_again`.
REFUSED_AGAIN = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.small_answer`.
SMALL_ANSWER = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.small_share`.
SMALL_SHARE = 0.3
#: What a refused answer's pixels read as when the view is matched again: far from any
#: colour (every channel 255 below black), so they support no template.
REFUSED_VALUE = -255.0
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.held`.
HELD = 0.5
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.wide_refused`.
WIDE_REFUSED = True

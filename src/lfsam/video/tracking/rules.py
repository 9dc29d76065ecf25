"""The rules of the tracker's search (issue 47; docs/design.md section 10, "Tracking"): each
setting and each switch of :func:`lfsam.video.tracking.search.search_object`, the acceptance of
its answers (:mod:`lfsam.video.tracking.answer`) and the depth gate of
:func:`lfsam.video.tracking.frame_search.search_frame`, with the case that motivated it.

They are read at call time as ``rules.NAME``, so a test or a benchmark switches one off with
``monkeypatch.setattr(rules, "NAME", False)``. The checks that live in a module of their own keep
their switch there (``CHECK`` of :mod:`~lfsam.video.tracking.contest`,
:mod:`~lfsam.video.tracking.union` and :mod:`~lfsam.video.tracking.placement`, ``ASK`` of
:mod:`~lfsam.video.tracking.neighbour`, ``POORLY_SUPPORTED`` of
:mod:`~lfsam.video.tracking.consistency`, ``RETRY_UNANSWERED`` of
:mod:`~lfsam.video.tracking.frame_search`).
"""

#: An answer more than this many times larger than the object's largest area is rejected.
MAX_GROWTH = 4.0
#: Cheapest template shifts whose support is compared.
CANDIDATES = 12
#: Fraction of the template that must still look the same near the prediction / elsewhere.
NEAR_SUPPORT = 0.1
FAR_SUPPORT = 0.3
#: A match showing this fraction of the template is not searched further near the prediction.
SURE = 0.6
#: Views of the ring (ranked by their SSD match) where every shift near the prediction is
#: scored too before prompting.
RESCORED = 2
#: Colour histogram intersection an answer away from the prediction needs.
MIN_ALIKE = 0.35
#: An answer holding :data:`KNOWN_SUPPORT` of the support may look unlike the template as a
#: whole where its part inside the carried template looks like it (an object showing a part
#: its template never held; issue 47 fifteenth pass).
KNOWN_PART = True
KNOWN_SUPPORT = 0.9
#: Whether :func:`lfsam.video.tracking.frame_search.search_frame` gates the match by depth
#: (:func:`search_object`'s ``disparities``). On since the object's disparity is the median
#: over its answer (:func:`lfsam.video.tracking.frame_search.object_disparity`): with the mean, an
#: answer spilling a pixel onto the background (the oracle's jitter) pulled a small object's
#: disparity towards the background's, and the gate refused the object's own pixels
#: (development seeds 7-12, jitter 1: 5.49 % of the visible triples lost with the mean and
#: the gate, 3.74 % without the gate, 3.49 % with the median and the gate).
DEPTH_GATE = True
#: An answer whose support lies mostly beside it (look-alike pixels around a partly hidden
#: object) is still the object where, at a shift within the search radius, the template
#: shows this fraction of the answer's pixels (:func:`explaining_shift`).
EXPLAINED = 0.5
#: Of the shifts explaining an answer this nearly as well as the best, the nearest to the
#: prediction is taken.
ALMOST = 0.9
#: An answer grown past :data:`MAX_GROWTH` (an object first seen mostly covered, then
#: uncovered) is accepted where it holds 90 % of the support, is at most this share of the
#: view and lies at the object's depth (:func:`~lfsam.video.tracking.answer.accept_answer`).
UNCOVERED = True
UNCOVERED_VIEW = 0.25
#: The widening stage (:func:`search_object`, stage 3): where the prediction missed, the
#: shifts within the search radius where most of the template's pixels could be the object
#: (:func:`lfsam.video.tracking.match.likely_shifts_many`), at most this many scored exactly per
#: view; the :data:`WIDE_VIEWS` views whose best shift shows most of the template prompted,
#: each needing :data:`WIDE_SUPPORT` of the template's part inside the frame supported and
#: the answer at the object's depth.
WIDE_CANDIDATES = 150
WIDE_VIEWS = 2
WIDE_SUPPORT = 0.15
#: In the views of the ring, the support needed near the prediction is a share of the
#: template's interior (its part inside the frame less its border pixels): a template cut
#: from an answer one pixel too wide (the oracle's jitter, a trained SAM's boundary) holds a
#: ring of pixels that were never the object (seed 901: an object mostly covered, 100 of its
#: 1032-pixel template supported in an outer view, 103 needed, was hidden for a frame). In
#: its own view the whole template counts: there a barely supported match is better
#: prompted in a view that sees more of it (seed 1203: two triples lost otherwise).
CORE_SUPPORT = True
#: In the views of the ring, the support needed near the prediction leaves out the
#: template's pixels that an object placed earlier in the frame covers: they cannot show the
#: object (sixteenth pass; fresh seed 2701: an object of 1451 pixels, 91 % behind a tracked
#: one, showed 115-141 pixels a view and was supported on 76-119 of them, 145 needed; hidden
#: for a frame, 25 lost triples). In its own view the whole template counts, as for
#: :data:`CORE_SUPPORT` (seed 903 at jitter 1 lost 27 triples more with it there).
PLACED_SUPPORT = True
#: Where the answers at the predicted place in the object's own view are refused and the
#: ring finds nothing, that view is matched once more with the refused answers' pixels
#: counted as not the object (every shift near the prediction scored): a mostly covered
#: object beside a background of its own colours had its match, and so its prompts, on that
#: background (seed 802: hidden for its last three frames while it showed 127-174 pixels in
#: the center view). After the ring: before it, the rematch took a poor answer in its own
#: view where an outer view saw the object whole (seed 1101, 5 triples).
REFUSED_AGAIN = True
#: An answer accepted in the object's own view that covers under :data:`SMALL_SHARE` of its
#: match's support there is held back while the ring's views are tried (the view where the
#: match shows most first), and given back where none of them is accepted. A thin object
#: mostly hidden in its own view, its answer there eroded by a segmenter's boundary error
#: to a sliver (fresh seed 1401 under the oracle's jitter: 9 pixels of the 42 it showed,
#: from a support of 32), set every view's refinement prompts (their boxes cut from it),
#: while a corner view showed all 118 of its pixels. Exact answers cover their support (no
#: answer changed without jitter on 87 videos); with jitter 1, 53 fewer lost triples (docs/
#: performance.md, issue 47 seventeenth pass; at 0.5 a ring view's answer lost seed 1301's
#: object two frames later, 38 more).
SMALL_ANSWER = True
SMALL_SHARE = 0.3
#: What a refused answer's pixels read as when the view is matched again: far from any
#: colour (every channel 255 below black), so they support no template.
REFUSED_VALUE = -255.0
#: An answer found again (the object unseen for frames) that holds this share of an object
#: placed earlier in the frame, in the answer's view, is that object (its mask carried
#: there, then as the segmenter answers it there, :mod:`lfsam.video.tracking.neighbour`; fresh seed
#: 1802's disc took a neighbour's place, docs/design.md section 10 "Tracking" step 5).
HELD = 0.5
#: The widening stage reads the answers refused in a view this frame (the object's own view
#: and the ring's) as not the object, as it reads the objects placed (fresh seed 1801: every
#: match of a hidden object on a background of its colours; docs/design.md section 10).
WIDE_REFUSED = True

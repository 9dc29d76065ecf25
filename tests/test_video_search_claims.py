"""Competing claims on an answer found again (issue 47, ninth pass; docs/design.md section
10, "Tracking", :mod:`lfsam.video.tracking.claims`): two clicked objects hidden at once, the small
one a look-alike of a part of the other; where the larger one comes out, the small one's search
(first in the frame's order: its template is wholly supported there) accepts it. The larger
object explains the answer better (its whole template against a sixth), so it is searched
first and keeps its id; before, the small one took it and the two ids swapped."""

from __future__ import annotations

import numpy as np

from lfsam.api import RunOptions, SegmentOptions
from lfsam.lightfield import LightField
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.tracking import claims
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.online import OnlineTracker
from lfsam.video.tracking.search import Track

GRID, CENTER, SIZE = (3, 3), (1, 1), (44, 60)
#: The large object (id 2, label 3): 10 x 14 pixels at ROW, its first column per frame
#: (None: hidden), and from which column on it shows (frame 4: its left part still hidden).
ROW, COLUMNS, SHOWS = 20, [2, 5, None, None, 14, 17], {4: 20}
#: The small object (id 1, label 2): the large one's texture at rows 0-5, columns 8-13,
#: still at SMALL in frames 0-1, hidden from frame 2 on.
SMALL, PART = (6, 30), (slice(0, 6), slice(8, 14))
PALETTE = np.array([[200, 40, 40], [40, 200, 40], [230, 230, 60]], np.float64)


def _texture() -> np.ndarray:
    """The large object's look: a few colours, so that a part of it and the whole have alike
    colour histograms (the search's appearance check passes for the small one)."""
    return PALETTE[np.random.default_rng(3).integers(0, len(PALETTE), (10, 14))]


def _frame(index: int) -> LightField:
    """Every view alike (disparity 0): a random background of dark colours, the small object
    in frames 0-1, the large one where :data:`COLUMNS` puts it."""
    background = np.random.default_rng(7).uniform(0, 120, (*SIZE, 3))
    look = _texture()
    image, label = background.copy(), np.ones(SIZE, np.int32)
    if index < 2:
        image[SMALL[0]:SMALL[0] + 6, SMALL[1]:SMALL[1] + 6] = look[PART]
        label[SMALL[0]:SMALL[0] + 6, SMALL[1]:SMALL[1] + 6] = 2
    if COLUMNS[index] is not None:
        c = COLUMNS[index]
        first = SHOWS.get(index, c) - c
        image[ROW:ROW + 10, c + first:c + 14] = look[:, first:]
        label[ROW:ROW + 10, c + first:c + 14] = 3
    views = np.broadcast_to(np.clip(image, 0, 255).astype(np.uint8), (*GRID, *SIZE, 3))
    labels = np.broadcast_to(label, (*GRID, *SIZE))
    return LightField(views.copy(), np.zeros((*GRID, *SIZE), np.float32), labels.copy())


def _tracked() -> list:
    tracker = OnlineTracker("oracle", disparity="gt",
                            options=SegmentOptions(run=RunOptions(progress=False)))
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(SMALL[1] + 2.0, SMALL[0] + 2.0),)),
                         ObjectPrompts(2, (PointPrompt(COLUMNS[0] + 7.0, ROW + 5.0),))])
    return [(frame, tracker.track(frame)) for frame in map(_frame, range(len(COLUMNS)))]


def test_an_answer_found_again_goes_to_the_hidden_object_that_explains_it_best():
    """Frame 4: the large object comes out (its right part); the small one, hidden too,
    matches its own pixels on that part. The large one takes it under its own id, the small
    one stays hidden; in frame 5 likewise (without the check: id 1 on label 3 from frame 4)."""
    frames = _tracked()
    for frame, result in frames[4:]:
        center = frame.labels[CENTER] == 3
        ours = result.labels[CENTER]
        assert (ours[center] == 2).mean() >= 0.9, result.meta["tracks"]
        assert not (ours == 1).any(), result.meta["tracks"]
    assert frames[4][1].meta["tracks"] == {"1": "hidden", "2": "found"}


def test_explained_counts_the_share_of_the_answer_the_template_covers():
    """:func:`claims.explained`: a template of the answer's own pixels explains all of it at
    its place, a sixth of it explains a sixth; a shift beyond the radius does not count."""
    look = _texture()
    image = np.zeros((*SIZE, 3), np.float32)
    image[ROW:ROW + 10, 10:24] = look
    mask = np.zeros(SIZE, bool)
    mask[ROW:ROW + 10, 10:24] = True
    whole = Track(CENTER, Template(look.astype(np.float32), np.ones((10, 14), bool),
                                   (ROW, 10)), sightings=2)
    part = Track(CENTER, Template(look[PART].astype(np.float32), np.ones((6, 6), bool),
                                  (ROW, 18)), sightings=2)
    assert claims.explained(whole, CENTER, mask, image, CENTER, 3) == 1.0
    assert abs(claims.explained(part, CENTER, mask, image, CENTER, 3) - 36 / 140) < 1e-6
    far = Track(CENTER, Template(look.astype(np.float32), np.ones((10, 14), bool),
                                 (ROW, 30)), sightings=2)
    assert claims.explained(far, CENTER, mask, image, CENTER, 5) < 0.5
    assert claims.explained(far, CENTER, mask, image, CENTER, None) == 1.0


def test_a_grown_answer_that_covers_a_tracked_neighbour_goes_to_the_neighbour():
    """:func:`claims.rival` with ``hidden_only=False`` (an answer grown past
    :data:`claims.GROWN` times the object's largest area, seed 1801 under jitter): a small
    tracked object's answer covers its tracked neighbour too; the neighbour, still to be
    searched, explains it clearly better and is searched first. Among hidden objects only
    (an answer found again), the tracked neighbour is no rival."""
    look = _texture()
    small = np.random.default_rng(5).uniform(0, 255, (6, 6, 3)).astype(np.float32)
    image = np.zeros((*SIZE, 3), np.float32)
    image[ROW:ROW + 10, 10:24] = look
    image[ROW + 2:ROW + 8, 24:30] = small
    mask = np.zeros(SIZE, bool)
    mask[ROW:ROW + 10, 10:24] = True
    mask[ROW + 2:ROW + 8, 24:30] = True
    tracks = {1: Track(CENTER, Template(small, np.ones((6, 6), bool), (ROW + 2, 24)),
                       sightings=2, area=36),
              2: Track(CENTER, Template(look.astype(np.float32), np.ones((10, 14), bool),
                                        (ROW, 10)), sightings=2, area=140)}
    assert mask.sum() > claims.GROWN * tracks[1].area
    args = (1, CENTER, mask, image, tracks, [2], CENTER, lambda view, m: None)
    assert claims.rival(*args, hidden_only=False) == 2
    assert claims.rival(*args) is None


def test_explained_is_the_best_shifts_truncated_colour_agreement():
    """:func:`claims.explained` against its definition, shift by shift: the largest, over the
    template's shifts within the radius of its predicted place, of the summed
    ``MAX_PIXEL_DIFFERENCE - distance`` (truncated at 0) over template pixels landing on the
    answer, over ``MAX_PIXEL_DIFFERENCE`` times the answer's area."""
    from lfsam.video.tracking.carry import MAX_PIXEL_DIFFERENCE
    from lfsam.video.tracking.motion import predicted

    rng = np.random.default_rng(11)
    for case in range(12):
        height, width = (int(x) for x in rng.integers(8, 16, 2))
        image = (rng.integers(0, 5, (height, width, 3)) * 15).astype(np.float32)
        t_h, t_w = (int(x) for x in rng.integers(2, 6, 2))
        template = Template(image[:t_h, :t_w].copy() + rng.integers(0, 2, (t_h, t_w, 3)),
                            rng.random((t_h, t_w)) > 0.2,
                            (int(rng.integers(0, height)), int(rng.integers(0, width))))
        track = Track(CENTER, template, velocity=(float(rng.normal()), 0.0))
        answer = rng.random((height, width)) > 0.6
        answer[0, 0] = True
        radius = None if case % 2 else int(rng.integers(0, 8))
        placed = predicted(track, CENTER, CENTER)
        best = 0.0
        for du in range(-height - t_h, height + t_h):
            for dv in range(-width - t_w, width + t_w):
                if radius is not None and du * du + dv * dv > radius * radius:
                    continue
                total = 0.0
                for r, c in zip(*np.nonzero(placed.mask), strict=True):
                    u, v = placed.origin[0] + r + du, placed.origin[1] + c + dv
                    if 0 <= u < height and 0 <= v < width and answer[u, v]:
                        distance = np.abs(image[u, v] - placed.image[r, c]).sum()
                        total += max(MAX_PIXEL_DIFFERENCE - distance, 0.0)
                best = max(best, total)
        expected = best / (MAX_PIXEL_DIFFERENCE * answer.sum())
        got = claims.explained(track, CENTER, answer, image, CENTER, radius)
        assert abs(got - expected) < 1e-9, (case, got, expected)

"""What the search of issue 47 accepts as the searched object (docs/design.md section 10,
"Tracking", steps 3 and 5): an object leaving the frame is found by the part of it still
inside; a partly hidden object whose match lies on look-alike pixels beside it is still found
where a part of its template explains the answer near the prediction, but not at another
depth; an object found again must lie at its depth."""

from __future__ import annotations

import numpy as np

from lfsam.video.tracking import rules
from lfsam.video.tracking.answer import accept_answer as _accept
from lfsam.video.tracking.answer import explaining_shift
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.rules import EXPLAINED
from lfsam.video.tracking.search import Track
from search_oracle import label_answer, search_one_image

SIZE, CENTER = (40, 50), (2, 2)


def _background(seed: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0, 110, (*SIZE, 3)).astype(np.float32)


def test_an_object_leaving_the_frame_is_found_by_its_part_inside():
    """A 30x30 object with 2 columns (60 pixels, under a tenth of its template) still inside
    the frame: its support is a share of the template's part inside the frame (before: of the
    whole template, so it was hidden while 60 of its pixels showed)."""
    rng = np.random.default_rng(1)
    look = (np.array([220.0, 60.0, 60.0]) + rng.uniform(-5, 5, (30, 30, 3))).astype(np.float32)
    image, labels = _background(), np.ones(SIZE, np.int64)
    image[5:35, 48:50] = look[:, :2]
    labels[5:35, 48:50] = 2
    template = Template(look, np.ones((30, 30), bool), (5, 48))
    track = Track(CENTER, template, area=900, sightings=2)
    found = search_one_image(track, image, label_answer(labels))
    assert found is not None
    view, mask, shift, _ = found
    assert view == CENTER and shift == (0, 0)
    np.testing.assert_array_equal(mask, labels == 2)


def _partly_hidden(shift=(3, 5)):
    """A textured 12x12 template at (10, 10); in the image only its top 5 rows show, moved by
    ``shift``; the returned support lies on the background elsewhere (look-alike pixels)."""
    rng = np.random.default_rng(2)
    look = rng.uniform(130, 255, (12, 12, 3)).astype(np.float32)
    template = Template(look, np.ones((12, 12), bool), (10, 10))
    image = _background()
    r, c = 10 + shift[0], 10 + shift[1]
    image[r:r + 5, c:c + 12] = look[:5]
    mask = np.zeros(SIZE, bool)
    mask[r:r + 5, c:c + 12] = True
    support = np.zeros(SIZE, bool)
    support[25:35, 30:40] = True  # the match's support: beside the answer
    carried = np.zeros(SIZE, bool)
    carried[24:36, 29:41] = True
    return template, image, mask, support, carried


def test_an_answer_beside_a_look_alike_support_is_explained_by_the_template():
    template, image, mask, support, carried = _partly_hidden()
    assert explaining_shift(mask, template, image, 6) == (3, 5)
    assert explaining_shift(mask, template, image, 2) is None  # too far from the prediction
    track = Track(CENTER, template, area=144, sightings=3, disparity=1.0)
    # before: refused (it covers none of the support and lies outside the carried mask)
    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6) == (3, 5)
    # another object of the template's colours but not its pixels: not explained
    other = image.copy()
    other[mask] = np.random.default_rng(9).permutation(image[mask])
    assert _accept(mask, support, carried, track, None, other, template, (0, 0), 6) is None
    assert EXPLAINED * mask.sum() >= 12


def test_the_explained_answer_and_a_found_again_answer_must_lie_at_the_objects_depth():
    template, image, mask, support, carried = _partly_hidden()
    track = Track(CENTER, template, area=144, sightings=3, disparity=1.0)

    def at(value):
        return CENTER, lambda view, m: value

    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6,
                   at(1.5)) == (3, 5)
    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6,
                   at(4.0)) is None  # a look-alike at another depth does not steal the id
    # an answer on the support itself: the depth is checked only after hidden frames
    on_support = support.copy()
    image[on_support] = template.image[:10, :10].reshape(-1, 3)
    assert _accept(on_support, support, carried, track, None, image, template, (1, 2), 6,
                   at(4.0)) == (1, 2)
    track.unseen = 2
    assert _accept(on_support, support, carried, track, None, image, template, (1, 2), 6,
                   at(4.0)) is None
    assert _accept(on_support, support, carried, track, None, image, template, (1, 2), 6,
                   at(2.5)) == (1, 2)  # within two frames' tolerance


def test_the_objects_disparity_is_the_median_over_an_answer_spilling_onto_the_background():
    """A 6x6 object at disparity 2 on a background at -1, answered one pixel too wide (the
    oracle's jitter): the median stays on the object (the mean, 0.3, was 1.7 off, beyond the
    depth gate's tolerance, so the gate refused the object's own pixels)."""
    from lfsam.video.tracking.frame_search import median_disparity, object_disparity
    from lfsam.video.tracking.motion import DISPARITY_TOLERANCE

    disparity = np.full(SIZE, -1.0, np.float32)
    disparity[10:16, 10:16] = 2.0
    dilated = np.zeros(SIZE, bool)
    dilated[9:17, 9:17] = True
    assert object_disparity(disparity, dilated) == 2.0
    assert abs(float(disparity[dilated].mean()) - 2.0) > DISPARITY_TOLERANCE
    assert median_disparity(disparity, np.zeros(SIZE, bool)) is None
    assert object_disparity(np.full(SIZE, np.nan, np.float32), dilated) == 0.0


def test_a_sliver_at_the_border_far_from_the_prediction_does_not_take_a_hidden_objects_id():
    """A look-alike entering at the frame's border, far from where a hidden object should
    be, shows a quarter of the object's template inside the frame: away from the prediction
    the support needed is a share of the whole template, so the id is not given to it (with
    the share of the part inside the frame, it was)."""
    rng = np.random.default_rng(4)
    look = (np.array([220.0, 60.0, 60.0]) + rng.uniform(-5, 5, (20, 20, 3))).astype(np.float32)
    image, labels = _background(), np.ones(SIZE, np.int64)
    image[10:30, 45:50] = look[:, :5]
    labels[10:30, 45:50] = 2
    template = Template(look, np.ones((20, 20), bool), (10, 10))
    track = Track(CENTER, template, area=400, sightings=3, unseen=1)
    found = search_one_image(track, image, label_answer(labels))
    assert found is None
    # the same sliver where the object is predicted (it is leaving the frame there): found
    near = Track(CENTER, Template(look, np.ones((20, 20), bool), (10, 45)), area=400,
                 sightings=3)
    found = search_one_image(near, image, label_answer(labels))
    assert found is not None
    np.testing.assert_array_equal(found[1], labels == 2)



def test_an_object_first_seen_mostly_covered_is_kept_as_it_is_uncovered():
    """An object seen at frame 0 by its 60 pixels (the rest covered), uncovered in the next
    frame to 450 pixels, more than 4x its largest area: its answer holds the whole support,
    is a small share of the view and lies at its depth, so it is the object (before:
    refused as grown too much, and hidden for good; seed 903 of ``bench_tracking.py``); the
    same answer mostly at the background's depth is still refused."""
    rng = np.random.default_rng(4)
    look = (np.array([60.0, 200.0, 90.0]) + rng.uniform(-5, 5, (15, 30, 3))).astype(np.float32)
    image, labels = _background(), np.ones(SIZE, np.int64)
    image[10:25, 10:40] = look
    labels[10:25, 10:40] = 2
    seen = np.zeros((15, 30), bool)
    seen[:6, :10] = True  # the 60 pixels shown at frame 0
    track = Track(CENTER, Template(look, seen, (10, 10)), area=60, sightings=1,
                  disparity=1.4)

    def search(disparity):
        return search_one_image(track, image, label_answer(labels),
                                disparities=lambda v: disparity,
                             depth=lambda v, m: float(np.median(disparity[m])))

    near = np.where(labels == 2, 1.5, -1.0).astype(np.float32)
    found = search(near)
    assert found is not None
    np.testing.assert_array_equal(found[1], labels == 2)
    far = near.copy()
    far[10:25, 20:40] = -1.0  # most of the answer at the background's depth
    assert search(far) is None


def test_an_answer_found_again_that_holds_a_placed_neighbour_is_that_neighbour():
    """Fresh seed 1802's case: a hidden object's answer lies on a neighbour's region, of
    which an object placed earlier in the frame holds 46 % of the answer (under the limit of
    half the answer) but most of its own mask: the answer is that object, so the hidden one
    is not found there (:data:`lfsam.video.tracking.rules.HELD`); an answer that only touches a
    placed object, or a tracked object's answer, is not refused so."""

    rng = np.random.default_rng(3)
    look = (np.array([60.0, 200.0, 90.0]) + rng.uniform(-4, 4, (12, 16, 3))).astype(np.float32)
    image, labels = _background(), np.ones(SIZE, np.int64)
    image[12:24, 14:30] = look
    labels[12:24, 14:30] = 2  # the neighbour's region: 192 pixels
    template = Template(look, np.ones((12, 16), bool), (12, 14))
    neighbour = np.zeros(SIZE, bool)
    neighbour[12:24, 14:21] = True  # placed earlier: 84 pixels, 44 % of the answer
    touched = np.zeros(SIZE, bool)
    touched[22:30, 28:40] = True  # another placed object: 4 of its 96 pixels in the answer
    answer = label_answer(labels)

    def hidden() -> Track:
        return Track(CENTER, template, area=192, sightings=3, unseen=2)

    def find(track: Track, held: list[np.ndarray]):
        return search_one_image(track, image, answer, placed=neighbour | touched,
                                held=lambda view, mask=None: held if mask is None else [])

    assert find(hidden(), []) is not None  # without the check: found on the neighbour
    assert find(hidden(), [touched]) is not None
    assert find(hidden(), [neighbour, touched]) is None
    assert rules.HELD * neighbour.sum() <= (neighbour & (labels == 2)).sum()
    tracked = Track(CENTER, template, area=192, sightings=3)
    assert find(tracked, [neighbour, touched]) is not None


def _showing_a_new_part(support_outside: int = 0):
    """A uniform red 12x12 template carried to (10, 10) with all of it supported; the answer
    holds it and a 12x28 part of another colour beside it, which the template never held (its
    colours as a whole: 144 of 480 pixels the template's). ``support_outside``: support
    pixels added outside the answer."""
    rng = np.random.default_rng(3)
    red = np.array([230.0, 60.0, 60.0])
    look = (red + rng.uniform(-5, 5, (12, 12, 3))).astype(np.float32)
    template = Template(look, np.ones((12, 12), bool), (10, 10))
    image = _background()
    image[10:22, 10:22] = look
    image[10:22, 22:50] = np.array([40.0, 60.0, 230.0]) + rng.uniform(-5, 5, (12, 28, 3))
    mask = np.zeros(SIZE, bool)
    mask[10:22, 10:50] = True
    carried = np.zeros(SIZE, bool)
    carried[10:22, 10:22] = True
    support = carried.copy()
    support[30:36, :support_outside // 6] = True
    return template, image, mask, support, carried


def test_an_answer_holding_its_support_is_judged_by_the_part_its_template_held(monkeypatch):

    template, image, mask, support, carried = _showing_a_new_part()
    track = Track(CENTER, template, area=144, sightings=3, disparity=1.0)
    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6) == (0, 0)
    monkeypatch.setattr(rules, "KNOWN_PART", False)  # judged as a whole: unlike
    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6) is None
    monkeypatch.setattr(rules, "KNOWN_PART", True)
    # the part the template held looks otherwise: another object there
    other = image.copy()
    other[10:22, 10:22] = np.array([60.0, 230.0, 60.0])
    assert _accept(mask, support, carried, track, None, other, template, (0, 0), 6) is None
    # an answer holding 80 % of the support (36 of 180 pixels outside it) is judged as a whole
    template, image, mask, support, carried = _showing_a_new_part(support_outside=36)
    assert support.sum() == 180 and (mask & support).sum() == 144
    assert _accept(mask, support, carried, track, None, image, template, (0, 0), 6) is None

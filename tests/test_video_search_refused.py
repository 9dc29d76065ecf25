"""An answer refused at the predicted place does not hide the object there (issue 47,
seventh pass; docs/design.md section 10, "Tracking", step 5): where a mostly covered object
sits beside a wide background of its own colours, the template's match lies on that
background, its answer (the background) is refused, and the object was hidden although it
showed itself at its predicted place (seed 802: 174 pixels in the center view, hidden for
its last three frames, 61 lost triples). The view is matched once more with the refused
answer's pixels counted as not the object."""

from __future__ import annotations

import numpy as np

from lfsam.video.tracking import rules
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.search import Track
from search_oracle import CENTER, label_answer, search_one_image


def _scene():
    rng = np.random.default_rng(8)
    colour = np.array([200.0, 60.0, 60.0])

    def alike(shape):
        return (colour + rng.uniform(-5, 5, (*shape, 3))).astype(np.float32)

    image = rng.uniform(0, 40, (60, 80, 3)).astype(np.float32)
    labels = np.ones((60, 80), np.int64)
    image[:27] = alike((27, 80))  # a background band of the object's colours
    labels[:27] = 4
    look = alike((12, 12))
    image[30:42, 40:52] = look  # the object, 3 px below the band
    labels[30:42, 40:52] = 2
    image[33:45, 36:56] = 0.0  # a cover over all but its top 3 rows
    labels[33:45, 36:56] = 3
    return image, labels, Template(look, np.ones((12, 12), bool), (30, 40))


def _search():
    image, labels, template = _scene()

    track = Track(CENTER, template, area=144, sightings=3, state="tracked")
    return search_one_image(track, image, label_answer(labels, CENTER))


def test_a_refused_answer_is_not_the_object_when_its_view_is_matched_again(monkeypatch):
    found = _search()
    assert found is not None
    view, mask, shift, _ = found
    _, labels, _ = _scene()
    assert view == CENTER and shift == (0, 0)
    assert mask.sum() == 36 and (labels[mask] == 2).all()  # its 3 visible rows
    monkeypatch.setattr(rules, "REFUSED_AGAIN", False)
    assert _search() is None  # the band's answer refused, the object hidden


def test_the_widening_reads_refused_answers_as_not_the_object(monkeypatch):
    """Fresh seed 1801's case (thirteenth pass): a hidden object of the background's colours
    is not in its own view any more but shows, partly covered, beside its prediction in
    another view; every match there lies on the background (more of the template supported
    than on the object's visible part), whose answer is refused. The widening reads those
    refused answers as not the object, as it reads placed objects, and finds it."""
    from lfsam.prompts import ObjectPrompts
    from lfsam.video.tracking.search import search_object

    rng = np.random.default_rng(4)
    colour = np.array([120.0, 110.0, 90.0])

    def alike(shape):
        return (colour + rng.uniform(-4, 4, (*shape, 3))).astype(np.float32)

    size, own = (48, 64), (4, 0)
    images = {own: alike(size), CENTER: alike(size)}  # the background: the object's colours
    labels = {own: np.ones(size, np.int64), CENTER: np.ones(size, np.int64)}
    images[CENTER][20:30, 30:40] = alike((10, 10))  # the object, moved while hidden
    labels[CENTER][20:30, 30:40] = 2
    images[CENTER][26:30, 28:42] = 0.0  # covered below its top 6 rows
    labels[CENTER][26:30, 28:42] = 3
    template = Template(np.full((10, 10, 3), colour, np.float32), np.ones((10, 10), bool),
                        (12, 20))

    def answer(obj: ObjectPrompts):
        point = next(p for p in obj.points if p.positive)
        view = point.view or CENTER
        return view, labels[view] == labels[view][round(point.y), round(point.x)]

    def find():
        track = Track(own, template, area=100, sightings=3, unseen=2, state="hidden")
        return search_object(1, track, images.__getitem__, CENTER, [], answer,
                             lambda view: None, None, (), False)

    found = find()
    assert found is not None
    view, mask, _, _ = found
    assert view == CENTER and mask.sum() == 60 and (labels[CENTER][mask] == 2).all()
    monkeypatch.setattr(rules, "WIDE_REFUSED", False)
    assert find() is None  # every match on the background, refused: hidden

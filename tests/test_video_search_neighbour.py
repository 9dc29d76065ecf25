"""A placed object asked in the view of a found-again answer that meets it (issue 47,
eighteenth pass; docs/design.md section 10, "Tracking", step 5;
:mod:`lfsam.video.tracking.neighbour`). Fresh seed 3603 without jitter, frame 5: a small disc
(object 3, label 4) hidden in every view was "found" in corner view (4, 0) on pixels of object 4
(label 5) that object 4's center mask, carried there, left out; object 3 then took object 4's place
(a swap)."""

from __future__ import annotations

import itertools

import numpy as np

from lfsam.video.io.synth import generate_video
from lfsam.video.tracking import neighbour
from search_oracle import least_ious


def _frames(count: int) -> list:
    return list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                seed=3603, num_objects=5, hard=True), count))


def test_a_hidden_object_is_not_found_on_a_placed_neighbours_other_pixels():
    frames = _frames(7)
    assert (frames[5].labels == 4).sum() == 0  # the disc shows nowhere at frame 5
    assert least_ious(frames, {5: 4})[5] >= 0.5


def test_without_asking_the_neighbour_the_disc_takes_its_pixels(monkeypatch):
    monkeypatch.setattr(neighbour, "ASK", False)
    assert least_ious(_frames(7), {5: 4})[5] < 0.5


class _Predictor:
    """Answers a point with the region under it; records what it was asked."""

    def __init__(self, regions: np.ndarray, view: tuple[int, int]):
        self.regions, self.view, self.ids, self.asked = regions, view, set(), []

    def set_object(self, prompts):
        self.ids.add(prompts.obj_id)
        self.asked.append(prompts)

    def predict_reference(self, obj_id):
        point = self.asked[-1].points[0]
        return self.view, self.regions == self.regions[round(point.y), round(point.x)], 1.0

    def remove_object(self, obj_id):
        self.ids.discard(obj_id)


def test_asked_mask_clicks_where_the_view_shows_the_objects_depth():
    regions = np.zeros((8, 12), int)
    regions[:, 6:] = 1  # the placed object's region in this view
    disparity = np.where(regions == 1, -1.0, 2.0)  # a nearer object covers the left half
    carried = np.zeros((8, 12), bool)
    carried[2:6, 3:9] = True  # its carried mask: half on the cover, half on itself
    predictor = _Predictor(regions, (4, 0))
    mask = neighbour.asked_mask(predictor, 3, (4, 0), carried, disparity, -1.0)
    assert np.array_equal(mask, regions == 1)
    assert predictor.asked[0].obj_id == neighbour.NEIGHBOUR_ID + 3 and not predictor.ids
    point = predictor.asked[0].points[0]
    assert point.positive and point.x >= 6  # on the object, not on the cover


def test_asked_mask_is_none_where_the_view_never_shows_the_object():
    regions = np.zeros((8, 12), int)
    carried = np.zeros((8, 12), bool)
    carried[2:6, 3:9] = True
    predictor = _Predictor(regions, (4, 0))
    assert neighbour.asked_mask(predictor, 0, (4, 0), carried, np.full((8, 12), 2.0),
                                -1.0) is None
    assert predictor.asked == []

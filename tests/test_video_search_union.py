"""An answer to several clicks that took an unprompted neighbour (issue 47, eighteenth pass;
docs/design.md section 10, "Tracking", step 5; :mod:`lfsam.video.tracking.union`). Fresh seed 3303
without jitter, frame 2: object 3 (label 5), partly behind an object nobody clicked (label 4,
alike in colour and within the depth gate), was answered with both (its clicks on each), and
followed the neighbour from frame 3 on."""

from __future__ import annotations

import itertools

import numpy as np

from lfsam.video.io.synth import generate_video
from lfsam.video.tracking import union
from search_oracle import least_ious


def test_a_click_on_an_unprompted_neighbour_is_left_out():
    frames = list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                  seed=3303, num_objects=5, hard=True), 4))
    # the neighbour is no clicked object: it never shows 100 pixels in frame 0's center view
    assert (frames[0].labels[frames[0].center] == 4).sum() < 100
    assert (frames[3].labels == 5).sum(axis=(2, 3)).min() >= 100
    assert least_ious(frames, {5: 3})[5] >= 0.9


def test_without_the_check_the_track_follows_the_neighbour(monkeypatch):
    frames = list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                  seed=3303, num_objects=5, hard=True), 4))
    monkeypatch.setattr(union, "CHECK", False)
    assert least_ious(frames, {5: 3})[5] < 0.5


def _regions() -> tuple[np.ndarray, dict[int, np.ndarray]]:
    support = np.zeros((6, 12), bool)
    support[:, :5] = True
    neighbour = np.zeros((6, 12), bool)
    neighbour[:, 6:] = True
    return support, {0: support, 1: neighbour}


def _asker(regions: dict[int, np.ndarray], calls: list):
    def ask(points):
        calls.append(list(points))
        mask = np.zeros((6, 12), bool)
        for x, _ in points:
            mask |= regions[int(x >= 6)]
        return (2, 2), mask
    return ask


def test_checked_keeps_an_answer_no_larger_than_the_object():
    support, regions = _regions()
    calls: list = []
    answer = ((2, 2), support | regions[1])
    out = union.checked(_asker(regions, calls), lambda v, m: (0, 0), [(1.0, 1.0), (8.0, 1.0)],
                        answer, (3, 4), support, largest=60)  # 66 pixels: not over 1.2 x 60
    assert out == (answer, (3, 4)) and calls == []


def test_checked_splits_a_union_and_leaves_the_predictor_with_the_clicks_kept():
    support, regions = _regions()
    calls: list = []
    clicks = [(1.0, 1.0), (8.0, 1.0), (2.0, 4.0)]
    (view, mask), shift = union.checked(_asker(regions, calls), lambda v, m: (1, 1), clicks,
                                        ((2, 2), support | regions[1]), (3, 4), support,
                                        largest=30)
    assert view == (2, 2) and np.array_equal(mask, support) and shift == (1, 1)
    assert calls[-1] == [(1.0, 1.0), (2.0, 4.0)]  # the last prompt asked: the clicks kept


def test_checked_asks_the_clicks_together_again_where_the_split_is_refused():
    support, regions = _regions()
    calls: list = []
    clicks = [(1.0, 1.0), (8.0, 1.0)]
    answer = ((2, 2), support | regions[1])
    out = union.checked(_asker(regions, calls), lambda v, m: None, clicks, answer, (3, 4),
                        support, largest=30)
    assert out == (answer, (3, 4)) and calls[-1] == clicks


def test_every_click_on_the_support_keeps_the_answer():
    support, regions = _regions()
    calls: list = []
    clicks = [(1.0, 1.0), (2.0, 4.0)]
    answer = ((2, 2), support)
    out = union.checked(_asker(regions, calls), lambda v, m: (1, 1), clicks, answer, (3, 4),
                        support, largest=10)  # grown (uncovered), yet every click is its own
    assert out == (answer, (3, 4)) and calls[-1] == clicks and len(calls) == 3

"""Removal fills two views at a time on the CPU (docs/design.md section 13): the same light field
as one at a time, and an error in one view stops it without waiting for the rest."""

from __future__ import annotations

import time

import numpy as np
import pytest
import torch

import lfsam.render.remove as remove
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene():
    lf = generate_scene(grid=(5, 5), size=(48, 64), seed=3, num_objects=2)
    sc, tc = lf.center
    ids, counts = np.unique(lf.labels[sc, tc], return_counts=True)
    obj = int(ids[1:][np.argmax(counts[1:])])
    return lf.views, lf.labels == obj, lf.disparity[sc, tc]


def test_two_views_at_a_time_give_the_same_light_field_as_one(scene, monkeypatch):
    views, masks, disparity = scene
    # the workers follow torch's thread count (one in a `make test` worker): set it both ways
    monkeypatch.setattr(torch, "get_num_threads", lambda: 2)
    together = remove.remove_objects(views, masks, disparity)
    monkeypatch.setattr(torch, "get_num_threads", lambda: 1)
    alone = remove.remove_objects(views, masks, disparity)
    np.testing.assert_array_equal(together[0], alone[0])
    np.testing.assert_array_equal(together[1], alone[1])
    assert together[1].any() and (together[0] != views).any()  # it did fill and flag


def test_an_error_in_one_view_stops_the_removal(scene, monkeypatch):
    views, masks, disparity = scene
    real = remove._fill_view
    calls = []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("view failed")
        time.sleep(0.05)
        return real(*args, **kwargs)

    monkeypatch.setattr(remove, "_fill_view", failing)
    with pytest.raises(RuntimeError, match="view failed"):
        remove.remove_objects(views, masks, disparity)
    # the views not started never are (map cancels them)
    assert len(calls) < masks.shape[0] * masks.shape[1] - 5



def test_removal_shows_progress_over_the_background_disparities_then_the_fills(scene,
                                                                               monkeypatch):
    import lfsam.render.background_disparity as background

    views, masks, disparity = scene
    bars = []

    def recording(iterable, **kwargs):
        bars.append((kwargs["desc"], kwargs["disable"]))
        return iterable

    monkeypatch.setattr(background, "tqdm", recording)
    monkeypatch.setattr(remove, "tqdm", recording)
    with_bars = remove.remove_objects(views, masks, disparity, progress=True)
    # shown (None: where the output is a terminal), the background disparities first
    assert bars == [("background disparity", None), ("removing", None)]
    bars.clear()
    without = remove.remove_objects(views, masks, disparity)
    assert bars == [("background disparity", True), ("removing", True)]
    np.testing.assert_array_equal(with_bars[0], without[0])
